"""Geometric calibration from a recording with locked winches (constant cable lengths).

While the winches are locked, every cable's length from its pulley entry point ``A_i`` to its
attachment ``B_i`` (arc on the pulley rim included, :func:`cdprid.model.cable_lengths`) is a
constant ``L_i``, and each swivel encoder reads the angle of its pulley plane
(:func:`cdprid.model.swivel_angles`) up to a constant offset (encoders are zeroed at homing). A
motion-capture system measures the pose of a marker frame ``M`` in its own frame ``V``. This module
estimates, by nonlinear least squares over the whole recording,

- ``B_R_V, B_p_V``: the transform Vicon frame -> robot base frame,
- either ``M_R_P, M_p_P`` (``anchors="config"``: the platform frame in the marker frame, the
  attachments ``P_b`` being the configuration's) or ``M_b`` (``anchors="free"``: the attachment
  points in the marker frame, 3 m numbers),
- ``L`` (m,): the constant cable lengths,
- ``delta`` (m,): the swivel-encoder offsets, ``psi_meas = s (psi_model - delta)`` with a sign
  ``s`` (``swivel_sign``, +1 by default),

with residuals ``(L_i(pose) - L_i) / sigma_L`` and ``wrap(s(psi_i - delta_i) - psi_meas) /
sigma_psi``; the two group scales are re-estimated from a first solution (so each group has unit
RMS), then the problem is solved again. The covariance is ``s^2 (J^T J)^{-1}`` of the weighted
Jacobian at the solution, computed through the SVD of J (never by inverting ``J^T J``). Consecutive
samples are correlated (smooth motion), so these standard deviations are lower bounds; the test
suite checks that synthetic, noise-free data are recovered to ~1e-8.

Frames: ``B`` base (the configuration's frame of the pulleys), ``V`` Vicon, ``M`` marker frame
(:mod:`cdprid.io._vicon`), ``P`` platform frame (origin P, the configuration's frame of the
attachments ``points``, centre of mass ``PtoG``). Rotations are parametrised as
``R = R0 exp([r]x)`` around a starting guess ``R0`` (multi-start over yaw multiples of 90 deg).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import ConvergenceError, InputError
from cdprid.identify._calibration_types import CalibrationData, CalibrationResult
from cdprid.model import (
    CableRobot,
    cable_lengths,
    matrix_to_quat,
    quat_to_matrix,
    rotvec_to_quat,
    swivel_angles,
)


# ----------------------------------------------------------------------- the model
def _rot(R0, r):
    return R0 @ quat_to_matrix(rotvec_to_quat(r))


def _names(anchors: str, m: int) -> list[tuple[str, int]]:
    sizes = [("B_r_V", 3), ("B_p_V", 3)]
    sizes += [("M_r_P", 3), ("M_p_P", 3)] if anchors == "config" else [("M_b", 3 * m)]
    sizes += [("length", m), ("swivel_offset", m)]
    return sizes


def _split(x, sizes):
    out, i = {}, 0
    for name, n in sizes:
        out[name] = x[i:i + n]
        i += n
    return out


def _wrap(a):
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))


def _make_residual(robot: CableRobot, anchors: str, sizes, use_swivel: bool, swivel_sign: float):
    """Residual ``f(x, args)`` with ``args = (V_R_M, V_p_M, psi, w, R0_BV, R0_MP)``."""
    m = robot.n_cables

    def sample(x, V_R_M, V_p_M, psi_meas, w, R0_BV, R0_MP):
        q = _split(x, sizes)
        B_R_V = _rot(R0_BV, q["B_r_V"])
        B_R_M = B_R_V @ V_R_M
        B_p_M = B_R_V @ V_p_M + q["B_p_V"]
        if anchors == "config":
            M_R_P = _rot(R0_MP, q["M_r_P"])
            B_R_P = B_R_M @ M_R_P
            B_p_P = B_R_M @ q["M_p_P"] + B_p_M
            rob = robot
        else:
            B_R_P, B_p_P = B_R_M, B_p_M
            rob = robot.replace(P_b=q["M_b"].reshape(m, 3))
        rl = (cable_lengths(rob, B_p_P, B_R_P) - q["length"]) * w[0]
        if not use_swivel:
            return rl
        psi = swivel_angles(rob, B_p_P, B_R_P)
        rs = _wrap(swivel_sign * (psi - q["swivel_offset"]) - psi_meas) * w[1]
        return jnp.concatenate([rl, rs])

    @jax.jit
    def residual(x, args):
        V_R_M, V_p_M, psi, w, R0_BV, R0_MP = args
        return jax.vmap(sample, in_axes=(None, 0, 0, 0, None, None, None))(
            x, V_R_M, V_p_M, psi, w, R0_BV, R0_MP).ravel()

    return residual


def _yaw(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _initial_x(robot, anchors, sizes, data, R0_BV, R0_MP, residual, use_swivel, swivel_sign):
    """Start vector: translation puts the mean platform under the mean exit point."""
    m = robot.n_cables
    x = {name: np.zeros(n) for name, n in sizes}
    V_c = np.mean(data.V_p_M, axis=0)
    A_c = np.mean(np.asarray(robot.B_A), axis=0)
    x["B_p_V"] = np.array([A_c[0], A_c[1], 0.0]) - R0_BV @ np.array([V_c[0], V_c[1], 0.0])
    if anchors == "free":
        x["M_b"] = (np.asarray(robot.P_b) @ R0_MP.T).ravel()
    vec = np.concatenate([x[name] for name, _ in sizes])
    # best constants for the start pose: lengths and offsets absorb their means
    args = _args(data, use_swivel, (1.0, 1.0), R0_BV, R0_MP)
    r = np.asarray(residual(jnp.asarray(vec), args)).reshape(len(data.t), -1)
    q = _split(vec, sizes)
    q["length"][:] = np.mean(r[:, :m], axis=0)
    if use_swivel:
        q["swivel_offset"][:] = 0.0
        rs = r[:, m:]
        # circular mean of the angle mismatch psi_model - psi_meas (sign applied below)
        q["swivel_offset"][:] = swivel_sign * np.arctan2(np.mean(np.sin(rs), 0),
                                                         np.mean(np.cos(rs), 0))
    return vec


def _args(data: CalibrationData, use_swivel: bool, w, R0_BV, R0_MP):
    psi = data.swivel if use_swivel else np.zeros((len(data.t), 1))
    return (jnp.asarray(data.V_R_M), jnp.asarray(data.V_p_M), jnp.asarray(psi),
            jnp.asarray(np.asarray(w, float)), jnp.asarray(R0_BV, float),
            jnp.asarray(R0_MP, float))


def _solve(residual, x0, args, max_steps, strict: bool = True):
    """Levenberg-Marquardt; with ``strict`` a failed solve raises
    :class:`cdprid.base.ConvergenceError` (multi-start candidates are not strict: a start
    that fails is simply not the best one)."""
    import optimistix as optx  # here, not at import: 0.15 s off every command's start-up

    solver = optx.LevenbergMarquardt(rtol=1e-12, atol=1e-12)
    sol = optx.least_squares(residual, solver, jnp.asarray(x0), args=args, max_steps=max_steps,
                             throw=False)
    ok = sol.result == optx.RESULTS.successful
    if strict and not ok:
        raise ConvergenceError(
            f"geometric calibration: Levenberg-Marquardt did not converge in {max_steps} steps "
            f"({optx.RESULTS[sol.result]}); try a larger max_steps or other yaw_starts.")
    return np.asarray(sol.value), bool(ok)


def _group_rms(r, m, use_swivel):
    r = r.reshape(-1, 2 * m if use_swivel else m)
    out = {"length_m": float(np.sqrt(np.mean(r[:, :m] ** 2)))}
    per = {"length_m": np.sqrt(np.mean(r[:, :m] ** 2, axis=0))}
    if use_swivel:
        out["swivel_rad"] = float(np.sqrt(np.mean(r[:, m:] ** 2)))
        per["swivel_rad"] = np.sqrt(np.mean(r[:, m:] ** 2, axis=0))
    return out, per


def calibrate_geometry(
    robot: CableRobot,
    data: CalibrationData,
    anchors: str = "config",
    use_swivel: bool = True,
    swivel_sign: float = 1.0,
    yaw_starts: int = 4,
    start_subsample: int = 5,
    max_steps: int = 200,
    R0_BV=None,
    R0_MP=None,
    progress=None,
) -> CalibrationResult:
    """Estimate the Vicon->base transform, attachments, lengths and swivel offsets.

    Parameters
    ----------
    robot : CableRobot
        Exit points, pulleys (radius, axis, reference) in the base frame; ``P_b`` are the
        configuration's attachments (used by ``anchors="config"``, start of ``"free"``).
    data : CalibrationData
    anchors : {"config", "free"}
        Estimate the marker->platform transform (6 numbers, attachments from ``robot``) or
        the attachments in the marker frame (3 m numbers).
    use_swivel : bool
        Add the swivel-angle residuals (needs ``data.swivel``).
    swivel_sign : float
        +1 when the encoder counts like :func:`cdprid.model.swivel_angles`, -1 otherwise.
    yaw_starts : int
        Multi-start: yaw multiples of ``360 / yaw_starts`` deg for ``R0_BV`` and ``R0_MP``
        (ignored for a rotation given explicitly); the best start, fitted on every
        ``start_subsample``-th sample, is refined on all samples.
    start_subsample : int
        Stride of the samples the multi-start candidates are fitted on.
    max_steps : int
        Levenberg-Marquardt steps per solve.
    R0_BV, R0_MP : array (3, 3), optional
        Fixed starting rotations.
    progress : callable(str), optional
        Receives one line per multi-start candidate and per refinement pass.

    Returns
    -------
    CalibrationResult
    """
    if anchors not in ("config", "free"):
        raise InputError(f"anchors must be 'config' or 'free', got {anchors!r}.")
    if use_swivel and data.swivel is None:
        raise InputError("use_swivel=True needs measured swivel angles in the data.")
    m = robot.n_cables
    sizes = _names(anchors, m)
    yaws = [2 * np.pi * k / yaw_starts for k in range(yaw_starts)]
    starts_BV = [np.asarray(R0_BV, float)] if R0_BV is not None else [_yaw(a) for a in yaws]
    starts_MP = [np.asarray(R0_MP, float)] if R0_MP is not None else [_yaw(a) for a in yaws]
    small = data.subsample(start_subsample)
    res = _make_residual(robot, anchors, sizes, use_swivel, swivel_sign)
    w = (1e3, 1e2)  # 1 mm and 10 mrad as the first scales
    say = progress or (lambda msg: None)
    Rb, Rm, x = _best_start(robot, anchors, sizes, small, starts_BV, starts_MP, res, use_swivel,
                            swivel_sign, w, max_steps, say)
    rms_before = _naive_rms(robot, anchors, sizes, data, res, use_swivel, swivel_sign)
    x, w, rms_after, per = _refine(res, x, data, use_swivel, w, Rb, Rm, max_steps, m, say)
    std, cond = _weighted_std(res, x, _args(data, use_swivel, w, Rb, Rm))
    return _calibration_result(robot, anchors, sizes, x, std, Rb, Rm, rms_before, rms_after,
                               per, len(data.t), cond, swivel_sign)


def _best_start(robot, anchors, sizes, small, starts_BV, starts_MP, res, use_swivel,
                swivel_sign, w, max_steps, say):
    """Multi-start on the subsampled ``small`` data: ``(R0_BV, R0_MP, x)`` of the pair of
    starting rotations with the lowest finite cost (:class:`ConvergenceError` if none)."""
    best = None
    n_starts = len(starts_BV) * len(starts_MP)
    for k, (Rb, Rm) in enumerate(itertools.product(starts_BV, starts_MP), start=1):
        x0 = _initial_x(robot, anchors, sizes, small, Rb, Rm, res, use_swivel, swivel_sign)
        args = _args(small, use_swivel, w, Rb, Rm)
        x, _ = _solve(res, x0, args, max_steps, strict=False)
        cost = float(np.sum(np.asarray(res(jnp.asarray(x), args)) ** 2))
        say(f"  calibration start {k}/{n_starts}: cost {cost:.4g}")
        if not np.isfinite(cost):
            continue
        if best is None or cost < best[0]:
            best = (cost, Rb, Rm, x)
    if best is None:
        raise ConvergenceError("geometric calibration: every multi-start solve gave a non-finite "
                               "cost; check the swivel axis and the marker frame.")
    return best[1:]


def _naive_rms(robot, anchors, sizes, data, res, use_swivel, swivel_sign):
    """The "before" RMS per residual group: the naive start (identity transforms) with its
    best constants (mean lengths, circular-mean swivel offsets), on all samples."""
    m = robot.n_cables
    x_naive = np.zeros(sum(n for _, n in sizes))
    qn = _split(x_naive, sizes)
    if anchors == "free":
        qn["M_b"][:] = np.asarray(robot.P_b).ravel()
    a1 = _args(data, use_swivel, (1.0, 1.0), np.eye(3), np.eye(3))
    r0 = np.asarray(res(jnp.asarray(x_naive), a1)).reshape(len(data.t), -1)
    qn["length"][:] = r0[:, :m].mean(0)
    if use_swivel:
        qn["swivel_offset"][:] = swivel_sign * np.arctan2(np.sin(r0[:, m:]).mean(0),
                                                          np.cos(r0[:, m:]).mean(0))
    return _group_rms(np.asarray(res(jnp.asarray(x_naive), a1)), m, use_swivel)[0]


def _refine(res, x, data, use_swivel, w, Rb, Rm, max_steps, m, say):
    """Two strict passes on all samples, with the scales ``w`` then with scales re-estimated
    from the first solution (unit RMS per group): ``(x, w, rms_after, rms_per_cable)``."""
    for k in range(2):
        say(f"  calibration refinement {k + 1}/2 on {len(data.t)} samples ...")
        x, _ = _solve(res, x, _args(data, use_swivel, w, Rb, Rm), max_steps)
        r1 = np.asarray(res(jnp.asarray(x), _args(data, use_swivel, (1.0, 1.0), Rb, Rm)))
        rms_after, per = _group_rms(r1, m, use_swivel)
        w = (1.0 / max(rms_after["length_m"], 1e-12),
             1.0 / max(rms_after.get("swivel_rad", 1.0), 1e-12))
    return x, w, rms_after, per


def _weighted_std(res, x, args):
    """Standard deviations ``sqrt(diag(s^2 (J^T J)^{-1}))`` of the weighted Jacobian at ``x``,
    through its SVD, and its condition number."""
    J = np.asarray(jax.jacfwd(res)(jnp.asarray(x), args))
    rw = np.asarray(res(jnp.asarray(x), args))
    dof = max(J.shape[0] - J.shape[1], 1)
    s2 = float(rw @ rw) / dof
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    inv = np.where(sv > sv[0] * 1e-14, 1.0 / np.maximum(sv, 1e-300) ** 2, 0.0)
    cov = (Vt.T * inv) @ Vt * s2
    return np.sqrt(np.diag(cov)), cond


def _calibration_result(robot, anchors, sizes, x, std, Rb, Rm, rms_before, rms_after, per,
                        n_samples, cond, swivel_sign) -> CalibrationResult:
    """The :class:`CalibrationResult` of the solution ``x`` and its standard deviations."""
    m = robot.n_cables
    q = {k: np.array(v) for k, v in _split(x, sizes).items()}
    qs = {k: np.array(v) for k, v in _split(std, sizes).items()}
    B_R_V = np.asarray(_rot(Rb, jnp.asarray(q["B_r_V"])))
    if anchors == "config":
        M_R_P = np.asarray(_rot(Rm, jnp.asarray(q["M_r_P"])))
        M_p_P = q["M_p_P"]
        M_b = np.asarray(robot.P_b) @ M_R_P.T + M_p_P
    else:
        M_R_P = M_p_P = None
        M_b = q["M_b"].reshape(m, 3)
        qs["M_b"] = qs["M_b"].reshape(m, 3)
    return CalibrationResult(
        anchors=anchors, B_R_V=B_R_V, B_p_V=q["B_p_V"], M_R_P=M_R_P, M_p_P=M_p_P, M_b=M_b,
        lengths=q["length"], swivel_offset=q["swivel_offset"], params=q, sigma=qs,
        rms_before=rms_before, rms_after=rms_after, rms_per_cable=per,
        n_samples=n_samples, condition=cond, swivel_sign=float(swivel_sign),
    )


def platform_pose(result: CalibrationResult, V_R_M, V_p_M):
    """Platform pose in the base frame from marker poses in the Vicon frame.

    With ``anchors="free"`` the platform frame is the marker frame (P = marker origin).

    Parameters
    ----------
    result : CalibrationResult
    V_R_M : array (n, 3, 3)
        Rotations marker frame -> Vicon frame.
    V_p_M : array (n, 3)
        Marker-frame origins, Vicon frame, m.

    Returns
    -------
    B_R_P : ndarray (n, 3, 3)
    B_p_P : ndarray (n, 3)
        Positions of P, base frame, m.
    """
    V_R_M = np.asarray(V_R_M, float)
    V_p_M = np.asarray(V_p_M, float)
    B_R_M = np.einsum("ab,nbc->nac", result.B_R_V, V_R_M)
    B_p_M = V_p_M @ result.B_R_V.T + result.B_p_V
    if result.M_R_P is None:
        return B_R_M, B_p_M
    B_R_P = B_R_M @ result.M_R_P
    B_p_P = np.einsum("nab,b->na", B_R_M, result.M_p_P) + B_p_M
    return B_R_P, B_p_P


def write_calibrated_dataset(src, result: CalibrationResult, out, overwrite: bool = False):
    """Rewrite an imported dataset (pose of the marker frame in the Vicon frame) so that the
    pose is the platform's in the base frame.

    With ``anchors="config"`` the platform frame is the configuration's (its ``points`` are the
    anchors, unchanged); with ``anchors="free"`` the platform frame is the marker frame and
    the anchors are replaced by the estimated ``M_b``. Tensions and extra streams are copied.

    Parameters
    ----------
    src : path or Dataset
    result : CalibrationResult
    out : folder to write
    overwrite : bool

    Returns
    -------
    Path
        The dataset folder written.
    """
    from cdprid.io import Dataset, read_dataset, write_dataset

    ds = src if isinstance(src, Dataset) else read_dataset(src)
    q = ds.quaternion if ds.quaternion is not None else np.tile([1.0, 0, 0, 0], (len(ds.pose_t), 1))
    V_R_M = np.stack([np.asarray(quat_to_matrix(qq)) for qq in q])
    B_R_P, B_p_P = platform_pose(result, V_R_M, ds.position)
    robot = ds.robot if result.M_R_P is not None else ds.robot.replace(P_b=result.M_b)
    meta = dict(ds.meta)
    notes = dict(meta.get("frames", {}))
    notes["pose"] = ("platform frame P in the robot base frame B, from the geometric "
                     "calibration (cdprid.identify._calibration)")
    meta["frames"] = notes
    meta["calibration"] = result.as_dict()
    extra = {k: (cols, vals) for k, (cols, vals) in ds.extra.items()}
    return write_dataset(out, robot, ds.pose_t, B_p_P, ds.tension_t, ds.tension,
                         quaternion=matrix_to_quat(B_R_P), meta=meta, extra=extra,
                         overwrite=overwrite)


def calibration_data(rec) -> CalibrationData:
    """:class:`CalibrationData` of a :class:`cdprid.io._uacdpr.UacdprRecording`, on the overlap
    of the Vicon stream and the robot log (swivel angles averaged and interpolated at the
    pose times).

    Parameters
    ----------
    rec : UacdprRecording

    Returns
    -------
    CalibrationData
    """
    v = rec.valid
    R, p = rec.fit.V_R_M[v], rec.fit.V_p_M[v]
    sw = rec.swivel_at_pose()
    keep = np.all(np.isfinite(sw), axis=1)
    return CalibrationData(rec.pose_t[keep], R[keep], p[keep], sw[keep])


def import_calibrated_uacdpr(vicon, robot_log, config, out, force: bool = False,
                             swivel_axis: str | None = None, subsample: int = 4,
                             yaw_starts: int = 4, nuisance: bool = True,
                             progress=None) -> Path:
    """Convert a UACDPR recording, calibrate its geometry and fit its nuisances.

    The three stages of ``cdprid import uacdpr``: :mod:`cdprid.io._uacdpr` converts the
    formats, :func:`calibrate_geometry` (``anchors="config"``, every ``subsample``-th Vicon
    frame) gives the pose of the configuration's PLATFORM frame in the robot BASE frame
    (robot.toml's anchors and exits apply unchanged; meta.toml ``[calibration]``), and with
    ``nuisance=True`` :func:`cdprid.identify.nuisance_summary` writes meta.toml ``[nuisance]``
    (offsets and delay from the dynamics, informational: tensions.csv stays raw). The
    folder, ``[nuisance]`` included, appears whole or not at all
    (:func:`cdprid.base.atomic_dir`).

    Parameters
    ----------
    vicon, robot_log, config : path
    out : folder to create
    force : bool
        Replace an existing ``out``.
    swivel_axis : {"first", "third"}, optional
        Default :data:`cdprid.io._uacdpr.DEFAULT_SWIVEL_AXIS`.
    subsample, yaw_starts : int
        Calibration options.
    nuisance : bool
        Fit the nuisances.
    progress : callable(str), optional
        Receives one line per stage (the CLI prints them on stderr).

    Returns
    -------
    Path
    """
    import time

    from cdprid.base import atomic_dir, check_output
    from cdprid.io import (
        DATASET_FILES,
        DEFAULT_SWIVEL_AXIS,
        load_uacdpr,
        read_dataset,
        sources_of,
        uacdpr_meta,
        write_uacdpr,
    )

    say = progress or (lambda msg: None)
    swivel_axis = swivel_axis or DEFAULT_SWIVEL_AXIS
    check_output(out, force=force, kind="dir", inputs=[vicon, robot_log, config])
    t0 = time.perf_counter()
    rec = load_uacdpr(vicon, robot_log, config, swivel_axis)
    data = calibration_data(rec).subsample(max(1, int(subsample)))
    say(f"geometric calibration on {len(data.t)} Vicon frames (about a minute) ...")
    res = calibrate_geometry(rec.robot, data, anchors="config", yaw_starts=yaw_starts,
                             progress=say)
    say(f"calibration done in {time.perf_counter() - t0:.0f} s: RMS lengths "
        f"{1e3 * res.rms_after['length_m']:.3f} mm, swivel "
        f"{1e3 * res.rms_after.get('swivel_rad', float('nan')):.2f} mrad")
    v = rec.valid
    R, p = platform_pose(res, rec.fit.V_R_M[v], rec.fit.V_p_M[v])
    meta = _calibrated_meta(uacdpr_meta(rec, sources_of(vicon, robot_log, config), swivel_axis),
                            res, subsample)
    with atomic_dir(out, force=force, owned=DATASET_FILES) as tmp:
        write_uacdpr(rec, tmp, meta, R, p, overwrite=True)
        if nuisance:
            from cdprid.base import ConvergenceError
            from cdprid.core import InsufficientDataError
            from cdprid.identify._real import nuisance_summary, prepare_real

            say("nuisance fit (offsets, delay, dynamics; whole recording) ...")
            try:
                meta["nuisance"] = nuisance_summary(prepare_real(read_dataset(tmp)))
                say(f"nuisance fit done at {time.perf_counter() - t0:.0f} s")
            except (ConvergenceError, InsufficientDataError) as exc:
                meta["nuisance"] = {"error": str(exc)}
                say(f"nuisance fit failed (recorded in meta.toml [nuisance]): {exc}")
            write_uacdpr(rec, tmp, meta, R, p, overwrite=True)
    return Path(out)


def _calibrated_meta(meta: dict, res: CalibrationResult, subsample: int) -> dict:
    """meta.toml of a converted recording, updated for the calibrated pose."""
    meta = dict(meta)
    meta["description"] = (
        "UACDPR (Univ. Bologna) recording with locked winches, imported by "
        "cdprid.io._uacdpr: pose of the configuration's platform frame in the robot base "
        "frame (rigid-body fit of the raw markers + geometric calibration); raw load-cell "
        "tensions at the robot's rate.")
    meta["frames"] = dict(meta["frames"])
    meta["frames"]["pose"] = (
        "platform frame P (the configuration's: robot.toml anchors apply) in the robot base "
        "frame B, from the geometric calibration (cdprid.identify._calibration, anchors='config')")
    cal = res.as_dict()
    cal["subsample"] = int(subsample)
    cal["note"] = ("sigma: formal 1-sigma of the LM fit (consecutive samples correlate: "
                   "lower bounds); rotation-vector sigmas in rad")
    meta["calibration"] = cal
    return meta
