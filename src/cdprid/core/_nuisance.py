# ruff: noqa: F722  (jaxtyping shape strings)
"""The one nuisance pipeline of real recordings: masks, tension interpolation, joint fit.

A real recording differs from the model in ways a simulation does not: load cells carry
offsets and relative gains, the tension log lags the pose, cables go slack. Every feature
that fits real data (:mod:`cdprid.identify._real`, ``cdprid import uacdpr``, the diagnosis) uses the
functions of this module, so the same recording gets the same masks, delay and
uncertainties whichever command reads it.

Public API
----------
Masks (pose time base ``t``):

- :func:`taut_mask` ``(t, tension_t, tension, threshold_N, window_s, offset) -> bool (n,)``:
  every cable above :data:`cdprid.base.TAUT_THRESHOLD_N` over ``t +- window_s`` of the RAW
  tension stream (a slack event between two pose samples is not missed), and ``t`` inside
  the stream by ``window_s``.
- :func:`rest_mask` ``(t, speed, max_speed, min_duration_s) -> bool (n,)``: the one "at
  rest" rule: speed below :data:`cdprid.base.REST_SPEED_M_S` during at least
  ``min_duration_s`` (:data:`REST_MIN_DURATION_S`).
- :func:`mask_windows` ``(t, mask) -> [(t0, t1), ...]``: the runs of a mask as time windows.
- :class:`InsufficientDataError` (a ``ValueError``): too few usable samples.

Interpolation of the tension stream at shifted times ``tau(t + delay)``
(:mod:`cdprid.core._tension`):

- :class:`TensionStream` (``eqx.Module``: ``t``, ``values``; uniform step checked when built);
- :func:`tension_at` ``(stream, s, method) -> (n, m)``, pure JAX, differentiable in ``s``;
  ``method`` is ``"linear"`` or ``"catmull-rom"`` (cubic Hermite, C1);
  :data:`INTERPOLATION` is the default, chosen by measurement (below).

Joint fit of the nuisances with the linear dynamic parameters:

- :class:`NuisanceSpec` (which nuisances are free: ``offsets`` True / False / ``"zero_sum"``,
  ``gains``, ``delay``, the fixed ``delay0``);
- :func:`fit_nuisance` ``(W, A, stream, t, rows, wrench_filter, spec) -> NuisanceFit``:
  nonlinear least squares (optimistix Levenberg-Marquardt, ``sol.result`` checked:
  :class:`cdprid.base.ConvergenceError` when the solver fails) of

      ``F(W(pose) k * (tau_meas(t + delay) - o)) = A(pose, motion) x``

  on the rows ``rows`` (taut samples), with ``F`` the zero-phase low-pass through which the
  accelerations were obtained (matched filtering), force and moment rows weighted by the
  inverse of their residual RMS (two passes). Gains are relative: ``k = 1 + B g`` with
  ``sum(k) = m`` (a common gain is the mass). The covariance is
  :func:`cdprid.core.hac_covariance` of the weighted Jacobian at the solution
  (Newey-West sandwich: the filtered residuals are strongly correlated in time).

Linear vs Catmull-Rom, raw vs smoothed (measured)
-------------------------------------------------
``studies/real_uacdpr.py`` (section "interpolation"; numbers in ``results/real-uacdpr.md``)
simulates the 8-cable CRAFT-like robot on the paper's orbits (20 s, 1 kHz tensions with the
default 0.5 N noise, 100 Hz poses) with a known 23.7 ms delay and fits it (translation
model, 3 seeds). On the RAW stream the cost ripples with the 1 ms tension step and both
interpolants stop in a ripple: RMS error 2.8 ms (linear) and 2.7 ms (Catmull-Rom) with a
reported std of 0.02 ms, i.e. dishonest. After the 20 Hz low-pass (:data:`SMOOTH_HZ`) both
recover the delay to 0.12 ms RMS with a reported std of 0.21 ms (honest), and the two
interpolants differ by less than 3 us. The smoothing is what matters; :data:`INTERPOLATION`
is ``"linear"``: as accurate, simpler, valid on any grid.

Delay sign: ``tau_true(t) = tau_meas(t + delay)`` (delay > 0: the tension log lags the pose).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Bool, Float

from cdprid.base import REST_SPEED_M_S, TAUT_THRESHOLD_N, ConvergenceError, InputError
from cdprid.core._covariance import hac_covariance, std_from_cov
from cdprid.core._tension import _METHODS, INTERPOLATION, TensionStream, tension_at

__all__ = [
    "INTERPOLATION",
    "InsufficientDataError",
    "REST_MIN_DURATION_S",
    "TAUT_WINDOW_S",
    "NuisanceFit",
    "NuisanceSpec",
    "TensionStream",
    "fit_nuisance",
    "mask_windows",
    "rest_mask",
    "taut_mask",
    "tension_at",
]

TAUT_WINDOW_S: float = 0.1
"""Half-width (s) around a pose sample in which every cable must stay taut: the matched
filter spreads a slack event over about ``1 / cutoff`` s."""

REST_MIN_DURATION_S: float = 0.5
"""Shortest run (s) of low speed that counts as rest (vibrations average out)."""

DELAY_RANGE_S: float = 0.1
"""Half-width (s) of the delay scan that gives the Levenberg-Marquardt start."""

SMOOTH_HZ: float | None = 20.0
"""Zero-phase low-pass (Hz) of the raw tension stream before interpolation at shifted times.

Interpolating a noisy 1 kHz stream between its samples changes the noise variance within
each sample interval, so the fit cost ripples with the tension step and a gradient solver
stops in the nearest ripple (measured: a 23.7 ms simulated delay was found at 0.5 ms from a
zero start). A low-pass well above the matched filter's 4 Hz (20 Hz: gain 0.998 at 4 Hz,
1 - 1e-7 at the 0.5 Hz of the motion) removes the ripple and leaves the band the model fits."""

DELAY_SCAN_STEP_S: float = 0.005
"""Step (s) of that scan (the Levenberg-Marquardt refinement does the rest)."""

class InsufficientDataError(ValueError):
    """Too few usable (taut, trimmed) samples for the fit; the message says how many."""


# --------------------------------------------------------------------------- masks


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index runs ``[i, j)`` where ``mask`` is True."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(int))
    return list(zip(np.nonzero(d == 1)[0].tolist(), np.nonzero(d == -1)[0].tolist(), strict=True))


def taut_mask(
    t: Float[np.ndarray, " n"],
    tension_t: Float[np.ndarray, " k"],
    tension: Float[np.ndarray, "k m"],
    threshold_N: float = TAUT_THRESHOLD_N,
    window_s: float = TAUT_WINDOW_S,
    offset: Float[np.ndarray, " m"] | None = None,
) -> Bool[np.ndarray, " n"]:
    """Pose samples where every cable stays taut.

    Parameters
    ----------
    t : ndarray (n,)
        Pose times, s.
    tension_t, tension : ndarray (k,), (k, m)
        Raw tension stream.
    threshold_N : float
        A cable below this (after ``offset``) is slack.
    window_s : float
        Every cable must stay above the threshold during ``t +- window_s``.
    offset : ndarray (m,), optional
        Load-cell offsets subtracted before the comparison.

    Returns
    -------
    ndarray (n,) of bool
        True where taut and ``t`` lies inside the stream by at least ``window_s``.
    """
    tension_t = np.asarray(tension_t, float)
    tau = np.asarray(tension, float) - (0.0 if offset is None else np.asarray(offset)[None, :])
    slack = (tau.min(axis=1) <= threshold_N).astype(float)
    tdt = float(np.median(np.diff(tension_t)))
    k = max(1, int(round(window_s / tdt)))
    near_slack = np.convolve(slack, np.ones(2 * k + 1), mode="same") > 0
    ok = np.interp(t, tension_t, (~near_slack).astype(float)) > 0.999
    inside = (t >= tension_t[0] + window_s) & (t <= tension_t[-1] - window_s)
    return ok & inside


def rest_mask(
    t: Float[np.ndarray, " n"],
    speed: Float[np.ndarray, " n"],
    max_speed: float = REST_SPEED_M_S,
    min_duration_s: float = REST_MIN_DURATION_S,
    edge_s: float = 0.0,
) -> Bool[np.ndarray, " n"]:
    """The one "at rest" rule: speed below ``max_speed`` during at least ``min_duration_s``.

    Parameters
    ----------
    t : ndarray (n,)
        Times, s.
    speed : ndarray (n,)
        Platform speed, m/s (filtered: e.g. ``|v|`` of :func:`cdprid.core.estimate_motion`).
    max_speed : float
        m/s, default :data:`cdprid.base.REST_SPEED_M_S`.
    min_duration_s : float
        Shortest run that counts.
    edge_s : float
        Seconds dropped inside each run where it meets motion (the platform still
        accelerates there; the recording's own ends are kept), default 0.

    Returns
    -------
    ndarray (n,) of bool
    """
    t = np.asarray(t, float)
    still = np.asarray(speed, float) < max_speed
    out = np.zeros(len(t), bool)
    for i, j in _runs(still):
        if t[j - 1] - t[i] >= min_duration_s:
            lo = t[i] + edge_s if i > 0 else -np.inf
            hi = t[j - 1] - edge_s if j < len(t) else np.inf
            out[i:j] = (t[i:j] >= lo) & (t[i:j] <= hi)
    return out


def mask_windows(t: Float[np.ndarray, " n"], mask: Bool[np.ndarray, " n"]
                 ) -> list[tuple[float, float]]:
    """The runs of ``mask`` as ``(t_first, t_last)`` windows.

    Parameters
    ----------
    t : array_like (n,)
        Sample times, s.
    mask : array_like (n,) of bool

    Returns
    -------
    list of (float, float)
        First and last time of each run of True, s.
    """
    t = np.asarray(t, float)
    return [(float(t[i]), float(t[j - 1])) for i, j in _runs(mask)]


# --------------------------------------------------------------------------- joint fit


@dataclasses.dataclass(frozen=True)
class NuisanceSpec:
    """Which nuisances are estimated (the others stay at 0 offsets, unit gains, ``delay0``).

    Attributes
    ----------
    offsets : bool or "zero_sum"
        Load-cell offsets; ``"zero_sum"`` constrains ``sum(o) = 0`` (a common offset of all
        cells is a nearly constant vertical force that cannot be told from the weight).
    gains : bool
        Relative load-cell gains (``sum(k) = m``).
    delay : bool
        Time delay of the tension log.
    delay0 : float
        Fixed delay when ``delay`` is False, s; centre of the delay scan otherwise.
    interpolation : {"linear", "catmull-rom"}
    delay_range_s : float
        The free delay starts from the best of a scan over ``delay0 +- delay_range_s``
        (profile cost, dynamic parameters by linear LS): the cost has local minima.
    smooth_hz : float or None
        Zero-phase low-pass of the raw tension stream before interpolation (None: raw).
    """

    offsets: bool | str = True
    gains: bool = False
    delay: bool = True
    delay0: float = 0.0
    interpolation: str = INTERPOLATION
    delay_range_s: float = DELAY_RANGE_S
    smooth_hz: float | None = SMOOTH_HZ

    def __post_init__(self):
        if self.offsets not in (True, False, "zero_sum"):
            raise InputError(f"offsets must be True, False or 'zero_sum', got {self.offsets!r}.")
        if self.interpolation not in _METHODS:
            raise InputError(f"interpolation must be one of {_METHODS}, got "
                             f"{self.interpolation!r}.")


@dataclasses.dataclass(frozen=True)
class NuisanceFit:
    """Result of :func:`fit_nuisance`.

    Attributes
    ----------
    x : ndarray (p,)
        Dynamic parameters.
    offset, gain : ndarray (m,)
        Load-cell offsets (N) and relative gains.
    delay : float
        s.
    x_std, offset_std, gain_std : ndarray
        Standard deviations (HAC); zeros for nuisances held fixed.
    delay_std : float
    cov : ndarray (q, q)
        HAC covariance of the free parameters ``[x, offsets, gain ratios, delay]``.
    bandwidth : float
        Bartlett bandwidth of the HAC covariance, samples.
    residual : ndarray (n, 6)
        Filtered measured minus model wrench at every pose sample.
    measured : ndarray (n, 6)
        Filtered measured wrench (with the nuisances applied).
    row_weight : ndarray (6,)
        Weights of the force and moment rows.
    n_steps : int
        Levenberg-Marquardt steps of the last pass.
    """

    x: np.ndarray
    offset: np.ndarray
    gain: np.ndarray
    delay: float
    x_std: np.ndarray
    offset_std: np.ndarray
    gain_std: np.ndarray
    delay_std: float
    cov: np.ndarray
    bandwidth: float
    residual: np.ndarray
    measured: np.ndarray
    row_weight: np.ndarray
    n_steps: int


@dataclasses.dataclass(frozen=True)
class _Layout:
    """Slices of the free-parameter vector ``[x | offsets | gain ratios | delay]``."""

    p: int
    m: int
    spec: NuisanceSpec

    @property
    def sizes(self) -> tuple[int, int, int, int]:
        s, m = self.spec, self.m
        n_off = (m - 1 if s.offsets == "zero_sum" else m) if s.offsets else 0
        return self.p, n_off, (m - 1) if s.gains else 0, 1 if s.delay else 0

    def slices(self) -> tuple[slice, slice, slice, slice]:
        e = np.cumsum((0,) + self.sizes)
        return tuple(slice(int(a), int(b)) for a, b in zip(e[:-1], e[1:], strict=True))

    @property
    def size(self) -> int:
        return int(sum(self.sizes))

    @property
    def basis(self) -> np.ndarray:
        """(m, m-1): ``o = B theta`` with ``sum(o) = 0`` (zero-sum offsets, gain ratios)."""
        B = np.zeros((self.m, self.m - 1))
        B[np.arange(self.m - 1), np.arange(self.m - 1)] = 1.0
        B[self.m - 1, :] = -1.0
        return B

    def scale(self) -> np.ndarray:
        """Parameter scaling for balanced LM steps (delay in 10 ms, gains in 1 %)."""
        sc = np.ones(self.size)
        _, _, sg, sd = self.slices()
        sc[sg] = 0.01
        sc[sd] = 0.01
        return sc

    def unpack(self, theta):
        sx, so, sg, sd = self.slices()
        B = jnp.asarray(self.basis)
        s = self.spec
        if not s.offsets:
            o = jnp.zeros(self.m)
        else:
            o = B @ theta[so] if s.offsets == "zero_sum" else theta[so]
        k = 1.0 + B @ theta[sg] if s.gains else jnp.ones(self.m)
        d = theta[sd][0] if s.delay else jnp.asarray(s.delay0)
        return theta[sx], o, k, d


def _row_weight(e: np.ndarray) -> np.ndarray:
    """Inverse RMS of the force rows (3) and of the moment rows (3)."""
    f = 1.0 / max(float(np.sqrt(np.mean(e[:, :3] ** 2))), 1e-300)
    mo = 1.0 / max(float(np.sqrt(np.mean(e[:, 3:] ** 2))), 1e-300)
    return np.array([f, f, f, mo, mo, mo])


def _solve(fun, z0, args, max_steps: int):
    """Levenberg-Marquardt with the solver status checked."""
    import optimistix as optx

    solver = optx.LevenbergMarquardt(rtol=1e-10, atol=1e-10)
    sol = optx.least_squares(fun, solver, z0, args=args, max_steps=max_steps, throw=False)
    if sol.result != optx.RESULTS.successful:
        msg = optx.RESULTS[sol.result]
        raise ConvergenceError(
            f"nuisance fit (Levenberg-Marquardt on offsets/gains/delay and the dynamic "
            f"parameters) did not converge in {max_steps} steps ({msg}); try a larger "
            "max_steps, a starting delay0 closer to the truth, or fewer free nuisances.")
    return np.asarray(sol.value), int(sol.stats["num_steps"])


def _scan_delay(measured, theta, lay: _Layout, A, rows, spec: NuisanceSpec, step: float) -> float:
    """Best delay on a grid over ``delay0 +- delay_range_s`` (profile cost: x by linear LS
    at each delay, force and moment rows weighted by their RMS at ``delay0``)."""
    from cdprid.core._identification import least_squares

    p = A.shape[2]
    Ar = A[rows].reshape(-1, p)
    n_grid = 2 * max(1, int(round(spec.delay_range_s / max(step, DELAY_SCAN_STEP_S)))) + 1
    grid = spec.delay0 + np.linspace(-spec.delay_range_s, spec.delay_range_s, n_grid)
    sd = lay.slices()[3]
    meas = jax.jit(measured)
    costs, wrow = [], None
    for d in grid:
        th = theta.copy()
        th[sd] = d
        y = np.asarray(meas(jnp.asarray(th)))[rows]
        e = y - (Ar @ least_squares(Ar, y.reshape(-1)).x).reshape(-1, 6)
        if wrow is None:
            wrow = _row_weight(e)
        costs.append(float(np.sum((e * wrow[None, :]) ** 2)))
    return float(grid[int(np.argmin(costs))])


def fit_nuisance(
    W: Float[np.ndarray, "n 6 m"],
    A: Float[np.ndarray, "n 6 p"],
    stream: TensionStream,
    t: Float[np.ndarray, " n"],
    rows: Bool[np.ndarray, " n"],
    wrench_filter,
    spec: NuisanceSpec = NuisanceSpec(),
    max_steps: int = 200,
) -> NuisanceFit:
    """Joint nonlinear least squares of the dynamic parameters and the nuisances.

    Parameters
    ----------
    W : ndarray (n, 6, m)
        Wrench matrices at the pose samples (:func:`cdprid.core.wrench_matrices`).
    A : ndarray (n, 6, p)
        Regressors (:func:`cdprid.core.regressors`).
    stream : TensionStream
        Raw tensions.
    t : ndarray (n,)
        Pose times, s.
    rows : ndarray (n,) of bool
        Samples that enter the fit (taut, trimmed, training window).
    wrench_filter : callable
        JAX-traceable time-first filter applied to the measured wrench (matched filtering),
        e.g. :class:`cdprid.signal.ZeroPhaseFilter`; the identity if the accelerations are
        unfiltered.
    spec : NuisanceSpec
    max_steps : int
        Levenberg-Marquardt steps per pass.

    Returns
    -------
    NuisanceFit

    Raises
    ------
    cdprid.base._errors.ConvergenceError
        The solver did not reach its tolerance.
    """
    from cdprid.core._identification import least_squares

    n, _, m = W.shape
    p = A.shape[2]
    lay = _Layout(p, m, spec)
    stream = stream.smoothed(spec.smooth_hz)
    Wj, Aj, tj = jnp.asarray(W), jnp.asarray(A), jnp.asarray(t)

    def measured(theta):
        _, o, k, d = lay.unpack(theta)
        tau = (tension_at(stream, tj + d, spec.interpolation) - o[None, :]) * k[None, :]
        return wrench_filter(jnp.einsum("nij,nj->ni", Wj, tau))

    def resid(theta):
        return measured(theta) - jnp.einsum("nij,j->ni", Aj, theta[: p])

    rows = np.asarray(rows, bool)
    idx = jnp.asarray(np.nonzero(rows)[0])
    scale = lay.scale()
    theta = np.zeros(lay.size)
    if spec.delay:
        theta[lay.slices()[3]] = _scan_delay(measured, theta, lay, A, rows, spec, stream.dt)
    y0 = np.asarray(measured(jnp.asarray(theta)))
    theta[:p] = least_squares(A[rows].reshape(-1, p), y0[rows].reshape(-1)).x
    wrow = _row_weight((y0 - np.einsum("nij,j->ni", A, theta[:p]))[rows])

    def fun(z, args):
        w_, s_ = args
        return (resid(z * s_)[idx] * w_[None, :]).ravel()

    theta, wrow, n_steps = _two_passes(fun, resid, theta, scale, wrow, rows, max_steps)
    cov, bw = _scaled_hac(fun, theta, scale, wrow, lay.size)
    return _package(lay, theta, cov, bw, np.asarray(resid(jnp.asarray(theta))),
                    np.asarray(measured(jnp.asarray(theta))), wrow, n_steps)


def _two_passes(fun, resid, theta, scale, wrow, rows, max_steps: int):
    """Two Levenberg-Marquardt passes of :func:`fit_nuisance` on the scaled vector, the second
    with row weights from the first solution: ``(theta, row weights, steps of the last)``."""
    n_steps = 0
    for _ in range(2):
        args = (jnp.asarray(wrow), jnp.asarray(scale))
        z, n_steps = _solve(fun, jnp.asarray(theta / scale), args, max_steps)
        theta = z * scale
        wrow = _row_weight(np.asarray(resid(jnp.asarray(theta)))[rows])
    return theta, wrow, n_steps


def _scaled_hac(fun, theta, scale, wrow, size: int):
    """HAC covariance of ``theta`` (:func:`hac_covariance` of the weighted residual's Jacobian
    in the scaled vector, scaled back) and its bandwidth."""
    args = (jnp.asarray(wrow), jnp.asarray(scale))
    z = jnp.asarray(theta / scale)
    J = np.asarray(jax.jacfwd(lambda zz: fun(zz, args))(z)).reshape(-1, 6, size)
    e = np.asarray(fun(z, args)).reshape(-1, 6)
    cov, bw = hac_covariance(J, e)
    return cov * np.outer(scale, scale), bw


def _package(lay: _Layout, theta, cov, bw, e, meas, wrow, n_steps) -> NuisanceFit:
    """Named estimates and standard deviations from the free-parameter vector."""
    sx, so, sg, sd = lay.slices()
    x, o, k, d = (np.asarray(v) for v in lay.unpack(jnp.asarray(theta)))
    std = std_from_cov(cov)
    B = lay.basis
    m = lay.m
    if not lay.spec.offsets:
        ostd = np.zeros(m)
    elif lay.spec.offsets == "zero_sum":
        ostd = std_from_cov(B @ cov[so, so] @ B.T)
    else:
        ostd = std[so]
    kstd = std_from_cov(B @ cov[sg, sg] @ B.T) if lay.spec.gains else np.zeros(m)
    return NuisanceFit(
        x=x, offset=o, gain=k, delay=float(d), x_std=std[sx], offset_std=ostd, gain_std=kstd,
        delay_std=float(std[sd][0]) if lay.spec.delay else 0.0, cov=cov, bandwidth=float(bw),
        residual=e, measured=meas, row_weight=wrow, n_steps=n_steps)
