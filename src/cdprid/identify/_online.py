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
     For the **full model**, matched filtering is rotation-consistent instead
     (:mod:`cdprid.core._linear_match`): every regressor term and ``y`` pass one causal
     FIR (fitted at :func:`online_init` to the cascade's response on a reference motion),
     the rotation terms are formed from centred differences of samples ``k - 6 .. k``, and the
     rows ``(A, y)`` output at sample ``k`` are those of sample ``k - 3``. The cascade's own
     motion is still reported.
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

import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.core import condition_number
from cdprid.identify._online_episodes import (
    detector_settings,
    episode_rows,
    online_episodes,
    run_detect_scan,
)
from cdprid.identify._online_step import _online_scan, _x64_scope, online_init, online_step
from cdprid.identify._online_types import OnlineOutput, OnlineResult, OnlineSample
from cdprid.model import PARAMETER_NAMES, CableRobot

"""Treatments of the measured wrench ``W tau`` (see the module docstring, item 3)."""


"""The causal differentiator of the online identification (the paper's SIHD-2 cascade)."""


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
        raise InputError(f"signals must hold t (n,), position (n, 3), quaternion (n, 4) and "
                         f"tension (n, m); got {t.shape}, {pos.shape}, {q.shape}, {tau.shape}.")
    if n < 3:
        raise InputError(f"online identification needs at least 3 samples, got {n}.")
    return t, pos, q, tau


def online_identify(signals, robot: CableRobot, model: str = "translation",
                    forgetting: float = 1.0, gains: dict | None = None,
                    episodes: bool | dict = False, **options) -> OnlineResult:
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
    episodes : bool or dict
        Flag episodes as they happen (:mod:`cdprid.identify._online_episodes`): the update is
        frozen during them and restarted at a payload step. A dict gives keywords of
        :func:`detector_settings` (``freeze=False`` only reports them).
    **options
        Further keywords of :func:`online_init` (``wrench_filter``, ``wrench_delay``, ``x0``,
        ``prior_weight``, ``warmup``, ``excitation_window``, ``excitation_threshold``).

    Returns
    -------
    OnlineResult
    """
    t, pos, q, tau = _as_arrays(signals)
    if tau.shape[1] != robot.n_cables:
        raise InputError(f"the tensions have {tau.shape[1]} columns but the robot has "
                         f"{robot.n_cables} cables.")
    dt = float(np.median(np.diff(t)))
    with _x64_scope():
        st0 = online_init(robot, dt, model, forgetting, gains, **options)
        smp = OnlineSample(jnp.asarray(pos), jnp.asarray(q), jnp.asarray(tau))
        found = ()
        if episodes is False:
            st, out = _online_scan(st0, smp)
            o = OnlineOutput(*(np.asarray(v) for v in out))
        else:
            kw = dict(episodes) if isinstance(episodes, dict) else {}
            kw.setdefault("prior_weight", float(st0.config.prior_weight))
            lag = int(round(kw.get("short_s", 0.1) / dt))
            st, o, dout = run_detect_scan(st0, smp, detector_settings(dt, **kw))
            found = tuple(online_episodes(t, o.x, PARAMETER_NAMES[model], dout, lag))
            if kw.get("freeze", True):  # rows rolled back at an alarm were not used
                o = o._replace(used=o.used & ~episode_rows(dout))
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
        wrench_filter=st0.config.wrench_filter, episodes=found,
    )
