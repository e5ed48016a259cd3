"""Online identification: streaming SIHD differentiation + recursive least squares.

The seed paper's long-term aim is to identify CRAFT's parameters *on line*, during handling
tasks, with the causal semi-implicit homogeneous differentiator (SIHD) instead of a zero-phase
filter (section 7). This module does it sample by sample, in ONE ``jax.lax.scan`` whose body,
:func:`online_step`, is also usable on its own in a real-time loop:

1. **Motion** — the pose sample goes through the paper's cascade of two SIHD-2
   (:func:`cdprid.signal.sihd2_step`, gains of eq. 35 unless overridden):
   position -> velocity -> acceleration; for the 10-parameter model the sign-continuous
   quaternion goes through the same cascade and ``omega = 2 vec(qd q*)``,
   ``alpha = 2 vec(qdd q*)``. The outputs equal :func:`cdprid.differentiate` with
   ``method="sihd2-cascade"`` sample for sample (tested).
2. **Rows** — the regressor ``A_k`` (6, p) (eq. 10, or the full model) from the estimated
   motion, and the measured wrench ``y_k = W_k tau_k`` (eq. 2) at the measured pose.
3. **Lag matching** — the causal SIHD delays and attenuates the acceleration (about 0.3 s and
   -15 % at the paper's 0.25 Hz orbits with the eq.-35 gains), while ``W tau`` is not filtered
   at all; the mismatch biases the estimate of the parameters the horizontal accelerations
   carry (m z_G). ``wrench_filter`` chooses what is done to ``y_k``:

   - ``"matched"`` (default): ``y_k`` goes through the *same* SIHD cascade as the positions,
     fed with its running (trapezoidal) integral: stage 1 sees ``int y`` and returns a
     low-passed ``y`` exactly as it sees ``p = int v`` and returns a low-passed ``v``; stage 2
     likewise. For ``alpha = 1`` (linear SIHD) both sides of ``A x = y`` then see the same
     linear filter, so the equation holds exactly for the translation model with constant
     orientation; with ``alpha < 1`` the gains depend weakly on the error amplitude, so the
     wrench channels are scaled to acceleration units first (force rows divided by
     ``|F_0| / |g|``, the mass seen at the first sample; moment rows additionally by the
     platform radius ``max |P_b|``) — an approximation, measured in ``benchmarks/online.py``.
   - ``"delay"``: ``y_k`` is delayed by ``wrench_delay`` samples (a ring buffer), which matches
     the phase at one frequency but not the attenuation.
   - ``"none"``: no compensation.

4. **Recursive least squares** — square-root information form (a QR update, no matrix
   inverse, no covariance downdate): the upper-triangular factor ``S`` of ``[W_ID | Y_ID]``
   (p+1, p+1) is updated with the six new rows at once,
   ``S <- R-factor of [sqrt(lambda) S ; A_k  y_k]``, so that ``S^T S`` is the exponentially
   weighted ``[W_ID Y_ID]^T [W_ID Y_ID]``. Then ``R = S[:p, :p]``, ``x = R^-1 S[:p, p]``
   (eq. 15), the weighted residual sum of squares is ``S[p, p]^2``,
   ``sigma_rho^2 = S[p, p]^2 / (N_eff - p)`` (eq. 19, ``N_eff`` the weighted row count) and
   ``cov = sigma_rho^2 R^-1 R^-T`` (eq. 20). With ``lambda = 1`` this *is* the batch QR least
   squares of :func:`cdprid.least_squares` on the same rows (tested to 1e-8), apart from the
   prior ``prior_weight * ||x - x0||^2`` that makes ``R`` invertible from the first sample
   (1e-9 by default: negligible).
5. **Excitation** — a short-memory information matrix ``M`` (time constant
   ``excitation_window`` s) of the used rows; ``excitation = sqrt(lambda_min(M / n_rows))`` is
   the RMS regressor entry (m/s^2 or rad/s^2, all columns of ``A`` have those units) along the
   least excited direction of parameter space; ``excitation_ok`` is
   ``excitation >= excitation_threshold``. A static platform gives zero in the ``m z_G``
   direction (only horizontal accelerations carry it) and in every inertia direction, so the
   flag drops; with ``lambda < 1`` the sigmas grow at the same time (covariance wind-up).

The first ``warmup`` seconds (the SIHD start-up transient, as the batch pipeline's trim) are
differentiated but not used by the least squares.

Float64: enable ``jax_enable_x64`` in your script (the CLI does); this module does not change
JAX's configuration on import.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from cdprid.core._covariance import hac_covariance, std_from_cov
from cdprid.core._identification import condition_number
from cdprid.model._dynamics import PARAMETER_NAMES, regressor_full, regressor_translation
from cdprid.model._geometry import CableRobot, wrench_matrix
from cdprid.model._rotations import angular_rates_from_quat, quat_to_matrix
from cdprid.signal._differentiators import METHODS, scan_blocked, sihd2_step

__all__ = [
    "WRENCH_FILTERS",
    "CascadeState",
    "DelayState",
    "MatchedFilterState",
    "OnlineConfig",
    "OnlineState",
    "OnlineSample",
    "OnlineOutput",
    "OnlineResult",
    "RLSResult",
    "online_init",
    "online_step",
    "OnlineStepper",
    "online_identify",
    "recursive_least_squares",
]

WRENCH_FILTERS = ("matched", "delay", "none")
"""Treatments of the measured wrench ``W tau`` (see the module docstring, item 3)."""

SIHD_METHOD = "sihd2-cascade"
"""The causal differentiator of the online identification (the paper's SIHD-2 cascade)."""
_SIHD = SIHD_METHOD


# ----------------------------------------------------------------------------- data


class OnlineConfig(eqx.Module):
    """Constant settings of an online identification (an immutable pytree).

    Attributes
    ----------
    robot : CableRobot
    dt : array ()
        Sampling period, s.
    forgetting : array ()
        Exponential forgetting factor lambda in (0, 1] of the least squares (per sample).
    gains : array (6,)
        SIHD-2 cascade gains ``(lambda1, lambda2, lambda3, lambda4, alpha, mu)``.
    x0 : array (p,)
        Prior mean of the parameters.
    prior_weight : array ()
        Weight delta of the prior ``delta ||x - x0||^2`` (information per parameter).
    warmup : array ()
        Seconds at the start whose rows are not used.
    excitation_forgetting : array ()
        Per-sample forgetting of the excitation information matrix.
    excitation_threshold : array ()
        Minimum RMS regressor entry along the weakest direction, m/s^2.
    model : str
        ``"translation"`` (4 parameters) or ``"full"`` (10).
    wrench_filter : str
        One of :data:`WRENCH_FILTERS`.
    wrench_delay : int
        Delay of ``W tau`` in samples (``wrench_filter="delay"`` only).
    """

    robot: CableRobot
    dt: jnp.ndarray
    forgetting: jnp.ndarray
    gains: jnp.ndarray
    x0: jnp.ndarray
    prior_weight: jnp.ndarray
    warmup: jnp.ndarray
    excitation_forgetting: jnp.ndarray
    excitation_threshold: jnp.ndarray
    model: str = eqx.field(static=True, default="translation")
    wrench_filter: str = eqx.field(static=True, default="matched")
    wrench_delay: int = eqx.field(static=True, default=0)

    @property
    def n_params(self) -> int:
        """Number of parameters p."""
        return len(PARAMETER_NAMES[self.model])


class CascadeState(NamedTuple):
    """State of two SIHD-2 in cascade: each stage's ``(z1, z2)`` (:func:`sihd2_step`'s state)."""

    stage1: tuple
    stage2: tuple


class MatchedFilterState(NamedTuple):
    """State of the matched wrench filter (``wrench_filter="matched"``), (6,) arrays.

    ``integral1``/``integral2`` are the running trapezoidal integrals fed to the two SIHD
    stages, ``stage1``/``stage2`` their ``(z1, z2)`` states, ``y_prev``/``f1_prev`` the previous
    inputs of the integrals, ``scale`` the per-channel amplitude normalisation.
    """

    integral1: jnp.ndarray
    stage1: tuple
    integral2: jnp.ndarray
    stage2: tuple
    y_prev: jnp.ndarray
    f1_prev: jnp.ndarray
    scale: jnp.ndarray


class DelayState(NamedTuple):
    """State of the delayed wrench (``wrench_filter="delay"``): the (D, 6) ring buffer."""

    buffer: jnp.ndarray


class OnlineState(eqx.Module):
    """Carry of :func:`online_step`: the configuration and every recursive state.

    Attributes
    ----------
    config : OnlineConfig
    k : array () int
        Samples consumed so far.
    sihd_p, sihd_q : CascadeState
        SIHD cascade states of the 3 position / 4 quaternion channels.
    q_prev : array (4,)
        Previous quaternion (sign continuity).
    wf : MatchedFilterState, DelayState or tuple
        Wrench-filter state: :class:`MatchedFilterState` for ``"matched"``,
        :class:`DelayState` for ``"delay"``, ``()`` for ``"none"``.
    S : array (p+1, p+1)
        Upper-triangular square-root information factor of ``[W_ID | Y_ID]``.
    n_rows : array ()
        Forgetting-weighted number of rows used.
    M : array (p, p)
        Short-memory information matrix (excitation monitor).
    m_rows : array ()
        Its weighted number of rows.
    """

    config: OnlineConfig
    k: jnp.ndarray
    sihd_p: CascadeState
    sihd_q: CascadeState
    q_prev: jnp.ndarray
    wf: MatchedFilterState | DelayState | tuple
    S: jnp.ndarray
    n_rows: jnp.ndarray
    M: jnp.ndarray
    m_rows: jnp.ndarray


class OnlineSample(NamedTuple):
    """One measured sample: position (3,), unit quaternion (4,) scalar first, tensions (m,)."""

    position: jnp.ndarray
    quaternion: jnp.ndarray
    tension: jnp.ndarray


class OnlineOutput(NamedTuple):
    """What :func:`online_step` yields for one sample (stacked over time by the scan).

    Attributes
    ----------
    velocity, acceleration : (3,)
        SIHD estimates of P's velocity and acceleration, base frame.
    omega, alpha : (3,)
        Angular velocity and acceleration, base frame (zeros for the translation model).
    A : (6, p)
        Regressor of the sample.
    y : (6,)
        Wrench ``W tau`` after the wrench filter (the right-hand side actually used).
    x, sigma : (p,)
        Current estimate and standard deviations ``sqrt(sigma_rho^2 diag P)``.
    sigma_rho : ()
        Current residual standard deviation (nan until more rows than parameters).
    excitation : ()
        ``sqrt(lambda_min(M / n))``, m/s^2.
    excitation_ok : () bool
    used : () bool
        Whether the sample's rows entered the least squares (False during the warm-up).
    """

    velocity: jnp.ndarray
    acceleration: jnp.ndarray
    omega: jnp.ndarray
    alpha: jnp.ndarray
    A: jnp.ndarray
    y: jnp.ndarray
    x: jnp.ndarray
    sigma: jnp.ndarray
    sigma_rho: jnp.ndarray
    excitation: jnp.ndarray
    excitation_ok: jnp.ndarray
    used: jnp.ndarray


@dataclasses.dataclass(frozen=True)
class RLSResult:
    """Per-sample output of :func:`recursive_least_squares` (numpy arrays).

    Attributes
    ----------
    x, sigma : (n, p)
    sigma_rho : (n,)
    cov : (p, p)
        Final covariance ``sigma_rho^2 R^-1 R^-T``.
    S : (p+1, p+1)
        Final square-root information factor.
    """

    x: np.ndarray
    sigma: np.ndarray
    sigma_rho: np.ndarray
    cov: np.ndarray
    S: np.ndarray


@dataclasses.dataclass(frozen=True)
class OnlineResult:
    """Result of :func:`online_identify` (numpy arrays, one row per sample).

    Attributes
    ----------
    t : (n,)
    names : tuple of str
    model : str
    x, sigma : (n, p)
        Parameter trajectory and its standard deviations.
    sigma_rho : (n,)
    excitation : (n,)
    excitation_ok : (n,) bool
    used : (n,) bool
    velocity, acceleration, omega, alpha : (n, 3)
    A : (n, 6, p)
    y : (n, 6)
    cov : (p, p)
        Final covariance.
    cond, cond_scaled : float
        Condition numbers of the (forgetting-weighted) stacked regressor, from the final R.
    n_samples : int
        Samples used by the least squares.
    forgetting : float
    wrench_filter : str
    """

    t: np.ndarray
    names: tuple
    model: str
    x: np.ndarray
    sigma: np.ndarray
    sigma_rho: np.ndarray
    excitation: np.ndarray
    excitation_ok: np.ndarray
    used: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    A: np.ndarray
    y: np.ndarray
    cov: np.ndarray
    cond: float
    cond_scaled: float
    n_samples: int
    forgetting: float
    wrench_filter: str

    @property
    def x_final(self) -> np.ndarray:
        """Final estimate (p,)."""
        return self.x[-1]

    @property
    def std_final(self) -> np.ndarray:
        """Final standard deviations (p,)."""
        return self.sigma[-1]

    def hac_cov_final(self) -> tuple[np.ndarray, float]:
        """HAC covariance of the final estimate and its bandwidth (:mod:`cdprid.core._covariance`).

        The sandwich over the rows the recursion used, each sample weighted
        ``sqrt(lambda^(n-1-k))`` as in the RLS cost; the RLS's own ``sigma`` (eq. 20) assumes
        independent residuals, which the filtered online residuals are not.
        """
        u = np.asarray(self.used, bool)
        if u.sum() <= len(self.names):
            return self.cov, float("nan")
        A, y = np.asarray(self.A)[u], np.asarray(self.y)[u]
        k = np.arange(u.sum())
        w = np.sqrt(self.forgetting ** (k[-1] - k))[:, None]
        e = (y - np.einsum("nrp,p->nr", A, self.x_final)) * w
        cov, bw = hac_covariance(A * w[:, :, None], e)
        return cov, bw

    def as_json(self) -> dict:
        """The JSON contract of ``cdprid identify --json`` for the final estimate.

        ``std`` is the HAC standard deviation of the final estimate; ``std_iid`` the RLS's
        eq. 20 value.
        """
        x, si = self.x_final, self.std_final
        cov, bw = self.hac_cov_final()
        s = std_from_cov(cov)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = 100.0 * s / np.abs(x)
        return {
            "model": self.model,
            "parameters": {
                n: {"value": float(v), "std": float(e), "rel_std_percent": float(r),
                    "std_iid": float(b)}
                for n, v, e, r, b in zip(self.names, x, s, rel, si, strict=True)
            },
            "sigma_rho": float(self.sigma_rho[-1]),
            "cond": self.cond,
            "cond_scaled": self.cond_scaled,
            "n_samples": self.n_samples,
            "covariance": "hac",
            "hac_bandwidth_samples": None if not np.isfinite(bw) else bw,
        }


# ----------------------------------------------------------------------------- RLS kernel


def _rls_init(x0, prior_weight):
    p = x0.shape[0]
    r = jnp.sqrt(prior_weight)
    S = jnp.zeros((p + 1, p + 1), x0.dtype)
    S = S.at[:p, :p].set(r * jnp.eye(p, dtype=x0.dtype)).at[:p, p].set(r * x0)
    return S


def _rls_update(S, n_rows, A, y, lam, use):
    """Square-root information update with the rows ``[A y]`` (weight ``use`` in {0, 1})."""
    lam = jnp.where(use, lam, 1.0)
    w = jnp.where(use, 1.0, 0.0)
    Z = jnp.concatenate([jnp.sqrt(lam) * S, w * jnp.concatenate([A, y[:, None]], axis=1)], axis=0)
    S = jnp.linalg.qr(Z, mode="r")
    n_rows = lam * n_rows + w * A.shape[0]
    return S, n_rows


def _rls_solution(S, n_rows):
    """Estimate, standard deviations and sigma_rho from the factor (eqs. 15, 19, 20)."""
    p = S.shape[0] - 1
    R = S[:p, :p]
    Rinv = jax.scipy.linalg.solve_triangular(R, jnp.eye(p, dtype=S.dtype), lower=False)
    x = Rinv @ S[:p, p]
    diagP = jnp.sum(Rinv**2, axis=1)
    dof = n_rows - p
    s2 = jnp.where(dof > 0, S[p, p] ** 2 / jnp.where(dof > 0, dof, 1.0), jnp.nan)
    return x, jnp.sqrt(s2 * diagP), jnp.sqrt(s2)


@jax.jit
def _rls_scan(A, y, lam, x0, prior_weight):
    def body(carry, inp):
        S, n = carry
        Ak, yk = inp
        S, n = _rls_update(S, n, Ak, yk, lam, True)
        x, sig, srho = _rls_solution(S, n)
        return (S, n), (x, sig, srho)

    S0 = _rls_init(x0, prior_weight)
    (S, n), out = jax.lax.scan(body, (S0, jnp.zeros((), A.dtype)), (A, y))
    return S, n, out


def recursive_least_squares(A, y, forgetting: float = 1.0, x0=None,
                            prior_weight: float = 1e-9) -> RLSResult:
    """Recursive least squares over given per-sample rows (the RLS kernel alone).

    Parameters
    ----------
    A : array (n, r, p)
        Regressor rows of each sample (r = 6 for a CDPR).
    y : array (n, r)
        Right-hand sides.
    forgetting : float
        lambda in (0, 1]; 1 = growing-memory least squares.
    x0 : array (p,), optional
        Prior mean (default zeros).
    prior_weight : float
        delta of the prior ``delta ||x - x0||^2`` (>= 0; keeps R invertible from sample 0).

    Returns
    -------
    RLSResult
    """
    A = np.asarray(A, np.float64)
    y = np.asarray(y, np.float64)
    if A.ndim != 3 or y.shape != A.shape[:2]:
        raise ValueError(f"A must be (n, r, p) and y (n, r); got {A.shape} and {y.shape}.")
    _check_forgetting(forgetting)
    p = A.shape[2]
    x0 = np.zeros(p) if x0 is None else np.asarray(x0, np.float64).reshape(p)
    with _x64_scope():
        S, n, (x, sig, srho) = _rls_scan(jnp.asarray(A), jnp.asarray(y), jnp.asarray(forgetting),
                                         jnp.asarray(x0), jnp.asarray(float(prior_weight)))
        S = np.asarray(S)
    Rinv = np.linalg.solve(S[:p, :p], np.eye(p))
    srho = np.asarray(srho)
    return RLSResult(np.asarray(x), np.asarray(sig), srho, srho[-1] ** 2 * Rinv @ Rinv.T, S)


# ----------------------------------------------------------------------------- step


def _x64_scope():
    if jax.config.read("jax_enable_x64"):
        return contextlib.nullcontext()
    return jax.enable_x64(True)  # pragma: no cover - callers normally enable x64


def _check_forgetting(f):
    if not (isinstance(f, (int, float)) and math.isfinite(f) and 0.0 < f <= 1.0):
        raise ValueError(f"the forgetting factor must be a number in (0, 1], got {f!r}.")


def online_init(
    robot: CableRobot,
    dt: float,
    model: str = "translation",
    forgetting: float = 1.0,
    gains: dict | None = None,
    wrench_filter: str = "matched",
    wrench_delay: int = 30,
    x0=None,
    prior_weight: float = 1e-9,
    warmup: float = 1.0,
    excitation_window: float = 1.0,
    excitation_threshold: float = 0.1,
) -> OnlineState:
    """Initial state of an online identification.

    Parameters
    ----------
    robot : CableRobot
    dt : float
        Sampling period of the pose/tension samples, s.
    model : {"translation", "full"}
        Paper eq. (10) (m, m s_G) or the 10-parameter model (plus the inertia about P).
    forgetting : float
        Exponential forgetting factor lambda in (0, 1]; memory ``dt / (1 - lambda)`` s.
    gains : dict, optional
        SIHD-2 cascade gains overriding ``METHODS["sihd2-cascade"].params`` (eq. 35).
    wrench_filter : {"matched", "delay", "none"}
        Lag compensation applied to ``W tau`` (module docstring, item 3).
    wrench_delay : int
        Delay in samples for ``wrench_filter="delay"`` (30 = 0.3 s at 100 Hz, the SIHD
        cascade's lag at 0.25 Hz with eq.-35 gains).
    x0 : array (p,), optional
        Prior mean (default zeros).
    prior_weight : float
        Prior information per parameter (>= 0).
    warmup : float
        Seconds at the start not used by the least squares.
    excitation_window : float
        Time constant of the excitation monitor, s.
    excitation_threshold : float
        Threshold of ``excitation`` (m/s^2) below which ``excitation_ok`` is False.

    Returns
    -------
    OnlineState
    """
    if model not in PARAMETER_NAMES:
        raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")
    if wrench_filter not in WRENCH_FILTERS:
        raise ValueError(f"unknown wrench filter {wrench_filter!r}; use one of "
                         f"{', '.join(WRENCH_FILTERS)}.")
    _check_forgetting(forgetting)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}.")
    g = dict(METHODS[_SIHD].params)
    bad = sorted(set(gains or {}) - set(g))
    if bad:
        raise ValueError(f"unknown SIHD gain(s) {', '.join(bad)}; valid: {', '.join(g)}.")
    g.update({k: float(v) for k, v in (gains or {}).items()})
    if not all(math.isfinite(v) and v > 0 for v in g.values()) or not 0.5 <= g["alpha"] <= 1:
        raise ValueError(f"SIHD gains must be finite and > 0 with 0.5 <= alpha <= 1, got {g}.")
    delay = int(wrench_delay) if wrench_filter == "delay" else 0
    if wrench_filter == "delay" and delay < 1:
        raise ValueError(f"wrench_delay must be >= 1 sample, got {wrench_delay!r}.")
    p = len(PARAMETER_NAMES[model])
    f64 = jnp.float64
    x0 = jnp.zeros(p, f64) if x0 is None else jnp.asarray(x0, f64).reshape(p)
    cfg = OnlineConfig(
        robot=robot,
        dt=jnp.asarray(dt, f64),
        forgetting=jnp.asarray(forgetting, f64),
        gains=jnp.asarray([g[k] for k in ("lambda1", "lambda2", "lambda3", "lambda4",
                                          "alpha", "mu")], f64),
        x0=x0,
        prior_weight=jnp.asarray(prior_weight, f64),
        warmup=jnp.asarray(warmup, f64),
        excitation_forgetting=jnp.asarray(math.exp(-dt / excitation_window), f64),
        excitation_threshold=jnp.asarray(excitation_threshold, f64),
        model=model,
        wrench_filter=wrench_filter,
        wrench_delay=delay,
    )
    z3, z4, z6 = (jnp.zeros(n, f64) for n in (3, 4, 6))
    if wrench_filter == "matched":
        wf = MatchedFilterState(z6, (z6, z6), z6, (z6, z6), z6, z6, jnp.ones(6, f64))
    elif wrench_filter == "delay":
        wf = DelayState(jnp.zeros((delay, 6), f64))
    else:
        wf = ()
    return OnlineState(
        config=cfg,
        k=jnp.zeros((), jnp.int64 if jax.config.read("jax_enable_x64") else jnp.int32),
        sihd_p=CascadeState((z3, z3), (z3, z3)),
        sihd_q=CascadeState((z4, z4), (z4, z4)),
        q_prev=jnp.asarray([1.0, 0.0, 0.0, 0.0], f64),
        wf=wf,
        S=_rls_init(x0, cfg.prior_weight),
        n_rows=jnp.zeros((), f64),
        M=jnp.zeros((p, p), f64),
        m_rows=jnp.zeros((), f64),
    )


def _cascade(state, y, first, gains, h):
    """Two SIHD-2 in cascade (as ``differentiate(method="sihd2-cascade")``), any channel shape."""
    s1, s2 = state.stage1, state.stage2
    g1 = (gains[0], gains[1], gains[4], gains[5])
    g2 = (gains[2], gains[3], gains[4], gains[5])
    # first sample: stage 1 starts at (y0, 0) and stage 2 at (0, 0), as the batch scan
    s1 = (jnp.where(first, y, s1[0]), jnp.where(first, 0.0, s1[1]))
    s2 = jax.tree_util.tree_map(lambda z: jnp.where(first, 0.0, z), s2)
    s1, v = sihd2_step(s1, y, g1, h)
    s2, a = sihd2_step(s2, v, g2, h)
    return CascadeState(s1, s2), v, a


def _matched_filter(wf, y, first, gains, h, cfg):
    """The SIHD cascade applied to the running integrals of the (scaled) wrench."""
    I1, st1, I2, st2 = wf.integral1, wf.stage1, wf.integral2, wf.stage2
    y_prev, f1_prev, scale = wf.y_prev, wf.f1_prev, wf.scale
    g1 = (gains[0], gains[1], gains[4], gains[5])
    g2 = (gains[2], gains[3], gains[4], gains[5])
    gnorm = jnp.linalg.norm(cfg.robot.gravity)
    m_seen = jnp.maximum(jnp.linalg.norm(y[:3]) / gnorm, 1e-6)
    radius = jnp.max(jnp.linalg.norm(cfg.robot.P_b, axis=1))
    scale0 = jnp.concatenate([jnp.full(3, m_seen), jnp.full(3, m_seen * radius)])
    scale = jnp.where(first, scale0, scale)
    u = y / scale
    # start in steady state: a constant wrench passes unchanged, as a platform at rest
    # gives zero velocity and acceleration
    y_prev = jnp.where(first, u, y_prev)
    I1 = I1 + 0.5 * h * (u + y_prev)
    st1 = (jnp.where(first, I1, st1[0]), jnp.where(first, u, st1[1]))
    st1, f1 = sihd2_step(st1, I1, g1, h)
    f1_prev = jnp.where(first, f1, f1_prev)
    I2 = I2 + 0.5 * h * (f1 + f1_prev)
    st2 = (jnp.where(first, I2, st2[0]), jnp.where(first, f1, st2[1]))
    st2, f2 = sihd2_step(st2, I2, g2, h)
    return MatchedFilterState(I1, st1, I2, st2, u, f1, scale), f2 * scale


def _online_step(state: OnlineState, sample: OnlineSample):
    cfg = state.config
    robot, h, gains = cfg.robot, cfg.dt, cfg.gains
    first = state.k == 0
    p_meas = jnp.asarray(sample.position, h.dtype)
    q = jnp.asarray(sample.quaternion, h.dtype)
    tau = jnp.asarray(sample.tension, h.dtype)

    # 1. motion (causal SIHD cascade)
    sihd_p, v, a = _cascade(state.sihd_p, p_meas, first, gains, h)
    q_prev = jnp.where(first, q, state.q_prev)
    q = jnp.where(q @ q_prev < 0, -q, q)  # sign continuity
    B_R_P = quat_to_matrix(q)
    if cfg.model == "full":
        sihd_q, qd, qdd = _cascade(state.sihd_q, q, first, gains, h)
        om, al = angular_rates_from_quat(q, qd, qdd)
        A = regressor_full(B_R_P, a, om, al, robot.gravity)
    else:
        sihd_q = state.sihd_q
        om = al = jnp.zeros(3, h.dtype)
        A = regressor_translation(B_R_P, a, robot.gravity)

    # 2.-3. measured wrench and its lag compensation
    y = wrench_matrix(robot, p_meas, B_R_P) @ tau
    if cfg.wrench_filter == "matched":
        wf, y = _matched_filter(state.wf, y, first, gains, h, cfg)
    elif cfg.wrench_filter == "delay":
        buf = state.wf.buffer
        buf = jnp.where(first, jnp.broadcast_to(y, buf.shape), buf)
        y, buf = buf[0], jnp.concatenate([buf[1:], y[None]], axis=0)
        wf = DelayState(buf)
    else:
        wf = state.wf

    # 4. recursive least squares (square-root information form)
    use = state.k.astype(h.dtype) * h >= cfg.warmup - 1e-9 * h
    S, n_rows = _rls_update(state.S, state.n_rows, A, y, cfg.forgetting, use)
    x, sigma, sigma_rho = _rls_solution(S, n_rows)

    # 5. excitation monitor
    le = jnp.where(use, cfg.excitation_forgetting, 1.0)
    M = le * state.M + jnp.where(use, 1.0, 0.0) * (A.T @ A)
    m_rows = le * state.m_rows + jnp.where(use, 6.0, 0.0)
    lam_min = jnp.linalg.eigvalsh(M / jnp.maximum(m_rows, 1.0))[0]
    exc = jnp.sqrt(jnp.maximum(lam_min, 0.0))
    ok = (exc >= cfg.excitation_threshold) & (m_rows > 0)

    new = OnlineState(cfg, state.k + 1, sihd_p, sihd_q, q, wf, S, n_rows, M, m_rows)
    return new, OnlineOutput(v, a, om, al, A, y, x, sigma, sigma_rho, exc, ok, use)


online_step = jax.jit(_online_step)
online_step.__doc__ = """Consume one sample; jitted (compiled once per model, wrench filter, robot).

Parameters
----------
state : OnlineState
    From :func:`online_init` or a previous call.
sample : OnlineSample
    ``(position (3,), quaternion (4,), tension (m,))``; pass ``[1, 0, 0, 0]`` when the
    orientation is not measured.

Returns
-------
state : OnlineState
out : OnlineOutput

Examples
--------
>>> st = online_init(robot, 0.01)                              # doctest: +SKIP
>>> for p, q, tau in stream:                                    # doctest: +SKIP
...     st, out = online_step(st, OnlineSample(p, q, tau))
...     print(out.x, out.sigma, bool(out.excitation_ok))
"""


def _step_without_regressor(state, sample):
    new, out = _online_step(state, sample)
    return new, out._replace(A=jnp.zeros((0,), out.A.dtype))


@jax.jit
def _online_scan(state, samples):
    """The online step over a record; outputs stacked as ``lax.scan`` does.

    The per-step outputs are gathered in small blocks (:func:`cdprid.signal._differentiators.
    scan_blocked`: XLA:CPU then runs the step on its lean sequential path) and the regressor
    rows ``A`` (the largest output) are recomputed afterwards, vectorised, from the
    estimated motion: the same function of the same numbers.
    """
    cfg = state.config
    # translation model: blocks of 2 steps, the fastest in our measurements (the shift
    # register copies every output at each step, so longer blocks cost more than they save).
    # The full model's (11, 11) factor is too large for XLA's small-buffer path, so it gains
    # nothing from blocking: plain scan.
    block = 2 if cfg.model == "translation" else 0
    new, out = scan_blocked(_step_without_regressor, state, samples, block, return_carry=True)
    q = samples.quaternion.astype(cfg.dt.dtype)
    B_R_P = jax.vmap(quat_to_matrix)(q)
    g = cfg.robot.gravity
    if cfg.model == "full":
        A = jax.vmap(lambda R, a, om, al: regressor_full(R, a, om, al, g))(
            B_R_P, out.acceleration, out.omega, out.alpha)
    else:
        A = jax.vmap(lambda R, a: regressor_translation(R, a, g))(B_R_P, out.acceleration)
    return new, out._replace(A=A)


def _recursive_part(state: OnlineState) -> tuple:
    """Every field of the state but its (constant) configuration."""
    return tuple(getattr(state, f.name) for f in dataclasses.fields(state))[1:]


class OnlineStepper:
    """Real-time driver of :func:`online_step`: one compiled call per sample, flat buffers.

    Calling the jitted :func:`online_step` from Python moves the whole state (about 40
    arrays, the robot included) through JAX's dispatch at every sample (results/online.md
    gives both costs). The stepper
    compiles the step once, ahead of time, with the configuration closed over and the
    recursive state packed into one float64 vector, so that each call passes one state vector
    and one sample vector in and gets two vectors back (``benchmarks/online.py`` measures
    both). Same numbers as :func:`online_step` (tested).

    Parameters
    ----------
    state : OnlineState
        From :func:`online_init` (or a later state).

    Examples
    --------
    >>> stepper = OnlineStepper(online_init(robot, 0.01))            # doctest: +SKIP
    >>> for p, q, tau in stream:                                      # doctest: +SKIP
    ...     out = stepper.step(p, q, tau)        # OnlineOutput of numpy arrays
    ...     print(out.x, out.sigma, bool(out.excitation_ok))
    """

    def __init__(self, state: OnlineState):
        from jax.flatten_util import ravel_pytree

        with _x64_scope():
            self._config = cfg = state.config
            flat, unravel = ravel_pytree(_recursive_part(state))
            self._unravel = unravel
            self._m = int(cfg.robot.n_cables)
            sample0 = OnlineSample(jnp.zeros(3), jnp.asarray([1.0, 0, 0, 0]), jnp.zeros(self._m))
            out_shape = jax.eval_shape(_online_step, state, sample0)[1]
            self._out_fields = []
            off = 0
            for name, sd in zip(OnlineOutput._fields, out_shape, strict=True):
                size = int(np.prod(sd.shape))
                self._out_fields.append((name, off, size, sd.shape, np.dtype(sd.dtype)))
                off += size

            def flat_step(flat_state, sample):
                st = OnlineState(cfg, *unravel(flat_state))
                smp = OnlineSample(sample[:3], sample[3:7], sample[7:])
                new, out = _online_step(st, smp)
                new_flat, _ = ravel_pytree(_recursive_part(new))
                out_flat = jnp.concatenate([jnp.ravel(v).astype(flat_state.dtype) for v in out])
                return new_flat, out_flat

            n_out = off

            def flat_step_in_loop(flat_state, sample, trips):
                # a loop of ``trips`` (= 1) iterations whose count XLA cannot see: XLA:CPU
                # runs a loop body on its lean executor path, a top-level program through
                # its concurrent one (several times slower for ~100 tiny kernels); same
                # operations, same numbers
                def body(i, c):
                    return flat_step(c[0], sample)

                init = (flat_state, jnp.zeros(n_out, flat_state.dtype))
                return jax.lax.fori_loop(0, trips, body, init)

            self._flat = flat
            self._one = jnp.ones((), jnp.int32)
            self._compiled = (
                jax.jit(flat_step_in_loop).lower(
                    flat, jnp.zeros(7 + self._m, flat.dtype), self._one
                ).compile()
            )

    def step(self, position, quaternion, tension) -> OnlineOutput:
        """Consume one sample (position (3,), quaternion (4,) scalar first, tensions (m,)).

        Returns
        -------
        OnlineOutput
            numpy arrays for this sample.
        """
        parts = [np.asarray(v, np.float64).ravel() for v in (position, quaternion, tension)]
        for name, v, size in zip(("position", "quaternion", "tension"), parts,
                                 (3, 4, self._m), strict=True):
            if v.size != size:
                raise ValueError(f"OnlineStepper.step: {name} must have {size} values, "
                                 f"got {v.size}.")
        sample = np.concatenate(parts)
        self._flat, out = self._compiled(self._flat, sample, self._one)
        out = np.asarray(out)
        return OnlineOutput(*(out[o:o + n].reshape(shape).astype(dt)
                              for _, o, n, shape, dt in self._out_fields))

    @property
    def state(self) -> OnlineState:
        """The current :class:`OnlineState` (unpacked from the flat vector)."""
        return OnlineState(self._config, *self._unravel(self._flat))


# ----------------------------------------------------------------------------- batch driver


def _as_arrays(signals):
    if hasattr(signals, "position") and hasattr(signals, "tension"):
        t, pos, tau = signals.t, signals.position, signals.tension
        q = getattr(signals, "quaternion", None)
    else:
        d = dict(signals)
        t, pos, tau, q = d["t"], d["position"], d["tension"], d.get("quaternion")
    t = np.asarray(t, np.float64)
    pos = np.asarray(pos, np.float64)
    tau = np.asarray(tau, np.float64)
    n = t.shape[0]
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if q is None else np.asarray(q, np.float64)
    if pos.shape != (n, 3) or q.shape != (n, 4) or tau.ndim != 2 or tau.shape[0] != n:
        raise ValueError(f"signals must hold t (n,), position (n, 3), quaternion (n, 4) and "
                         f"tension (n, m); got {t.shape}, {pos.shape}, {q.shape}, {tau.shape}.")
    if n < 3:
        raise ValueError(f"online identification needs at least 3 samples, got {n}.")
    return t, pos, q, tau


def online_identify(signals, robot: CableRobot, model: str = "translation",
                    forgetting: float = 1.0, gains: dict | None = None, **options) -> OnlineResult:
    """Run the online identification over recorded signals (one ``lax.scan``).

    Parameters
    ----------
    signals : AlignedSignals or mapping
        :func:`cdprid.align` output, or a mapping with ``t`` (n,), ``position`` (n, 3),
        ``tension`` (n, m) and optionally ``quaternion`` (n, 4); uniform sampling.
    robot : CableRobot
    model : {"translation", "full"}
    forgetting : float
        lambda in (0, 1].
    gains : dict, optional
        SIHD-2 cascade gains (default: the paper's, eq. 35).
    **options
        Further keywords of :func:`online_init` (``wrench_filter``, ``wrench_delay``, ``x0``,
        ``prior_weight``, ``warmup``, ``excitation_window``, ``excitation_threshold``).

    Returns
    -------
    OnlineResult
    """
    t, pos, q, tau = _as_arrays(signals)
    if tau.shape[1] != robot.n_cables:
        raise ValueError(f"the tensions have {tau.shape[1]} columns but the robot has "
                         f"{robot.n_cables} cables.")
    dt = float(np.median(np.diff(t)))
    with _x64_scope():
        st0 = online_init(robot, dt, model, forgetting, gains, **options)
        st, out = _online_scan(st0, OnlineSample(jnp.asarray(pos), jnp.asarray(q),
                                                 jnp.asarray(tau)))
        o = OnlineOutput(*(np.asarray(v) for v in out))
        S = np.asarray(st.S)
    p = st0.config.n_params
    R = S[:p, :p]
    Rinv = np.linalg.solve(R, np.eye(p))
    cov = float(o.sigma_rho[-1]) ** 2 * (Rinv @ Rinv.T)
    return OnlineResult(
        t=t, names=PARAMETER_NAMES[model], model=model, x=o.x, sigma=o.sigma,
        sigma_rho=o.sigma_rho, excitation=o.excitation, excitation_ok=o.excitation_ok.astype(bool),
        used=o.used.astype(bool), velocity=o.velocity, acceleration=o.acceleration,
        omega=o.omega, alpha=o.alpha, A=o.A, y=o.y, cov=cov,
        cond=condition_number(R), cond_scaled=condition_number(R, scaled=True),
        n_samples=int(o.used.sum()), forgetting=float(forgetting),
        wrench_filter=st0.config.wrench_filter,
    )


# ----------------------------------------------------------------------------- CLI
