"""The online step: initial state, causal SIHD cascade, matched wrench filter, one
sample's update inside lax.scan, and the compiled stepper."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.core import reference_fir
from cdprid.identify._online_types import (
    _SIHD,
    WRENCH_FILTERS,
    CascadeState,
    DelayState,
    IntegralStage,
    LinearMatchState,
    MatchedFilterState,
    OnlineConfig,
    OnlineOutput,
    OnlineSample,
    OnlineState,
    RotationFilterState,
)
from cdprid.identify._rls import (
    _check_forgetting,
    _rls_init,
    _rls_solution,
    _rls_update,
    _x64_scope,
)
from cdprid.model import (
    PARAMETER_NAMES,
    CableRobot,
    angular_rates_from_quat,
    quat_to_matrix,
    regressor_full,
    regressor_translation,
    wrench_matrix,
)
from cdprid.signal import METHODS, scan_blocked, sihd2_step


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
    g, delay = _checked_gains_and_delay(model, dt, forgetting, gains, wrench_filter,
                                        wrench_delay)
    p = len(PARAMETER_NAMES[model])
    f64 = jnp.float64
    x0 = jnp.zeros(p, f64) if x0 is None else jnp.asarray(x0, f64).reshape(p)
    fir = (reference_fir(_SIHD, g, dt) if _linear_match_on(model, wrench_filter)
           else np.zeros(0))
    cfg = _online_config(robot, dt, model, forgetting, g, wrench_filter, delay, x0,
                         prior_weight, warmup, excitation_window, excitation_threshold, fir)
    z3, z4 = (jnp.zeros(n, f64) for n in (3, 4))
    wf = _wrench_filter_init(wrench_filter, delay, f64)
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
        rot=RotationFilterState(*(_integral_stage_init(n, f64) for n in (9, 9, 4, 4, 4))),
        lm=(_linear_match_init(robot.n_cables, len(fir), p, f64)
            if _linear_match_on(model, wrench_filter) else ()),
    )


def _linear_match_on(model: str, wrench_filter: str) -> bool:
    """The full model with matched filtering takes the rotation-consistent path."""
    return model == "full" and wrench_filter == "matched"


def _linear_match_init(m: int, taps: int, p: int, dtype) -> LinearMatchState:
    k = 6 * p + 6
    z = jnp.zeros(k, dtype)
    return LinearMatchState(jnp.zeros((7, 3), dtype), jnp.zeros((7, 4), dtype),
                            jnp.zeros((7, 6), dtype), jnp.eye(3, dtype=dtype), z, z, z,
                            jnp.zeros((taps, k), dtype), jnp.zeros((taps, 3), dtype))


_CENTRE = 3
"""The rotation-consistent rows are those of sample ``k - 3`` (centred differences over
``k - 6 .. k``)."""


def _push(buf, x):
    return jnp.concatenate([x[None], buf[:-1]])


def _linear_match_rows(st: LinearMatchState, p, q, wtau, k, cfg):
    """Rows ``(A, y)`` of sample ``k - 3`` with every term through the FIR ``cfg.fir``
    (:class:`LinearMatchState`); also whether the FIR's history is full."""
    h, g, c = cfg.dt, cfg.robot.gravity, cfg.fir
    first = k == 0
    pos, quat, wt = (jnp.where(first, jnp.broadcast_to(x, b.shape), _push(b, x))
                     for b, x in ((st.pos, p), (st.quat, q), (st.wtau, wtau)))
    a_ref = (pos[0] - pos[2] - pos[4] + pos[6]) / (8.0 * h * h)
    qd = (quat[2] - quat[4]) / (2.0 * h)
    qdd = (quat[0] - quat[2] - quat[4] + quat[6]) / (8.0 * h * h)
    om, al = angular_rates_from_quat(quat[_CENTRE], qd, qdd)
    R0 = jnp.where(first, quat_to_matrix(q), st.R0)
    z = jnp.zeros(3, h.dtype)
    base = regressor_full(R0, z, z, z, g)
    rem = (regressor_full(quat_to_matrix(quat[_CENTRE]), a_ref, om, al, g)
           - regressor_full(R0, a_ref, z, z, g) + base)
    u = jnp.concatenate([rem.ravel(), wt[_CENTRE]])
    valid = k >= 2 * _CENTRE
    u0 = jnp.where(k == 2 * _CENTRE, u, st.u0)
    du = u - u0
    i1 = st.i1 + 0.5 * h * (du + st.u_prev)
    i2 = st.hist[0] + 0.5 * h * (i1 + st.i1)
    new = LinearMatchState(pos, quat, wt, R0, u0, du, i1, _push(st.hist, i2),
                           _push(st.phist, pos[_CENTRE]))
    new = new._replace(**{f: jnp.where(valid, getattr(new, f), getattr(st, f))
                          for f in ("u0", "u_prev", "i1", "hist", "phist")})
    filt = c @ new.hist + new.u0
    A = regressor_full(R0, c @ new.phist, z, z, g) - base + filt[:-6].reshape(base.shape)
    full = k >= 2 * _CENTRE + len(c)
    return new, A, filt[-6:], full


def _online_config(robot, dt, model, forgetting, g, wrench_filter, delay, x0, prior_weight,
                   warmup, excitation_window, excitation_threshold, fir) -> OnlineConfig:
    """The :class:`OnlineConfig` of :func:`online_init`'s (checked) arguments, in float64."""
    f64 = jnp.float64
    return OnlineConfig(
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
        fir=jnp.asarray(fir, f64),
        model=model,
        wrench_filter=wrench_filter,
        wrench_delay=delay,
    )


def _checked_gains_and_delay(model, dt, forgetting, gains, wrench_filter, wrench_delay):
    """Check the arguments of :func:`online_init` (:class:`InputError` otherwise) and return
    the SIHD cascade gains (defaults overridden by ``gains``) and the wrench delay, samples."""
    if model not in PARAMETER_NAMES:
        raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")
    if wrench_filter not in WRENCH_FILTERS:
        raise InputError(f"unknown wrench filter {wrench_filter!r}; use one of "
                         f"{', '.join(WRENCH_FILTERS)}.")
    _check_forgetting(forgetting)
    if not (math.isfinite(dt) and dt > 0):
        raise InputError(f"dt must be a positive number of seconds, got {dt!r}.")
    g = dict(METHODS[_SIHD].params)
    bad = sorted(set(gains or {}) - set(g))
    if bad:
        raise InputError(f"unknown SIHD gain(s) {', '.join(bad)}; valid: {', '.join(g)}.")
    g.update({k: float(v) for k, v in (gains or {}).items()})
    if not all(math.isfinite(v) and v > 0 for v in g.values()) or not 0.5 <= g["alpha"] <= 1:
        raise InputError(f"SIHD gains must be finite and > 0 with 0.5 <= alpha <= 1, got {g}.")
    delay = int(wrench_delay) if wrench_filter == "delay" else 0
    if wrench_filter == "delay" and delay < 1:
        raise InputError(f"wrench_delay must be >= 1 sample, got {wrench_delay!r}.")
    return g, delay


def _wrench_filter_init(wrench_filter: str, delay: int, dtype):
    """Initial state of the wrench filter: matched, a delay line of ``delay`` samples, or
    none (``()``)."""
    z6 = jnp.zeros(6, dtype)
    if wrench_filter == "matched":
        return MatchedFilterState(z6, (z6, z6), z6, (z6, z6), z6, z6, jnp.ones(6, dtype))
    if wrench_filter == "delay":
        return DelayState(jnp.zeros((delay, 6), dtype))
    return ()


def _integral_stage_init(n: int, dtype) -> IntegralStage:
    z = jnp.zeros(n, dtype)
    return IntegralStage(z, (z, z), z)


def _integral_stage(st: IntegralStage, u, first, g, h):
    """``(H / s) u``: trapezoidal integral of ``u`` through one SIHD stage, in steady state at
    the first sample (a constant input passes unchanged, as in the wrench's matched filter)."""
    u_prev = jnp.where(first, u, st.u_prev)
    integral = st.integral + 0.5 * h * (u + u_prev)
    stage = (jnp.where(first, integral, st.stage[0]), jnp.where(first, u, st.stage[1]))
    stage, out = sihd2_step(stage, integral, g, h)
    return IntegralStage(integral, stage, u), out


def _rotation_terms(rot, B_R_P, q, qd, first, gains, h):
    """``F[R]``, ``F[q]`` and ``F[dq/dt]`` with F the wrench's matched filter (H2 H1 / s^2).

    The regressor multiplies accelerations (already ``F[a]`` from the cascade) with the pose;
    filtering W tau by F and the pose terms by nothing leaves, with a causal filter's lag, a
    residual correlated with the rotation (the inertia and m s_G came out wrong even on
    noise-free data). With every factor through F, the products carry the same delay.
    """
    g1 = (gains[0], gains[1], gains[4], gains[5])
    g2 = (gains[2], gains[3], gains[4], gains[5])
    R1, r1 = _integral_stage(rot.R1, B_R_P.reshape(9), first, g1, h)
    R2, FR = _integral_stage(rot.R2, r1, first, g2, h)
    q1, f1 = _integral_stage(rot.q1, q, first, g1, h)
    q2, Fq = _integral_stage(rot.q2, f1, first, g2, h)
    qd2, Fqd = _integral_stage(rot.qd2, qd, first, g2, h)
    return RotationFilterState(R1, R2, q1, q2, qd2), FR.reshape(3, 3), Fq, Fqd


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


def _cascade_rows(state: OnlineState, B_R_P, q, qd, qdd, a, wtau, first):
    """Rows ``(A, y)`` of this sample from the SIHD cascade's motion, ``W tau`` through the
    chosen wrench filter (the translation model; the full model without matched filtering)."""
    cfg = state.config
    robot, h, gains = cfg.robot, cfg.dt, cfg.gains
    if cfg.wrench_filter == "matched":  # every pose term through the wrench's filter F
        rot, R_f, q_f, qd_f = _rotation_terms(state.rot, B_R_P, q, qd, first, gains, h)
        q_f = q_f / jnp.linalg.norm(q_f)
    else:
        rot, R_f, q_f, qd_f = state.rot, B_R_P, q, qd
    if cfg.model == "full":
        om, al = angular_rates_from_quat(q, qd, qdd)  # reported: the cascade's own estimate
        om_f, al_f = angular_rates_from_quat(q_f, qd_f, qdd)  # in the regressor: through F
        A = regressor_full(R_f, a, om_f, al_f, robot.gravity)
    else:
        om = al = jnp.zeros(3, h.dtype)
        A = regressor_translation(R_f, a, robot.gravity)
    # measured wrench and its lag compensation
    y = wtau
    if cfg.wrench_filter == "matched":
        wf, y = _matched_filter(state.wf, y, first, gains, h, cfg)
    elif cfg.wrench_filter == "delay":
        buf = state.wf.buffer
        buf = jnp.where(first, jnp.broadcast_to(y, buf.shape), buf)
        y, buf = buf[0], jnp.concatenate([buf[1:], y[None]], axis=0)
        wf = DelayState(buf)
    else:
        wf = state.wf
    return rot, wf, A, y, om, al


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
    sihd_q, qd, qdd = _cascade(state.sihd_q, q, first, gains, h)
    wtau = wrench_matrix(robot, p_meas, B_R_P) @ tau
    if _linear_match_on(cfg.model, cfg.wrench_filter):  # rows of sample k - 3, one FIR
        lm, A, y, full = _linear_match_rows(state.lm, p_meas, q, wtau, state.k, cfg)
        om, al = angular_rates_from_quat(q, qd, qdd)  # reported: the cascade's own estimate
        rot, wf = state.rot, state.wf
    else:
        rot, wf, A, y, om, al = _cascade_rows(state, B_R_P, q, qd, qdd, a, wtau, first)
        lm, full = state.lm, True

    # 4. recursive least squares (square-root information form)
    use = (state.k.astype(h.dtype) * h >= cfg.warmup - 1e-9 * h) & full
    S, n_rows = _rls_update(state.S, state.n_rows, A, y, cfg.forgetting, use)
    x, sigma, sigma_rho = _rls_solution(S, n_rows)

    # 5. excitation monitor
    le = jnp.where(use, cfg.excitation_forgetting, 1.0)
    M = le * state.M + jnp.where(use, 1.0, 0.0) * (A.T @ A)
    m_rows = le * state.m_rows + jnp.where(use, 6.0, 0.0)
    lam_min = jnp.linalg.eigvalsh(M / jnp.maximum(m_rows, 1.0))[0]
    exc = jnp.sqrt(jnp.maximum(lam_min, 0.0))
    ok = (exc >= cfg.excitation_threshold) & (m_rows > 0)

    new = OnlineState(cfg, state.k + 1, sihd_p, sihd_q, q, wf, S, n_rows, M, m_rows, rot, lm)
    return new, OnlineOutput(v, a, om, al, A, y, x, sigma, sigma_rho, exc, ok, use)


online_step = jax.jit(_online_step)


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
    if _linear_match_on(cfg.model, cfg.wrench_filter):  # rows of k - 3: not the motion's
        return scan_blocked(_online_step, state, samples, block, return_carry=True)
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
        """Consume one sample.

        Parameters
        ----------
        position : array-like (3,)
            Position of P, base frame, m.
        quaternion : array-like (4,)
            Unit quaternion, scalar first, platform -> base.
        tension : array-like (m,)
            Cable tensions, N.

        Returns
        -------
        OnlineOutput
            numpy arrays for this sample.

        Raises
        ------
        InputError
            An argument with the wrong number of values.
        """
        parts = [np.asarray(v, np.float64).ravel() for v in (position, quaternion, tension)]
        for name, v, size in zip(("position", "quaternion", "tension"), parts,
                                 (3, 4, self._m), strict=True):
            if v.size != size:
                raise InputError(f"OnlineStepper.step: {name} must have {size} values, "
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
