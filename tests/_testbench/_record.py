"""A recording of the test simulator, and its spec-v1 dataset (truth in meta.toml).

The plant: the prescribed motion (:mod:`._motion`), the wrench its Newton-Euler needs
(viscous drag included), the cable directions from the true pulley geometry, and tensions
distributed about a reference (``tau = tau_ref 1 + W^+ (w - W tau_ref 1)``, the least change
from the reference; the force rows only for a point mass). The cables' sliding speeds are
central differences of the total cable length (arc plus free part). The tension stream holds
the plant at ``t - clock_offset`` (its own clock), read through :func:`._sensors.cell_reading`.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from tests._testbench._episodes import apply_glitches, push_wrench
from tests._testbench._geometry import pulley_geometry, total_length
from tests._testbench._motion import Path, motion, newton_euler, random_path
from tests._testbench._robots import Robot
from tests._testbench._sensors import Sensors, cell_reading, mocap, rotvec_quat


@dataclasses.dataclass(frozen=True)
class Recording:
    """One simulated recording: the streams, the truth, the noise-free internals."""

    robot: Robot
    sensors: Sensors
    exit_error: np.ndarray  # (m, 3) true exit point - robot.toml's
    drag_Ns_per_m: float
    pose_t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray | None
    tension_t: np.ndarray
    tension: np.ndarray  # what the cells report
    tau_platform: np.ndarray  # noise-free platform-side tensions at the tension samples
    cell_force: np.ndarray  # the force on each cell (winch side if the cell is there)
    ldot: np.ndarray  # sliding speeds at the tension samples, m/s
    wrap_deg: np.ndarray  # (min, max) wrap angle over the recording per cable
    effects: list  # vocabulary (name, params) pairs of what the recording holds
    path: Path
    pushes: tuple = ()  # _episodes.Push: outside wrenches on the platform (truth)
    glitches: tuple = ()  # _episodes.Glitch: displaced motion-capture samples (truth)


def _rotate(R, rv):
    """Rotation matrices ``exp([rv]) R`` (Rodrigues)."""
    ang = np.linalg.norm(rv, axis=1)
    n = len(rv)
    K = np.zeros((n, 3, 3))
    ax = rv / np.maximum(ang, 1e-300)[:, None]
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -ax[:, 2], ax[:, 1], -ax[:, 0]
    K = K - np.transpose(K, (0, 2, 1))
    s, c = np.sin(ang)[:, None, None], np.cos(ang)[:, None, None]
    E = np.eye(3) + s * K + (1 - c) * K @ K
    return E @ R


def _plant(rob: Robot, A, mo, drag, external=None):
    B = mo.p[:, None, :] + np.einsum("nij,mj->nmi", mo.R, rob.b)
    T, beta, free, u = pulley_geometry(A, rob.k, rob.r, B)
    W = np.concatenate([np.transpose(u, (0, 2, 1)),
                        np.transpose(np.cross(B - mo.p[:, None, :], u), (0, 2, 1))], axis=1)
    w = newton_euler(mo, rob.mass, rob.com, rob.inertia_G, rob.gravity, drag)
    if external is not None:  # an outside wrench holds part of what the motion needs
        w = w - external
    rows = slice(0, 3) if rob.max_angle_rad == 0 else slice(0, 6)
    Wr, wr = W[:, rows], w[:, rows]
    ref = np.full(rob.m, rob.tension_ref)
    if rob.tension_ref > 0:
        res = wr - np.einsum("nim,m->ni", Wr, ref)
        tau = ref + np.einsum("nmi,ni->nm", np.linalg.pinv(Wr), res)
    else:
        tau = np.linalg.solve(Wr, wr[..., None])[..., 0]
    err = np.max(np.abs(np.einsum("nim,nm->ni", Wr, tau) - wr))
    assert err < 1e-6 * max(1.0, np.max(np.abs(wr))), err
    return tau, beta, B


def _sliding(rob: Robot, A, mo, h: float = 1e-4):
    """dl/dt of the total cable length by a central difference in time (O(h^2))."""
    out = []
    for sgn in (1.0, -1.0):
        p = mo.p + sgn * h * mo.v + 0.5 * h * h * mo.a
        R = _rotate(mo.R, sgn * h * mo.w)
        B = p[:, None, :] + np.einsum("nij,mj->nmi", R, rob.b)
        out.append(total_length(A, rob.k, rob.r, B))
    return (out[0] - out[1]) / (2 * h)


def vocabulary_effects(rob: Robot, s: Sensors, exit_error, drag) -> list:
    """The vocabulary's (name, params) for what a recording holds (cables from 1)."""
    out = []
    if rob.max_angle_rad > 0:
        out.append(("rotational_dynamics", {"amplitude_rad": float(rob.max_angle_rad)}))
    if s.clock_offset_s:
        out.append(("time_delay", {"delay_s": float(s.clock_offset_s)}))
    co, vi = np.asarray(s.coulomb_N), np.asarray(s.viscous_Ns_per_m)
    if s.cell_at_winch and (np.any(co) or np.any(vi)):
        if np.all(co == co[0]) and np.all(vi == vi[0]):
            out.append(("pulley_friction", {"cable": "all", "coulomb_N": float(co[0]),
                                            "viscous_Ns_per_m": float(vi[0])}))
        else:
            out += [("pulley_friction", {"cable": i + 1, "coulomb_N": float(co[i]),
                                         "viscous_Ns_per_m": float(vi[i])})
                    for i in range(rob.m) if co[i] or vi[i]]
    for i in range(rob.m):
        if s.offset_N[i]:
            out.append(("tension_offset", {"cable": i + 1, "offset_N": float(s.offset_N[i])}))
        if s.gain[i] != 1.0:
            out.append(("tension_gain", {"cable": i + 1, "gain": float(s.gain[i])}))
        if s.hysteresis_N[i]:
            out.append(("load_cell_hysteresis", {"cable": i + 1,
                                                 "width_N": float(s.hysteresis_N[i])}))
        if np.any(exit_error[i]):
            out.append(("exit_point_error", {"cable": i + 1, "displacement_m": [
                float(z) for z in exit_error[i]]}))
    if drag:
        out.append(("viscous_drag", {"coefficient_Ns_per_m": float(drag)}))
    return out


#: the least tension a drawn trajectory must keep (coarse check), N; the diagnosis drops samples
#: below 5 N
MIN_TENSION_N = 8.0


def feasible_path(rob: Robot, rng, duration_s: float, tries: int = 60) -> Path:
    """The first random trajectory whose distributed tensions stay above
    :data:`MIN_TENSION_N` (checked every 20 ms)."""
    for _ in range(tries):
        path = random_path(rng, rob.center, rob.half_range, rob.max_angle_rad)
        tau, _, _ = _plant(rob, rob.A, motion(path, np.arange(0.0, duration_s + 0.1, 0.02)),
                           0.0)
        if np.min(tau) > MIN_TENSION_N:
            return path
    raise RuntimeError(f"{rob.name}: no trajectory with taut cables in {tries} draws")


def record(rob: Robot, s: Sensors, seed: int, duration_s: float = 50.0, exit_error=None,
           drag_Ns_per_m: float = 0.0, noise: bool = True, path: Path | None = None,
           pushes=(), glitches=()) -> Recording:
    """Simulate one recording of ``duration_s`` (pose clock from 0); ``pushes``
    (:class:`._episodes.Push`) act on the platform on the plant's clock, ``glitches``
    (:class:`._episodes.Glitch`) displace motion-capture samples after their noise. Neither
    draws from the recording's random stream: without them the recording is the same."""
    rng = np.random.default_rng(seed)
    path = path or feasible_path(rob, rng, duration_s)
    exit_error = np.zeros((rob.m, 3)) if exit_error is None else np.asarray(exit_error, float)
    A_true = rob.A + exit_error
    pose_t = np.arange(0.0, duration_s, 1.0 / s.pose_rate_hz)
    tension_t = np.arange(s.clock_phase_s, duration_s, 1.0 / s.tension_rate_hz)
    plant_t = tension_t - s.clock_offset_s
    assert plant_t[0] >= 0.0, "the clock phase must exceed the clock offset"
    mo_t = motion(path, plant_t)
    tau, beta, _ = _plant(rob, A_true, mo_t, drag_Ns_per_m,
                          push_wrench(pushes, plant_t) if pushes else None)
    assert np.min(tau) > 1.0, f"{rob.name}: slack cable ({np.min(tau):.2f} N)"
    ldot = _sliding(rob, A_true, mo_t)
    reading = cell_reading(s, tau, ldot, rng, noise)
    cell = tau - (np.asarray(s.coulomb_N) * np.sign(ldot) + np.asarray(s.viscous_Ns_per_m)
                  * ldot if s.cell_at_winch else 0.0)
    mo_p = motion(path, pose_t)
    pos, quat = mocap(s, mo_p.p, mo_p.q, rng, noise)
    if glitches:
        pos, quat = apply_glitches(pose_t, pos, quat, glitches)
    wrap = np.degrees(np.stack([beta.min(0), beta.max(0)], 1))
    return Recording(rob, s, exit_error, drag_Ns_per_m, pose_t, pos,
                     quat if rob.max_angle_rad > 0 else None, tension_t, reading, tau, cell,
                     ldot, wrap, vocabulary_effects(rob, s, exit_error, drag_Ns_per_m), path,
                     tuple(pushes), tuple(glitches))


def _parameters_table(effects) -> dict:
    """``[truth.effect_parameters]`` in cdprid's layout (flat keys given by one effect only,
    one sub-table per effect, ``_2``, ``_3`` for repeats)."""
    if len(effects) == 1:
        return dict(effects[0][1])
    counts, flat = {}, {}
    for _, p in effects:
        for k, v in p.items():
            counts[k] = counts.get(k, 0) + 1
            flat[k] = v
    out = {k: v for k, v in flat.items() if counts[k] == 1}
    seen = {}
    for name, p in effects:
        seen[name] = seen.get(name, 0) + 1
        out[name if seen[name] == 1 else f"{name}_{seen[name]}"] = dict(p)
    return out


def write(rec: Recording, out_dir, overwrite: bool = False):
    """Write the recording as a spec-v1 dataset (cdprid's writer); the truth in meta.toml."""
    from cdprid.io import write_dataset
    from cdprid.model import robot_from_dict

    rob, s = rec.robot, rec.sensors
    first = rob.mass * rob.com
    truth = {"mass": rob.mass, "com": [float(z) for z in rob.com],
             "first_moment": [float(z) for z in first],
             "inertia_com": [[float(z) for z in row] for row in rob.inertia_G],
             "effects": [n for n, _ in rec.effects]}
    if rec.effects:
        truth["effect_parameters"] = _parameters_table(rec.effects)
    if rec.pushes or rec.glitches:  # what happens only sometimes: [[truth.episodes]]
        truth["episodes"] = [e.truth() for e in rec.pushes + rec.glitches]
    sens = {k: (list(map(float, v)) if isinstance(v, tuple | list | np.ndarray) else v)
            for k, v in dataclasses.asdict(s).items()}
    meta = {"description": f"tests/_testbench recording of {rob.name}",
            "source": "simulated (tests/_testbench, independent of cdprid's simulator)",
            "truth": truth,
            "testbench": {"sensors": sens, "drag_Ns_per_m": rec.drag_Ns_per_m,
                          "wrap_deg_min": float(rec.wrap_deg[:, 0].min()),
                          "wrap_deg_max": float(rec.wrap_deg[:, 1].max())}}
    nominal = robot_from_dict(rob.toml(A=rob.A))
    return write_dataset(out_dir, nominal, rec.pose_t, rec.position, rec.tension_t, rec.tension,
                         quaternion=rec.quaternion, meta=meta, overwrite=overwrite)


def quat_of_rotvec(rv):
    """Unit quaternions of rotation vectors (re-exported for the tests)."""
    return rotvec_quat(np.atleast_2d(rv))
