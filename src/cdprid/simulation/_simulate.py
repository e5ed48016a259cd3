"""Synthetic measured data: plant, sensors and injectable effects (spec-v1 datasets).

Plant (paper section 3): the platform follows a prescribed trajectory (exact p, v, a, q,
omega, alpha from :mod:`cdprid.model._trajectories`). At each tension sample the cables must
produce the platform wrench of the Newton-Euler equations,

    W_true(p, q) tau = platform_wrench(params, q, a, omega, alpha, g_true) - w_ext,

with W from :func:`cdprid.model.wrench_matrix` on the TRUE geometry (exit/anchor errors,
pulleys) and ``w_ext`` the external wrench of the effects (viscous drag, cable weight);
the tensions come from :func:`cdprid.model.distribute_tensions` (closest to a reference
pretension, never clipped). The effects are described in ``docs/effects.md``.

Sensors: position noise (m, Gaussian, per axis), orientation noise (rad: the measured
quaternion is ``q * exp(n)``, n Gaussian in the platform frame), tension noise (N), each
optionally quantised (rounded to a multiple of a step), each stream at its own rate
(pose and tensions on their own time bases, both starting at the trajectory start).
Noise comes from ``numpy.random.default_rng`` streams spawned from ``seed`` in a fixed
order (pose, orientation, tension), so runs with the same seed share the noise whatever
the effects.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.effects import (
    effect_parameters_table,
    encoder_lengths,
    load_cell_reading,
    plant_terms,
    true_gravity,
    true_robot,
    validate_effects,
)
from cdprid.effects import external_wrench as push_wrench
from cdprid.model import (
    DEFAULT_PRETENSION,
    POSITION_COLUMNS,
    ROTATION_COLUMNS,
    CableRobot,
    InertialParameters,
    TrajectoryState,
    cable_lengths,
    cable_vectors,
    check_workspace,
    distribute_tensions,
    platform_wrench,
    quat_multiply,
    quat_to_matrix,
    rotvec_to_quat,
    with_rotation,
    wrench_matrix,
)

__all__ = ["SensorNoise", "SimResult", "simulate", "write_simulation", "plant_wrenches"]


@dataclasses.dataclass(frozen=True)
class SensorNoise:
    """Sensor model (standard deviations and quantisation steps; 0 = off).

    Attributes
    ----------
    position_m : float
        Position noise std, m (default 0.2 mm, as the shared sample).
    orientation_rad : float
        Orientation noise std, rad (a small random rotation, platform frame).
    tension_N : float
        Tension noise std, N (default 0.5 N).
    length_m : float
        Winch encoder noise std of the optional ``lengths.csv`` stream, m (default 0.05 mm).
    position_quantum_m, orientation_quantum, tension_quantum_N : float
        Quantisation steps (quaternion components for the orientation, renormalised).
    """

    position_m: float = 2e-4
    orientation_rad: float = 0.0
    tension_N: float = 0.5
    position_quantum_m: float = 0.0
    orientation_quantum: float = 0.0
    tension_quantum_N: float = 0.0
    length_m: float = 5e-5

    def __post_init__(self):
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"sensor noise {f.name} must be a finite number >= 0, got {v}.")

    @classmethod
    def off(cls) -> SensorNoise:
        """No noise, no quantisation.

        Returns
        -------
        SensorNoise
            Every noise standard deviation and quantisation step 0.
        """
        return cls(0.0, 0.0, 0.0, length_m=0.0)


@dataclasses.dataclass(frozen=True)
class SimResult:
    """Output of :func:`simulate` (measured streams plus the truth behind them).

    Attributes
    ----------
    robot : CableRobot
        Nominal robot (written to robot.toml).
    robot_true : CableRobot
        Geometry of the plant.
    params : InertialParameters
    effects : tuple of Effect
    noise : SensorNoise
    gravity_true : ndarray (3,)
        Gravity of the plant in the pose frame.
    pose_t, position : (n,), (n, 3)
        Measured pose stream.
    quaternion : (n, 4) or None
        Measured quaternions (None for a pure translation without orientation noise).
    tension_t, tension : (k,), (k, m)
        Measured tension stream.
    tension_true : (k, m)
        Plant tensions before the sensor (gain, offset, noise, quantisation).
    motion : TrajectoryState
        True motion at ``pose_t``.
    motion_tension : TrajectoryState
        True motion at the times the tension samples refer to (``tension_t - delay``).
    wrench_required : (k, 6)
        ``platform_wrench`` at those times (before the external wrench of the effects).
    W_true : (k, 6, m)
        Wrench matrices of the plant at those times.
    n_qp : int
        Samples that needed the QP fallback of the tension distribution.
    seed : int
    has_rotation : bool
    description : str
    settings : dict
        Rates, pretension and trajectory name (written to meta.toml ``[simulation]``).
    lengths : (k, m) or None
        Winch encoder stream at ``tension_t`` (:func:`cdprid.effects.encoder_lengths`, with
        noise), written as ``lengths.csv``; None when not simulated.
    """

    robot: CableRobot
    robot_true: CableRobot
    params: InertialParameters
    effects: tuple
    noise: SensorNoise
    gravity_true: np.ndarray
    pose_t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray | None
    tension_t: np.ndarray
    tension: np.ndarray
    tension_true: np.ndarray
    motion: TrajectoryState
    motion_tension: TrajectoryState
    wrench_required: np.ndarray
    W_true: np.ndarray
    n_qp: int
    seed: int
    has_rotation: bool
    description: str
    settings: dict
    lengths: np.ndarray | None = None


def _time_base(t0: float, t1: float, rate: float) -> np.ndarray:
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"sampling rates must be positive numbers of Hz, got {rate}.")
    n = int(np.floor((t1 - t0) * rate + 1e-9)) + 1
    return t0 + np.arange(n) / rate


def _plant_one(robot_true, params, gravity, drag, rho, pk, vk, ak, qk, wk, alk):
    R = quat_to_matrix(qk)
    W = wrench_matrix(robot_true, pk, R)
    wp = platform_wrench(params, R, ak, wk, alk, gravity)
    # cable weight, half per cable, at the attachment B_i (effects.cable_mass)
    L = jnp.linalg.norm(cable_vectors(robot_true, pk, R), axis=1)
    f_i = (0.5 * rho * L)[:, None] * gravity[None, :]
    b = (R @ robot_true.P_b.T).T
    f_ext = -drag * vk + jnp.sum(f_i, axis=0)
    m_ext = jnp.sum(jnp.cross(b, f_i), axis=0)
    return W, wp, jnp.concatenate([f_ext, m_ext])


@eqx.filter_jit
def plant_wrenches(robot_true, params, gravity, drag, rho, p, v, a, q, omega, alpha):
    """Per-sample plant quantities, vmapped over time.

    Parameters
    ----------
    robot_true : CableRobot
    params : InertialParameters
    gravity : (3,)
        Plant gravity, pose frame.
    drag : float
        Viscous drag coefficient c, N s/m.
    rho : float
        Cable linear density, kg/m.
    p, v, a, omega, alpha : (n, 3)
    q : (n, 4)

    Returns
    -------
    W : (n, 6, m)
        True wrench matrices.
    w_platform : (n, 6)
        ``platform_wrench`` (force, moment about P).
    w_ext : (n, 6)
        External wrench of drag and cable weight on the platform (force, moment about P).
    """
    one = lambda *x: _plant_one(robot_true, params, gravity, drag, rho, *x)  # noqa: E731
    return jax.vmap(one)(p, v, a, q, omega, alpha)


@eqx.filter_jit
def _plant(robot_true, params, gravity, drag, rho, tau_ref, p, v, a, q, omega, alpha):
    """Plant wrenches and the closed-form tensions (one compilation for every trajectory)."""
    from cdprid.model import closed_form_tensions

    one = lambda *x: _plant_one(robot_true, params, gravity, drag, rho, *x)  # noqa: E731
    W, wp, wext = jax.vmap(one)(p, v, a, q, omega, alpha)
    tau0 = closed_form_tensions(W, wp - wext, tau_ref)
    return W, wp, wext, tau0


def _pad(x: np.ndarray, bucket: int = 4096) -> np.ndarray:
    """Pad along axis 0 (repeating the last row) to a multiple of ``bucket``: fewer compilations."""
    x = np.asarray(x)
    size = max(bucket, -(-x.shape[0] // bucket) * bucket)
    return np.concatenate([x, np.repeat(x[-1:], size - x.shape[0], axis=0)])


def _quantise(x, step):
    return x if step <= 0 else np.round(x / step) * step


def _default_params(robot):
    """robot.toml's platform parameters, else the CRAFT-like truth."""
    from cdprid.model import craft_like_truth

    pl = robot.platform
    if pl.mass is None or pl.com is None:
        return craft_like_truth()
    return InertialParameters(pl.mass, pl.com, pl.inertia)


def _tension_limits(robot, tension_min, tension_max):
    """Tension bounds: the arguments, else robot.toml's limits, else 0 and inf."""
    tmin = tension_min if tension_min is not None else (robot.limits.tension_min or 0.0)
    if tension_max is not None:
        return tmin, tension_max
    return tmin, robot.limits.tension_max if robot.limits.tension_max is not None else np.inf


def _describe(robot, trajectory, effects, noise, seed, rate_pose, rate_tension, tau_ref,
              tmin, tmax, n_qp, duration):
    """The one-line description and the ``[simulation]`` settings of meta.toml."""
    names = [e.name for e in effects]
    description = (
        f"{robot.name} robot, trajectory '{trajectory.name}', {duration:g} s, pose at "
        f"{rate_pose:g} Hz, tensions at {rate_tension:g} Hz, position noise "
        f"{noise.position_m * 1e3:g} mm, orientation noise {noise.orientation_rad:g} rad, "
        f"tension noise {noise.tension_N:g} N, "
        + (f"effects: {', '.join(names)}" if names else "no unmodelled effect")
    )
    settings = {
        "trajectory": trajectory.name,
        "seed": int(seed),
        "rate_pose_hz": float(rate_pose),
        "rate_tension_hz": float(rate_tension),
        "pretension_N": [
            float(v) for v in np.broadcast_to(np.asarray(tau_ref, float), (robot.n_cables,))
        ],
        "tension_min_N": float(tmin),
        "tension_max_N": float(tmax) if np.isfinite(tmax) else "inf",
        "noise": dataclasses.asdict(noise),
        "qp_fallback_samples": int(n_qp),
    }
    return description, settings


def _measure(motion, tau_true, W, mt, tension_t, effects, noise, seed, has_rotation):
    """Sensor streams: noisy (quantised) position and quaternion, load-cell readings.

    The load cells read what :func:`cdprid.effects.load_cell_reading` says (the sensor
    chain in physical order: ``gain * (tau + friction) + offset + drift``) plus noise.
    """
    n_pose = np.asarray(motion.p).shape[0]
    k = tau_true.shape[0]
    ss = np.random.SeedSequence(seed).spawn(3)
    rng_pos, rng_rot, rng_tau = (np.random.default_rng(s) for s in ss)
    position = np.asarray(motion.p) + noise.position_m * rng_pos.standard_normal((n_pose, 3))
    position = _quantise(position, noise.position_quantum_m)
    quaternion = None
    if has_rotation or noise.orientation_rad > 0:
        q = np.asarray(motion.q)
        dn = noise.orientation_rad * rng_rot.standard_normal((n_pose, 3))
        if noise.orientation_rad > 0:
            dq = np.asarray(jax.vmap(rotvec_to_quat)(jnp.asarray(dn)))
            q = np.asarray(jax.vmap(quat_multiply)(jnp.asarray(q), jnp.asarray(dq)))
        q = _quantise(q, noise.orientation_quantum)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        quaternion = np.where(q[:, :1] < 0, -q, q)
    tension = load_cell_reading(effects, tau_true, W, np.asarray(mt.v)[:k],
                                np.asarray(mt.omega)[:k], tension_t)
    tension = tension + noise.tension_N * rng_tau.standard_normal(tension.shape)
    return position, quaternion, _quantise(tension, noise.tension_quantum_N)


def _encoders(robot_true, mt, tau_true, effects, noise, seed):
    """Winch encoder readings at the tension times (true motion there), with noise.

    The geometric length is :func:`cdprid.model.cable_lengths` (from the exit point,
    the arc on a pulley rim included, to the attachment).
    """
    k = tau_true.shape[0]
    R = jax.vmap(quat_to_matrix)(jnp.asarray(np.asarray(mt.q)[:k]))
    L = np.asarray(jax.vmap(lambda p, Rk: cable_lengths(robot_true, p, Rk))(
        jnp.asarray(np.asarray(mt.p)[:k]), R))
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(4)[3])
    return encoder_lengths(effects, L, tau_true) + noise.length_m * rng.standard_normal(L.shape)


def simulate(
    robot: CableRobot,
    trajectory,
    params: InertialParameters | None = None,
    effects=(),
    noise: SensorNoise | None = None,
    rate_pose: float = 100.0,
    rate_tension: float = 100.0,
    seed: int = 0,
    tau_ref=DEFAULT_PRETENSION,
    tension_min: float | None = None,
    tension_max: float | None = None,
    check_workspace_box: bool = True,
    lengths: bool = False,
) -> SimResult:
    """Simulate measured pose and tension streams of a robot following a trajectory.

    Parameters
    ----------
    robot : CableRobot
        Nominal robot (what robot.toml will say).
    trajectory : Trajectory or SampledTrajectory
    params : InertialParameters, optional
        True platform parameters (default: those of robot.toml's ``[platform]``, else
        :func:`cdprid.model.craft_like_truth`).
    effects : sequence of Effect or (name, params) pairs
        See ``docs/effects.md`` (:data:`cdprid.effects.REGISTRY`).
    noise : SensorNoise, optional
        Default ``SensorNoise()`` (0.2 mm, 0.5 N).
    rate_pose, rate_tension : float
        Sampling rates, Hz.
    seed : int
        Seed of the noise generators.
    tau_ref : float or array (m,)
        Reference pretension of the tension distribution, N.
    tension_min, tension_max : float, optional
        Tension bounds, N (default robot.toml's limits, else 0 and inf).
    check_workspace_box : bool
        Raise if the trajectory leaves robot.toml's workspace box.
    lengths : bool
        Also simulate the winch encoders (``lengths.csv``); always on with
        ``cable_elasticity``.

    Returns
    -------
    SimResult

    Raises
    ------
    InfeasibleTensionsError
        When no admissible tensions exist at some samples (never clipped).
    ValueError
        Invalid effects, rates or a trajectory outside the workspace (one sentence).
    """
    effects = tuple(e for e in validate_effects(effects, robot.n_cables) if e.name != "none")
    noise = SensorNoise() if noise is None else noise
    params = _default_params(robot) if params is None else params
    terms = plant_terms(effects)
    if (amplitude := terms.rotation_amplitude_rad) > 0:
        trajectory = with_rotation(trajectory, amplitude)
    robot_true = true_robot(robot, effects)
    g_true = true_gravity(robot, effects)
    tmin, tmax = _tension_limits(robot, tension_min, tension_max)
    t0, t1 = trajectory.t_start, trajectory.t_end
    pose_t, tension_t = _time_base(t0, t1, rate_pose), _time_base(t0, t1, rate_tension)
    ref = np.broadcast_to(np.asarray(tau_ref, float), (robot.n_cables,))
    mt, motion, W, wp, tau_true, n_qp = _run_plant(
        robot_true, params, g_true, terms, ref, trajectory, pose_t, tension_t, tmin, tmax,
        robot if check_workspace_box else None, effects)
    # sensors
    has_rotation = bool(trajectory.has_rotation)
    position, quaternion, tension = _measure(motion, tau_true, W, mt, tension_t, effects,
                                             noise, seed, has_rotation)
    enc = (_encoders(robot_true, mt, tau_true, effects, noise, seed)
           if lengths or terms.encoders else None)
    description, settings = _describe(robot, trajectory, effects, noise, seed, rate_pose,
                                      rate_tension, tau_ref, tmin, tmax, n_qp, t1 - t0)
    return SimResult(robot, robot_true, params, effects, noise, g_true, pose_t, position,
                     quaternion, tension_t, tension, tau_true, motion, mt, wp, W, n_qp,
                     int(seed), has_rotation, description, settings, lengths=enc)


def _run_plant(robot_true, params, g_true, terms, ref, trajectory, pose_t, tension_t, tmin,
               tmax, box_robot, effects=()):
    """The plant: motion at the tension times (delayed) and at the pose times, the true
    wrench matrices and the tensions distributed within their limits.

    Returns ``(motion at tension times, motion at pose times, W, required wrench, true
    tensions, number of QP fallback samples)``; ``box_robot`` (or None) checks the
    workspace box of robot.toml; ``effects`` give the pushes (``external_wrench``).
    """
    # one evaluation of the trajectory at [tension times - delay, pose times]
    t_all = np.concatenate([tension_t - terms.delay_s, pose_t])
    k = tension_t.size
    state = [np.asarray(x) for x in trajectory.evaluate(t_all)]
    mt = TrajectoryState(*(x[:k] for x in state))
    motion = TrajectoryState(*(x[k:] for x in state))
    W, wp, wext, tau0 = _plant(
        robot_true, params, jnp.asarray(g_true), jnp.asarray(terms.drag_Ns_per_m, float),
        jnp.asarray(terms.rho_kg_per_m, float), jnp.asarray(ref),
        *(jnp.asarray(_pad(x)) for x in (mt.p, mt.v, mt.a, mt.q, mt.omega, mt.alpha)),
    )
    if box_robot is not None:
        check_workspace(trajectory, box_robot, state=motion)
    W, wp, wext = (np.asarray(x)[:k] for x in (W, wp, wext))
    # pushes (external_wrench) at the plant's times; the cables hold the trajectory
    push = push_wrench(effects, tension_t - terms.delay_s)
    wext = wext + push
    tau_true, n_qp = distribute_tensions(
        W, wp - wext, tmin, tmax, tau_ref=ref, t=tension_t,
        tau_initial=None if np.any(push) else np.asarray(tau0)[:k])
    return mt, motion, W, wp, tau_true, n_qp


def write_simulation(result: SimResult, out_dir, overwrite: bool = False, extra=None,
                     drives=None, drive_truth=None, load_cells: bool = True) -> Path:
    """Write a :class:`SimResult` as a spec-v1 dataset folder.

    Files: robot.toml (nominal robot), pose.csv (quaternion columns when rotations or
    orientation noise are present), tensions.csv, meta.toml (``description``,
    ``source = "simulated"``, ``[truth]`` with mass, com, first_moment, inertia_com,
    effects and ``[truth.effect_parameters]`` — see
    :func:`cdprid.effects.effect_parameters_table` — and ``[simulation]`` settings), and
    truth_motion.csv (``t,x,y,z,vx,vy,vz,ax,ay,az`` plus ``qw..alz`` when rotating: the
    noise-free motion at the pose times), and lengths.csv (``t,l_1..l_m``) when the winch
    encoders were simulated.

    Parameters
    ----------
    result : SimResult
    out_dir : str or Path
    overwrite : bool
        Existing dataset files are never replaced unless True.
    extra, drives, drive_truth, load_cells
        Used by :func:`cdprid.simulation.write_drive_simulation`: further streams, the
        robot.toml drive fields per cable, ``[truth.drives]``, and whether tensions.csv is
        written.

    Returns
    -------
    Path
    """
    from cdprid.io import write_dataset

    r = result
    p = r.params
    truth = {
        "mass": float(p.mass),
        "com": [float(v) for v in np.asarray(p.com)],
        "first_moment": [float(v) for v in np.asarray(p.first_moment)],
        "inertia_com": [[float(v) for v in row] for row in np.asarray(p.inertia_com)],
        "effects": [e.name for e in r.effects],
    }
    table = effect_parameters_table(r.effects)
    if table:
        truth["effect_parameters"] = table
    if plant_terms(r.effects).tilted:
        truth["gravity_pose_frame"] = [float(v) for v in r.gravity_true]
    meta = {
        "description": r.description,
        "source": "simulated",
        "truth": truth,
        "simulation": r.settings,
    }
    m = r.motion
    cols = list(POSITION_COLUMNS)
    vals = [r.pose_t[:, None], np.asarray(m.p), np.asarray(m.v), np.asarray(m.a)]
    if r.has_rotation:
        cols += list(ROTATION_COLUMNS)
        vals += [np.asarray(m.q), np.asarray(m.omega), np.asarray(m.alpha)]
    if drive_truth is not None:
        truth["drives"] = drive_truth
    extra = {"truth_motion": (cols, np.hstack(vals)), **(extra or {})}
    if r.lengths is not None:
        extra["lengths"] = (["t"] + [f"l_{i + 1}" for i in range(r.lengths.shape[1])],
                            np.column_stack([r.tension_t, r.lengths]))
    return write_dataset(
        out_dir,
        r.robot,
        r.pose_t,
        r.position,
        r.tension_t,
        r.tension if load_cells else None,
        quaternion=r.quaternion,
        meta=meta,
        extra=extra,
        overwrite=overwrite,
        drives=drives,
    )
