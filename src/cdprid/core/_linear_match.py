"""Rotation-consistent matched filtering for causal differentiators (issue 24).

A causal differentiator returns the accelerations through its own low-pass ``H`` (with its
lag): ``a_hat = H[a]``. Matched filtering keeps ``W tau = Y(pose, a, omega, alpha) theta``
unbiased by filtering both sides with the same ``H``. On rotating data every regressor term is
a *product* (``R I R^T alpha``, ``omega x I omega``, ``R m s x (a - g)``) and ``H`` does not
commute with products, so ``Y(R, H[a], H[omega], H[alpha]) != H[Y(R, a, omega, alpha)]``: the
inertia is a 1 % signal beside the first moment's gravity moment, and the mismatch biased it by
5-300 % on noise-free data (the SIHD cascade's angular rate lags 30 % rms while its angular
acceleration lags 4 %).

Here the whole regression passes one *linear* filter:

1. ``H`` is the differentiator's own response on this recording, as a causal FIR: the taps
   ``c`` with ``a_hat[k] ~ sum_j c_j p[k - j]`` (``j = 0..L``, least squares over the three
   position channels, constrained to annihilate constants and ramps). For a linear method this
   is its impulse response truncated at ``L``; for a homogeneous (SIHD) one it is its best
   linear approximation on this motion. ``H[u] = c * (double integral of u)``.
2. The regressor's rotation-dependent part is formed from accurate rates (central differences
   of the poses, ``omega``, ``alpha`` from the quaternions) and filtered by ``H``; its part
   linear in the translational acceleration at the mean orientation uses ``c * p``;
   ``W tau`` passes ``H`` too.

On noise-free data this is exact to the FIR fit (the identity ``H[Y] theta = H[W tau]`` holds
term by term); with noise it is the same linear matched filter for every term, so no product
commutes wrongly. The fit's relative residual is reported: a nonlinear differentiator whose
response is far from linear (residual above :data:`FIT_WARN`) gets a warning.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.core._motion import Motion, angular_rates
from cdprid.core._regression import StreamedRegression, cable_wrench, regressor_blocks
from cdprid.model import quat_to_matrix

__all__ = ["FIR_SECONDS", "FIT_WARN", "LinearMatch", "fir_length", "fit_linear_match",
           "linear_match_regression", "matched_regression", "reference_fir", "reference_rates",
           "rotation_remainder", "settled", "uses_linear_match"]

FIR_SECONDS = 1.0
"""Longest memory of the fitted FIR (s); capped by the trim, so its start-up never reaches a
kept sample."""

RIDGE = 1e-6
"""Ridge weight of the kernel fit, relative to the mean diagonal of its normal matrix: the
hat coefficients are pulled towards zero (a smooth kernel of unit sum), so that taps the
motion does not determine stay small."""

REFERENCE_NOISE_M = 3e-4
"""Position noise (m) added to the reference motion of :func:`reference_fir`, so that the taps
reproduce the differentiator's response to measurement noise as well as to motion (without it
the taps above the motion's band are arbitrary, and passed 15 times the noise)."""

FIT_WARN = 0.05
"""Relative rms residual of the FIR fit above which the differentiator is too nonlinear on
this recording for a linear matched filter (a warning says so)."""


@dataclasses.dataclass(frozen=True)
class LinearMatch:
    """The differentiator's causal FIR response ``c`` (position -> acceleration) per segment.

    Attributes
    ----------
    taps : ndarray (L + 1,)
        ``a_hat[k] = sum_j taps[j] p[k - j]``.
    fit_residual : float
        Relative rms residual of the fit on the kept samples.
    segments : tuple of (int, int)
        Gap-free segments; the FIR never spans a gap.
    dt : float
    """

    taps: np.ndarray
    fit_residual: float
    segments: tuple
    dt: float

    def whole(self, n: int) -> LinearMatch:
        """The same filter on a gap-free sequence of ``n`` samples (one segment).

        Parameters
        ----------
        n : int
            Samples of the sequence.

        Returns
        -------
        LinearMatch
            The same taps with ``segments = ((0, n),)``.
        """
        return dataclasses.replace(self, segments=((0, int(n)),))

    def _check_length(self, n: int) -> None:
        """The filter is defined on the recording's segments only (no sample left unset)."""
        if self.segments and self.segments[-1][1] != n:
            raise RuntimeError(f"LinearMatch: {n} samples given, its segments cover "
                             f"{self.segments[-1][1]} (use whole(n) for another sequence).")

    def position(self, x: np.ndarray) -> np.ndarray:
        """``c * x`` for position-like channels, per segment (zero for the first ``L`` samples
        of each).

        Parameters
        ----------
        x : ndarray (n,) or (n, k)
            Position-like channels on the filter's samples (m or rad).

        Returns
        -------
        ndarray, the shape of ``x``
            Their filtered second derivative (m/s^2 or rad/s^2).

        Raises
        ------
        RuntimeError
            ``n`` is not the length the segments cover (use :meth:`whole` for another sequence).
        """
        x = np.asarray(x, float)
        self._check_length(len(x))
        out = np.zeros_like(x)
        for a, b in self.segments:
            out[a:b] = _fir(self.taps, x[a:b])
        return out

    def __call__(self, u, scale=None) -> np.ndarray:
        """``H[u]``: the acceleration filter applied to (n, k) channels (mean passes unchanged).

        ``scale`` is accepted for the signature of the other wrench filters and unused (``H`` is
        linear).
        """
        u = np.asarray(u, float)
        squeeze = u.ndim == 1
        u2 = u.reshape(len(u), -1)
        self._check_length(len(u2))
        out = np.empty_like(u2)
        for a, b in self.segments:
            mu = u2[a:b].mean(axis=0)
            out[a:b] = _fir(self.taps, _double_integral(u2[a:b] - mu, self.dt)) + mu
        return out[:, 0] if squeeze else out.reshape(u.shape)


def _fir(c: np.ndarray, x: np.ndarray) -> np.ndarray:
    out = np.zeros_like(x)
    n = len(x)
    for j, cj in enumerate(c):
        if j < n:
            out[j:] += cj * x[:n - j]
    return out


def _double_integral(u: np.ndarray, dt: float) -> np.ndarray:
    z = np.zeros((1,) + u.shape[1:])
    i1 = np.concatenate([z, np.cumsum(0.5 * dt * (u[1:] + u[:-1]), 0)])
    return np.concatenate([z, np.cumsum(0.5 * dt * (i1[1:] + i1[:-1]), 0)])


def fit_linear_match(motion: Motion, keep, trim: float) -> LinearMatch:
    """Fit the causal FIR ``c`` that maps the positions to the differentiator's accelerations.

    Parameters
    ----------
    motion : Motion
        Positions and the differentiator's accelerations.
    keep : ndarray (n,) of bool
        Samples used by the identification (the fit uses them only).
    trim : float
        Seconds trimmed at every segment edge; the FIR is at most that long.

    Returns
    -------
    LinearMatch
        The taps (1/s^2), the fit's relative rms residual and the motion's segments.

    Raises
    ------
    InputError
        No gap-free segment is long enough for the FIR.
    """
    dt = float(np.median(np.diff(motion.t)))
    L = fir_length(dt, trim)
    rows, target = [], []
    for a, b in motion.segments:
        p, ah = motion.position[a:b], motion.acceleration[a:b]
        k = np.asarray(keep[a:b], bool).copy()
        k[:L] = False
        idx = np.flatnonzero(k)
        if not len(idx):
            continue
        lags = idx[:, None] - np.arange(L + 1)[None, :]
        for i in range(3):
            rows.append(p[lags, i])
            target.append(ah[idx, i])
    if not rows:
        raise InputError(f"no gap-free segment is longer than {2 * L * dt:.3g} s: too short for "
                         "the causal differentiator's matched filter; use euler-filtfilt.")
    c, res = _fit_taps(np.concatenate(rows), np.concatenate(target), L, dt)
    return LinearMatch(c, res, tuple(motion.segments), dt)


def _fit_taps(X: np.ndarray, y: np.ndarray, L: int, dt: float) -> tuple[np.ndarray, float]:
    """Least-squares taps ``c`` (L + 1,) of ``y ~ X c``, and the relative rms residual.

    ``c`` is the causal second difference ``(1, -2, 1) / dt^2`` convolved with a smooth
    acceleration kernel ``g`` (L - 1 taps) of unit sum: ``c`` annihilates constants and ramps
    and passes a constant acceleration unchanged, exactly. ``g`` is a combination of hat
    functions on lag knots dense near zero (:func:`_hat_basis`): a free FIR of 100 taps is
    undetermined outside the motion's band, and least squares gave taps of norm 1e9 whose
    response grew without bound above it.
    """
    B = _hat_basis(L - 1)
    D = np.zeros((L + 1, L - 1))
    for i in range(L - 1):
        D[i:i + 3, i] = np.array([1.0, -2.0, 1.0]) / dt ** 2
    T = D @ B  # taps per basis function
    s = B.sum(axis=0)  # the kernel's sum per basis function
    b0 = s / (s @ s)
    _, _, vt = np.linalg.svd(s[None, :])
    N = vt[1:].T
    Z = X @ T @ N
    r = y - X @ (T @ b0)
    G = Z.T @ Z
    mu = RIDGE * np.trace(G) / len(G)
    z = np.linalg.solve(G + mu * (N.T @ N), Z.T @ r - mu * (N.T @ b0))
    c = T @ (b0 + N @ z)
    res = float(np.sqrt(np.mean((y - X @ c) ** 2) / max(np.mean(y ** 2), 1e-300)))
    return c, res


def _hat_basis(n: int) -> np.ndarray:
    """(n, k) piecewise-linear hat functions of lag on knots 0, 1, 2, 3, 4, 6, 8, 11, ...
    (spacing growing by about a third), the last at ``n - 1``."""
    knots, k, step = [0.0], 0.0, 1.0
    while k + step < n - 1:
        k += step
        knots.append(k)
        step = step * 1.35 if k >= 4 else 1.0
    knots = sorted(set(float(round(v)) for v in knots))
    if knots[-1] < n - 1:
        knots.append(float(n - 1))
    j = np.arange(n, dtype=float)
    return np.stack([np.interp(j, knots, np.eye(len(knots))[i]) for i in range(len(knots))], 1)


def fir_length(dt: float, trim: float = FIR_SECONDS) -> int:
    """Number of FIR taps minus one: :data:`FIR_SECONDS` (at most ``trim``) of samples, at least 8.

    Parameters
    ----------
    dt : float
        Sampling period, s.
    trim : float
        Seconds trimmed at every segment edge, s.

    Returns
    -------
    int
        ``L`` (the FIR has ``L + 1`` taps).
    """
    return int(max(8, round(min(FIR_SECONDS, trim) / dt) - 1))


def reference_fir(method: str, params: dict, dt: float) -> np.ndarray:
    """Taps fitted to ``method``'s response on a reference motion, for online use.

    The reference is a 40 s multisine per axis (0.1 m at 0.15-1.2 Hz, the band of platform
    orbits) plus :data:`REFERENCE_NOISE_M` of white noise, so the taps are known before the
    first sample. Any taps keep the online regression exact on noise-free data (every term
    passes the same filter); fitting them to the differentiator keeps its noise behaviour.

    Parameters
    ----------
    method : str
        A differentiator of :data:`cdprid.signal.METHODS`.
    params : dict
        Its parameters.
    dt : float
        Sampling period, s.

    Returns
    -------
    ndarray (L + 1,)
        FIR taps (position to acceleration, 1/s^2), ``L`` from :func:`fir_length`.
    """
    from cdprid.signal import differentiate

    n = int(round(40.0 / dt))
    t = np.arange(n) * dt
    rng = np.random.default_rng(0)
    f = rng.uniform(0.15, 1.2, (3, 4))
    ph = rng.uniform(0.0, 2 * np.pi, (3, 4))
    p = np.stack([sum(0.1 / (1 + k) * np.sin(2 * np.pi * f[i, k] * t + ph[i, k])
                      for k in range(4)) for i in range(3)], 1)
    p = p + REFERENCE_NOISE_M * rng.normal(size=p.shape)
    _, a = differentiate(p, dt, method=method, **params)
    L = fir_length(dt)
    idx = np.flatnonzero(t >= max(5.0, (L + 1) * dt))
    lags = idx[:, None] - np.arange(L + 1)[None, :]
    X = np.concatenate([p[lags, i] for i in range(3)])
    y = np.concatenate([np.asarray(a)[idx, i] for i in range(3)])
    return _fit_taps(X, y, L, dt)[0]


def settled(keep, segments, taps: int) -> np.ndarray:
    """``keep`` without the first ``taps`` samples of every segment (the FIR's start-up).

    Parameters
    ----------
    keep : array_like (n,) of bool
    segments : sequence of (int, int)
        Gap-free segments ``[a, b)``.
    taps : int
        Samples dropped at the start of each segment.

    Returns
    -------
    ndarray (n,) of bool
    """
    k = np.asarray(keep, bool).copy()
    for a, _ in segments:
        k[a:a + taps] = False
    return k


def uses_linear_match(model: str, causal: bool, wrench_filter: str) -> bool:
    """Whether identification takes the rotation-consistent path: the full model with a causal
    differentiator and matched filtering.

    Parameters
    ----------
    model : {"translation", "full"}
    causal : bool
        The differentiator is causal.
    wrench_filter : str
        ``"matched"`` or ``"none"``.

    Returns
    -------
    bool
    """
    return model == "full" and causal and wrench_filter == "matched"


def linear_match_regression(robot, motion: Motion, quaternion, tension, model: str, keep,
                            trim: float, chunk: int):
    """Fit :class:`LinearMatch` and build :func:`matched_regression`.

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
        The causal differentiator's motion.
    quaternion : ndarray (n, 4)
        Measured quaternions at the pose times.
    tension : ndarray (n, m)
        Tensions at the pose times, N.
    model : {"translation", "full"}
    keep : ndarray (n,) of bool
        Samples kept (trimmed ends).
    trim : float
        Seconds trimmed at every segment edge (bounds the FIR's length).
    chunk : int
        Samples per regressor block.

    Returns
    -------
    regression : StreamedRegression
    lm : LinearMatch
        The wrench filter (also for the errors-in-variables noise gains).
    note : str
        One sentence for the report.
    warnings : list of str
        A sentence when the FIR fit's residual exceeds :data:`FIT_WARN`.

    Raises
    ------
    InputError
        No segment is long enough for the FIR (:func:`fit_linear_match`).
    """
    lm = fit_linear_match(motion, keep, trim)
    reg = matched_regression(robot, motion, quaternion, tension, model, keep, lm, chunk)
    note = (f"rotation-consistent matched filtering: every regressor term and W tau pass one "
            f"causal FIR ({len(lm.taps)} taps) fitted to the differentiator's response on this "
            f"recording (relative fit residual {lm.fit_residual:.2%}); rotation terms from "
            "central differences of the poses")
    warns = []
    if lm.fit_residual > FIT_WARN:
        warns.append(f"the differentiator's response on this recording is far from linear (FIR "
                     f"fit residual {lm.fit_residual:.1%} > {FIT_WARN:.0%}): the matched filter "
                     "is approximate and the inertia may be biased; prefer kalman or "
                     "euler-filtfilt.")
    return reg, lm, note, warns


def reference_rates(motion: Motion, quaternion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Accurate accelerations and angular rates per segment (central differences, base frame).

    Second differences of the positions, and ``omega = 2 vec(qd q*)``, ``alpha = 2 vec(qdd q*)``
    from central differences of the sign-continuous quaternions (segment ends: the nearest
    interior value); no difference uses the sample it is centred on (:func:`_second`).

    Parameters
    ----------
    motion : Motion
        Positions and segments.
    quaternion : ndarray (n, 4)
        Measured quaternions ``(w, x, y, z)``; signs may flip between samples.

    Returns
    -------
    a : ndarray (n, 3)
        Accelerations, m/s^2.
    omega : ndarray (n, 3)
        Angular rates, rad/s.
    alpha : ndarray (n, 3)
        Angular accelerations, rad/s^2.
    """
    n = len(motion.t)
    dt = float(np.median(np.diff(motion.t)))
    q = np.asarray(quaternion, float).copy()
    a_ref = np.zeros((n, 3))
    qd, qdd = np.zeros((n, 4)), np.zeros((n, 4))
    for s0, s1 in motion.segments:
        qs = q[s0:s1]
        flip = np.cumprod(np.where(np.sum(qs[1:] * qs[:-1], axis=1) < 0, -1.0, 1.0))
        qs[1:] *= flip[:, None]
        a_ref[s0:s1] = _second(motion.position[s0:s1], dt)
        qd[s0:s1] = np.gradient(qs, dt, axis=0, edge_order=2) if s1 - s0 > 2 else 0.0
        qdd[s0:s1] = _second(qs, dt)
    om, al = angular_rates(q, qd, qdd)
    return a_ref, om, al


def _second(x: np.ndarray, dt: float) -> np.ndarray:
    """Second derivative from samples ``k +- 1`` and ``k +- 3``, never sample ``k`` itself.

    ``(x[k+3] - x[k+1] - x[k-1] + x[k-3]) / (8 dt^2)``, error ``(5/6) dt^2`` times the fourth
    derivative. Leaving sample ``k`` out keeps its noise uncorrelated with the rotation matrix
    and quaternion of the same sample that multiply it (the 3-point stencil correlates them by
    ``-2 sigma^2 / dt^2``, which biased the inertia by 6 %); it is also 24 times less noisy.
    """
    out = np.zeros_like(x)
    if len(x) > 6:
        out[3:-3] = (x[6:] - x[4:-2] - x[2:-4] + x[:-6]) / (8.0 * dt ** 2)
        out[:3], out[-3:] = out[3], out[-4]
    return out


def _mean_rotation(quaternion, keep) -> np.ndarray:
    q = np.asarray(quaternion, float)[np.asarray(keep, bool)]
    q = q * np.where(q @ q[0] < 0, -1.0, 1.0)[:, None]
    qm = q.mean(axis=0)
    return np.asarray(quat_to_matrix(jnp.asarray(qm / np.linalg.norm(qm))))


def rotation_remainder(robot, motion: Motion, quaternion, model: str, keep, chunk: int):
    """The regressor's rotation-dependent part from accurate rates, and its linear part.

    ``rem = Y(R, a, omega, alpha) - Y(R0, a, 0, 0) + Y(R0, 0, 0, 0)`` with ``R0`` the mean
    orientation and the rates of :func:`reference_rates` (to be passed through the matched
    filter term by term), and ``linear_part(a_hat) = Y(R0, a_hat, 0, 0) - Y(R0, 0, 0, 0)``,
    the part linear in the translational acceleration at the mean orientation, for the
    differentiator's own (already filtered) accelerations ``a_hat`` (n, 3).

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
    quaternion : ndarray (n, 4)
        Measured quaternions.
    model : {"translation", "full"}
    keep : ndarray (n,) of bool
        Samples whose orientations give the mean ``R0``.
    chunk : int
        Samples per regressor block.

    Returns
    -------
    rem : ndarray (n, 6, p)
        In N and N m per unit of each parameter.
    linear_part : callable
        ``a_hat (n, 3) -> (n, 6, p)``.
    """
    n = len(motion.t)
    a_ref, om, al = reference_rates(motion, quaternion)
    R0 = np.broadcast_to(_mean_rotation(quaternion, keep), (n, 3, 3))
    z = np.zeros((n, 3))
    g = robot.gravity
    base = regressor_blocks(model, R0[:1], z[:1], z[:1], z[:1], g, 1)(0, 1)[0]
    rem = regressor_blocks(model, motion.B_R_P, a_ref, om, al, g, chunk)(0, n)
    rem -= regressor_blocks(model, R0, a_ref, z, z, g, chunk)(0, n) - base

    def linear_part(a_hat):
        return regressor_blocks(model, R0, a_hat, z, z, g, chunk)(0, n) - base

    return rem, linear_part


def matched_regression(robot, motion: Motion, quaternion, tension, model: str, keep,
                       lm: LinearMatch, chunk: int) -> StreamedRegression:
    """The kept samples' regression with every term through the linear filter ``lm``.

    ``A = Y(R0, c * p, 0, 0) - Y(R0, 0, 0, 0) + H[Y(R, a, omega, alpha) - Y(R0, a, 0, 0)
    + Y(R0, 0, 0, 0)]`` with ``R0`` the mean orientation and accurate rates
    (:func:`reference_rates`); ``y = H[W tau]``. Holds the (n, 6 p) filtered regressor.

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
    quaternion : ndarray (n, 4)
        Measured quaternions at the pose times.
    tension : ndarray (n, m)
        Tensions at the pose times, N.
    model : {"translation", "full"}
    keep : ndarray (n,) of bool
        Samples kept; the FIR's start-up of each segment is dropped too (:func:`settled`).
    lm : LinearMatch
    chunk : int
        Samples per regressor block.

    Returns
    -------
    StreamedRegression
        Rows (k, 6, p) and filtered wrenches (k, 6), N and N m, at the settled kept samples.
    """
    n = len(motion.t)
    rem, linear_part = rotation_remainder(robot, motion, quaternion, model, keep, chunk)
    A = lm(rem.reshape(n, -1)).reshape(rem.shape)
    del rem
    A += linear_part(lm.position(motion.position))
    y = lm(cable_wrench(robot, motion.position, motion.B_R_P, tension, chunk))
    idx = np.flatnonzero(settled(keep, motion.segments, len(lm.taps)))
    A, y, t = A[idx], y[idx], motion.t[idx]
    return StreamedRegression(t, y, model, lambda i0, i1: A[i0:i1])
