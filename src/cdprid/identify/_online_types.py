"""Types of online identification: configuration, scan state and samples, outputs,
results."""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.core import Estimate, Estimates, hac_covariance, parameter_unit, std_from_cov
from cdprid.model import PARAMETER_NAMES, CableRobot

WRENCH_FILTERS = ("matched", "delay", "none")


SIHD_METHOD = "sihd2-cascade"


_SIHD = SIHD_METHOD


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
    fir : array (L + 1,)
        Taps of the rotation-consistent matched filter of the full model (position ->
        acceleration, :func:`cdprid.core._linear_match.reference_fir`; empty otherwise).
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
    fir: jnp.ndarray
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


class IntegralStage(NamedTuple):
    """One SIHD stage fed with a running trapezoidal integral: applies ``H / s`` to its input
    (``H`` the stage's derivative transfer), any channel shape."""

    integral: jnp.ndarray
    stage: tuple
    u_prev: jnp.ndarray


class RotationFilterState(NamedTuple):
    """The matched filter F of the wrench applied to the pose terms of the regressor, so that
    every term of the regression passes the same filter (issue 24): ``F[R]`` (9 entries of
    ``B_R_P``), ``F[q]`` and ``F[dq/dt]`` (with ``F[d2q/dt2]`` from the quaternion cascade).
    ``F = H2 H1 / s^2``: stage 1 of the cascade after one integration, then stage 2 after
    another."""

    R1: IntegralStage
    R2: IntegralStage
    q1: IntegralStage
    q2: IntegralStage
    qd2: IntegralStage


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


class LinearMatchState(NamedTuple):
    """Rotation-consistent matched filter of the full model (:mod:`cdprid.core._linear_match`).

    The rows are those of sample ``k - 3``: its accelerations and angular rates come from
    centred differences over samples ``k - 6 .. k`` (never from the sample itself), every
    regressor term and ``W tau`` pass the causal FIR ``config.fir`` through their running double
    integral, and the translational acceleration is the FIR applied to the positions.

    Attributes
    ----------
    pos, quat, wtau : arrays (7, 3), (7, 4), (7, 6)
        The last 7 positions, sign-continuous quaternions and wrenches, newest first.
    R0 : array (3, 3)
        First orientation (the constant reference of the linear part).
    u0, u_prev, i1 : arrays (6 p + 6,)
        First value of the filtered channels, previous value minus ``u0``, running integral.
    hist : array (L + 1, 6 p + 6)
        Double integrals of the channels, newest first.
    phist : array (L + 1, 3)
        Positions of the row samples, newest first.
    """

    pos: jnp.ndarray
    quat: jnp.ndarray
    wtau: jnp.ndarray
    R0: jnp.ndarray
    u0: jnp.ndarray
    u_prev: jnp.ndarray
    i1: jnp.ndarray
    hist: jnp.ndarray
    phist: jnp.ndarray


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
    rot : RotationFilterState
        The wrench's matched filter applied to the rotation terms of the regressor.
    lm : LinearMatchState or tuple
        The full model's rotation-consistent matched filter (``()`` otherwise).
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
    rot: RotationFilterState
    lm: LinearMatchState | tuple = ()


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
    episodes : tuple of Episode
        Episodes flagged as they happened (``online_identify(..., episodes=True)``).
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
    episodes: tuple = ()

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

        Returns
        -------
        cov : ndarray (p, p)
            Covariance of the final estimate, in the parameters' units squared; the RLS's own
            ``cov`` when no more rows than parameters were used.
        bandwidth : float
            The HAC bandwidth, samples (NaN in that case).
        """
        u = np.asarray(self.used, bool)
        if u.sum() <= len(self.names):
            return self.cov, float("nan")
        A, y = np.asarray(self.A)[u], np.asarray(self.y)[u]
        k = np.arange(u.sum())
        w = np.sqrt(self.forgetting ** (k[-1] - k))[:, None]
        e = (y - np.einsum("nrp,p->nr", A, self.x_final)) * w
        mb = 1.0
        if self.model == "full" and self.wrench_filter == "matched":  # the FIR's memory
            from cdprid.core import fir_length

            mb = float(fir_length(float(np.median(np.diff(self.t)))) + 1)
        cov, bw = hac_covariance(A * w[:, :, None], e, min_bandwidth=mb)
        return cov, bw

    def _final_estimates(self) -> tuple[Estimates, float]:
        """The final estimates (std: HAC; ``std_iid``: the RLS's eq. 20) and the HAC bandwidth."""
        x, si = self.x_final, self.std_final
        cov, bw = self.hac_cov_final()
        s = std_from_cov(cov)
        items = tuple(Estimate(n, float(v), float(e), float(b), parameter_unit(n))
                      for n, v, e, b in zip(self.names, x, s, si, strict=True))
        return Estimates(items, cov, np.diag(np.asarray(si, float) ** 2)), bw

    def parameters(self) -> Estimates:
        """The final estimate, typed (value, HAC std, ``std_iid``, unit, 95 % interval per
        parameter; no Cramer-Rao bound online).

        Returns
        -------
        cdprid.core.Estimates
        """
        return self._final_estimates()[0]

    def as_json(self) -> dict:
        """The JSON contract of ``cdprid identify --json`` for the final estimate.

        ``std`` is the HAC standard deviation of the final estimate; ``std_iid`` the RLS's
        eq. 20 value.

        Returns
        -------
        dict
            ``model``, ``parameters`` (``{name: {"value", "std", "rel_std_percent",
            "std_iid"}}``), ``sigma_rho``, ``cond``, ``cond_scaled``, ``n_samples``,
            ``covariance`` ("hac"), ``hac_bandwidth_samples``.
        """
        est, bw = self._final_estimates()
        return {
            "model": self.model,
            "parameters": est.as_json(bound=False),
            "sigma_rho": float(self.sigma_rho[-1]),
            "cond": self.cond,
            "cond_scaled": self.cond_scaled,
            "n_samples": self.n_samples,
            "covariance": "hac",
            "hac_bandwidth_samples": None if not np.isfinite(bw) else bw,
        }
