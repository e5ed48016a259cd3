"""Importer of UACDPR recordings (Univ. Bologna GRAB lab) into spec-v1 datasets.

Inputs (see ``docs/importers.md``):

- a raw Vicon "Trajectories" export (:mod:`cdprid.io.vicon`), 100 Hz, markers in mm;
- the robot log ``<name>_exp.mat`` with the struct ``st_out`` (fields ``t`` 1 x N at 1 kHz on
  the Vicon clock, ``tensions`` 4 x N in N, ``swivel`` 4 x N in rad, ``cable_length`` 4 x N,
  ``epsilon`` 3 x N inclinometer angles in rad); Vicon frame f is at ``t = (f - 1) / rate``;
- the robot configuration ``.mat`` with the struct ``s`` (``Trasmission.Pulley(i)`` with
  ``r``, ``CableEnterPosition``, ``FixedFrame``; ``EndEffector.Platform`` with ``m``,
  ``PtoG``, ``InertialMatrix``, ``points``).

The written pose is that of the MARKER frame in the VICON frame (both defined in
:mod:`cdprid.io.vicon`: origin at marker 9, axes = Vicon axes at the first frame); robot.toml
holds the configuration's geometry in the robot base frame and attachments in the platform
frame. The two frames pairs differ by transforms that :mod:`cdprid.calibration` estimates;
meta.toml says so.

Swivel axis. In the lab's MATLAB model (``libs/cdpr_model/@Pulley``) the swivel axis is the
third ``FixedFrame`` vector and the swivel angle is ``atan2(FF2 . DA, FF1 . DA)``; the
configuration files hold ``FixedFrame = {[0 0 -1], [0 1 0], [1 0 0]}`` (pulleys 1, 2) and
``{[0 0 -1], [0 -1 0], [-1 0 0]}`` (pulleys 3, 4). ``swivel_axis="third"`` follows the MATLAB
model (axis FF3, horizontal, reference FF1); ``swivel_axis="first"`` reads the first vector as
the axis (vertical, reference FF2, the right-handed choice). The default is "third": on
FreeMotion02 the calibration explains the measured swivel angles to 4.0 mrad RMS with it, and
not at all (18 mrad, the signal's own spread) with "first"; the fitted encoder offsets
(+-0.81..0.85 rad) then equal the model's angle at homing (see ``docs/importers.md``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..geometry import CableRobot, robot_from_dict
from .vicon import MarkerFit, ViconTrajectories, estimate_layout, read_vicon_trajectories

__all__ = [
    "RobotLog",
    "UacdprRecording",
    "read_robot_log",
    "read_config",
    "config_to_dict",
    "load_uacdpr",
    "import_uacdpr",
    "DEFAULT_SWIVEL_AXIS",
]

DEFAULT_SWIVEL_AXIS = "third"
ORIGIN_MARKER = 8  # 0-based: marker 9 of the UACDPR platform


@dataclasses.dataclass(frozen=True)
class RobotLog:
    """The robot's own signals of an ``_exp.mat`` log (rows = samples).

    Attributes
    ----------
    t : ndarray (n,)
        Time, s, on the Vicon clock.
    tensions : ndarray (n, m)
        Load-cell tensions, N.
    swivel : ndarray (n, m)
        Swivel angles, rad, relative to homing.
    cable_length : ndarray (n, m)
        Cable lengths relative to homing, m.
    epsilon : ndarray (n, 3)
        Inclinometer angles in the Vicon frame, rad.
    """

    t: np.ndarray
    tensions: np.ndarray
    swivel: np.ndarray
    cable_length: np.ndarray
    epsilon: np.ndarray


def _loadmat(path: Path, what: str) -> dict:
    import scipy.io

    if not path.is_file():
        raise ValueError(f"{path}: {what} file is missing.")
    try:
        return scipy.io.loadmat(str(path), squeeze_me=True, struct_as_record=False)
    except NotImplementedError:
        raise ValueError(f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with "
                         "-v7 instead.") from None
    except Exception as exc:  # noqa: BLE001  (scipy raises several types for non-MAT input)
        raise ValueError(f"{path}: not a readable MATLAB .mat file ({type(exc).__name__}).") \
            from None


def _field(obj, name: str, path: Path, where: str):
    if not hasattr(obj, name) or (hasattr(obj, "_fieldnames") and name not in obj._fieldnames):
        raise ValueError(f"{path}: struct {where} has no field '{name}'.")
    return getattr(obj, name)


def _numeric(val, path: Path, where: str, shape=None) -> np.ndarray:
    try:
        arr = np.asarray(val, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: {where} is not numeric.") from None
    if shape is not None and arr.shape != shape:
        raise ValueError(f"{path}: {where} has shape {arr.shape}, expected {shape}.")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{path}: {where} holds non-finite values.")
    return arr


def read_robot_log(path: str | Path, n_cables: int = 4) -> RobotLog:
    """Read the ``st_out`` struct of a UACDPR ``_exp.mat`` log.

    Raises
    ------
    ValueError
        One sentence: missing file, not a MAT file, no ``st_out``, a missing field, or fields
        whose lengths disagree.
    """
    path = Path(path)
    d = _loadmat(path, "robot log")
    if "st_out" not in d:
        raise ValueError(f"{path}: holds no struct 'st_out' (a UACDPR _exp.mat log was expected).")
    st = d["st_out"]
    t = _numeric(_field(st, "t", path, "st_out"), path, "st_out.t").ravel()
    n = t.size
    if n < 2 or np.any(np.diff(t) <= 0):
        raise ValueError(f"{path}: st_out.t is not a strictly increasing time vector.")

    def rows(name, k):
        a = _numeric(_field(st, name, path, "st_out"), path, f"st_out.{name}")
        a = np.atleast_2d(a)
        if a.shape == (n, k):
            return a
        if a.shape != (k, n):
            raise ValueError(f"{path}: st_out.{name} has shape {a.shape}, expected ({k}, {n}) "
                             "like st_out.t.")
        return a.T

    return RobotLog(t, rows("tensions", n_cables), rows("swivel", n_cables),
                    rows("cable_length", n_cables), rows("epsilon", 3))


def config_to_dict(path: str | Path, swivel_axis: str = DEFAULT_SWIVEL_AXIS,
                   name: str | None = None) -> dict:
    """The spec-v1 robot.toml mapping of a UACDPR configuration ``.mat`` (struct ``s``).

    Parameters
    ----------
    path : file
    swivel_axis : {"first", "third"}
        Which ``FixedFrame`` vector is the swivel axis (module docstring).
    name : str, optional
        Robot name (default: the file stem).
    """
    if swivel_axis not in ("first", "third"):
        raise ValueError(f"swivel_axis must be 'first' or 'third', got {swivel_axis!r}.")
    path = Path(path)
    d = _loadmat(path, "configuration")
    if "s" not in d:
        raise ValueError(f"{path}: holds no struct 's' (a UACDPR configuration was expected).")
    s = d["s"]
    tr = _field(s, "Trasmission", path, "s")
    pulleys = np.atleast_1d(_field(tr, "Pulley", path, "s.Trasmission"))
    ee = _field(s, "EndEffector", path, "s")
    plat = _field(ee, "Platform", path, "s.EndEffector")
    points = np.atleast_1d(_field(plat, "points", path, "s.EndEffector.Platform"))
    if points.dtype != object:  # stored as a numeric m x 3 matrix instead of a cell
        points = list(np.atleast_2d(points))
    if len(points) != len(pulleys):
        raise ValueError(f"{path}: s.EndEffector.Platform.points has {len(points)} entries but "
                         f"s.Trasmission.Pulley has {len(pulleys)}.")
    cables = []
    for i, (p, b) in enumerate(zip(pulleys, points, strict=True), start=1):
        where = f"s.Trasmission.Pulley({i})"
        r = float(_numeric(_field(p, "r", path, where), path, f"{where}.r", ()))
        A = _numeric(_field(p, "CableEnterPosition", path, where), path,
                     f"{where}.CableEnterPosition", (3,))
        ff = list(np.atleast_1d(_field(p, "FixedFrame", path, where)))
        if len(ff) != 3:
            raise ValueError(f"{path}: {where}.FixedFrame has {len(ff)} vectors, expected 3.")
        ff = [_numeric(v, path, f"{where}.FixedFrame{{{j + 1}}}", (3,)) for j, v in enumerate(ff)]
        k, ref = (ff[0], ff[1]) if swivel_axis == "first" else (ff[2], ff[0])
        cables.append({
            "exit": A.tolist(),
            "anchor": _numeric(b, path, f"s.EndEffector.Platform.points{{{i}}}", (3,)).tolist(),
            "pulley_radius": r,
            "pulley_axis": (k / np.linalg.norm(k)).tolist(),
            "pulley_reference": (ref / np.linalg.norm(ref)).tolist(),
        })
    out = {"name": name or path.stem, "gravity": [0.0, 0.0, -9.81], "cable": cables}
    platform = {"mass": float(_numeric(_field(plat, "m", path, "s.EndEffector.Platform"), path,
                                       "s.EndEffector.Platform.m", ()))}
    platform["com"] = _numeric(_field(plat, "PtoG", path, "s.EndEffector.Platform"), path,
                               "s.EndEffector.Platform.PtoG", (3,)).tolist()
    platform["inertia"] = _numeric(_field(plat, "InertialMatrix", path, "s.EndEffector.Platform"),
                                   path, "s.EndEffector.Platform.InertialMatrix", (3, 3)).tolist()
    out["platform"] = platform
    return out


def read_config(path: str | Path, swivel_axis: str = DEFAULT_SWIVEL_AXIS) -> CableRobot:
    """A :class:`~cdprid.geometry.CableRobot` from a UACDPR configuration ``.mat``."""
    return robot_from_dict(config_to_dict(path, swivel_axis), source=str(path))


@dataclasses.dataclass(frozen=True)
class UacdprRecording:
    """Everything read from one recording, before writing.

    Attributes
    ----------
    robot : CableRobot
    vicon : ViconTrajectories
    fit : MarkerFit
        Marker layout and the marker frame's pose at every Vicon frame.
    log : RobotLog
    pose_t : ndarray (n,)
        Vicon times of frames with a valid fit, s.
    """

    robot: CableRobot
    vicon: ViconTrajectories
    fit: MarkerFit
    log: RobotLog
    pose_t: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """Rows of the Vicon stream with a valid rigid-body fit."""
        return np.all(np.isfinite(self.fit.V_p_M), axis=1)

    def swivel_at_pose(self, window: int = 11) -> np.ndarray:
        """Swivel angles at the pose times: centred moving average of ``window`` 1 kHz samples,
        then linear interpolation (NaN outside the log's time range)."""
        sw = self.log.swivel
        if window > 1:
            ker = np.ones(window) / window
            sw = np.column_stack([np.convolve(sw[:, i], ker, mode="same")
                                  for i in range(sw.shape[1])])
        return np.column_stack([np.interp(self.pose_t, self.log.t, sw[:, i], left=np.nan,
                                          right=np.nan) for i in range(sw.shape[1])])

    def calibration_data(self):
        """:class:`cdprid.calibration.CalibrationData` on the overlap of Vicon and robot log."""
        from ..calibration import CalibrationData

        v = self.valid
        R, p = self.fit.V_R_M[v], self.fit.V_p_M[v]
        sw = self.swivel_at_pose()
        keep = np.all(np.isfinite(sw), axis=1)
        return CalibrationData(self.pose_t[keep], R[keep], p[keep], sw[keep])


def load_uacdpr(vicon: str | Path, robot_log: str | Path, config: str | Path,
                swivel_axis: str = DEFAULT_SWIVEL_AXIS) -> UacdprRecording:
    """Read the three inputs and fit the marker frame's pose (no file written)."""
    robot = read_config(config, swivel_axis)
    log = read_robot_log(robot_log, robot.n_cables)
    vt = read_vicon_trajectories(vicon)
    origin = ORIGIN_MARKER if vt.V_m.shape[1] > ORIGIN_MARKER else 0
    fit = estimate_layout(vt.V_m, origin_marker=origin)
    t = vt.t[np.all(np.isfinite(fit.V_p_M), axis=1)]
    if t[-1] < log.t[0] or log.t[-1] < t[0]:
        raise ValueError(f"{vicon}: Vicon time range [{t[0]:g}, {t[-1]:g}] s does not overlap "
                         f"the robot log's [{log.t[0]:g}, {log.t[-1]:g}] s.")
    return UacdprRecording(robot, vt, fit, log, t)


def _meta(rec: UacdprRecording, sources: dict, swivel_axis: str) -> dict:
    rms = rec.fit.rms_per_marker
    log = rec.log
    return {
        "description": "UACDPR (Univ. Bologna) recording with locked winches, imported by "
                       "cdprid.io.uacdpr: pose of the marker frame in the Vicon frame from a "
                       "rigid-body fit of the raw markers; tensions at the robot's rate.",
        "source": "; ".join(f"{k}: {v}" for k, v in sources.items()),
        "frames": {
            "pose": "marker frame M in the Vicon frame V (NOT the platform frame in the base "
                    "frame): run cdprid.calibration to estimate V->B and M->P",
            "marker_frame": f"origin at marker {rec.fit.origin_marker + 1} "
                            f"({rec.vicon.names[rec.fit.origin_marker]}); axes = Vicon axes at "
                            f"frame row {rec.fit.reference_frame} (t = "
                            f"{rec.vicon.t[rec.fit.reference_frame]:g} s)",
            "robot_toml": "exits and pulleys in the configuration's base frame B; anchors in "
                          "the configuration's platform frame P",
            "swivel_axis": f"FixedFrame vector '{swivel_axis}' read as the swivel axis",
            "time": "Vicon frame f at t = (f - 1) / rate; robot log t on the Vicon clock",
        },
        "marker_fit": {
            "layout_m": rec.fit.M_m.tolist(),
            "rms_per_marker_mm": (1e3 * rms).tolist(),
            "rms_mm": 1e3 * rec.fit.rms,
            "max_mm": float(1e3 * np.nanmax(rec.fit.residual)),
            "iterations": rec.fit.n_iter,
        },
        "streams": {
            "swivel": "swivel angles, rad, relative to homing (encoder zero unknown)",
            "inclinometer": "inclinometer angles eps_1..3 brought into the Vicon frame, rad",
            "cable_length": "cable lengths relative to homing, m",
            "tension_range_N": [log.tensions.min(0).tolist(), log.tensions.max(0).tolist()],
        },
    }


def import_uacdpr(vicon: str | Path, robot_log: str | Path, config: str | Path,
                  out: str | Path, overwrite: bool = False,
                  swivel_axis: str = DEFAULT_SWIVEL_AXIS, calibrate: bool = True,
                  subsample: int = 4, yaw_starts: int = 4, dynamics: bool = True,
                  progress=None) -> Path:
    """Convert a UACDPR recording into a spec-v1 dataset folder.

    Writes robot.toml (configuration), pose.csv (100 Hz), tensions.csv (1 kHz, raw load-cell
    readings), swivel.csv, inclinometer.csv, cable_length.csv and meta.toml.

    With ``calibrate=True`` (default) the geometric calibration
    (:func:`cdprid.calibration.calibrate_geometry`, ``anchors="config"``, on every
    ``subsample``-th Vicon frame) runs first and pose.csv holds the pose of the
    configuration's PLATFORM frame in the robot BASE frame, so robot.toml's anchors and
    exits apply unchanged; meta.toml ``[calibration]`` holds the estimates and their standard
    deviations. With ``dynamics=True`` meta.toml ``[nuisance]`` also holds the load-cell offsets
    and the residual time delay estimated from the dynamics over the whole recording
    (:func:`cdprid.real.identify_real`, full model, taut phases), for information only:
    tensions.csv stays raw. ``calibrate=False`` writes the marker frame in the Vicon frame.

    Raises
    ------
    ValueError
        Malformed input (one sentence naming the file).
    FileExistsError
        ``out`` already holds a dataset and ``overwrite`` is False.
    """
    from ..rotations import matrix_to_quat
    from .dataset import write_dataset

    def say(msg):
        if progress is not None:
            progress(msg)

    out = Path(out)
    if out.exists() and not overwrite:  # fail before the (slow) calibration, as write_dataset
        clash = [f for f in ("robot.toml", "pose.csv", "tensions.csv", "meta.toml")
                 if (out / f).exists()]
        if clash:
            raise FileExistsError(f"{out}: already holds {', '.join(clash)}; refusing to "
                                  "overwrite (use --force).")
    rec = load_uacdpr(vicon, robot_log, config, swivel_axis)
    v = rec.valid
    R, p = rec.fit.V_R_M[v], rec.fit.V_p_M[v]
    log = rec.log
    m = rec.robot.n_cables
    extra = {
        "swivel": (["t"] + [f"swivel_{i}" for i in range(1, m + 1)],
                   np.column_stack([log.t, log.swivel])),
        "inclinometer": (["t", "eps_1", "eps_2", "eps_3"], np.column_stack([log.t, log.epsilon])),
        "cable_length": (["t"] + [f"dl_{i}" for i in range(1, m + 1)],
                         np.column_stack([log.t, log.cable_length])),
    }
    sources = {"vicon": Path(vicon).name, "robot_log": Path(robot_log).name,
               "config": Path(config).name}
    meta = _meta(rec, sources, swivel_axis)
    if calibrate:
        from ..calibration import calibrate_geometry, platform_pose

        data = rec.calibration_data().subsample(max(1, int(subsample)))
        say(f"geometric calibration on {len(data.t)} Vicon frames ...")
        res = calibrate_geometry(rec.robot, data, anchors="config", yaw_starts=yaw_starts)
        say(f"calibration RMS: lengths {1e3 * res.rms_after['length_m']:.3f} mm, swivel "
            f"{1e3 * res.rms_after.get('swivel_rad', float('nan')):.2f} mrad")
        R, p = platform_pose(res, R, p)
        meta["description"] = (
            "UACDPR (Univ. Bologna) recording with locked winches, imported by "
            "cdprid.io.uacdpr: pose of the configuration's platform frame in the robot base "
            "frame (rigid-body fit of the raw markers + geometric calibration); raw load-cell "
            "tensions at the robot's rate.")
        meta["frames"]["pose"] = (
            "platform frame P (the configuration's: robot.toml anchors apply) in the robot base "
            "frame B, from the geometric calibration (cdprid.calibration, anchors='config')")
        cal = res.as_dict()
        cal["subsample"] = int(subsample)
        cal["note"] = ("sigma: formal 1-sigma of the LM fit (consecutive samples correlate: "
                       "lower bounds); rotation-vector sigmas in rad")
        meta["calibration"] = cal
    ds_path = write_dataset(out, rec.robot, rec.pose_t, p, log.t, log.tensions,
                            quaternion=matrix_to_quat(R), meta=meta, extra=extra,
                            overwrite=overwrite)
    if calibrate and dynamics:
        try:
            meta["nuisance"] = _dynamic_nuisance(ds_path, say)
        except Exception as exc:  # noqa: BLE001  (informational: never fail the import)
            meta["nuisance"] = {"error": f"{type(exc).__name__}: {exc}"}
        write_dataset(out, rec.robot, rec.pose_t, p, log.t, log.tensions,
                      quaternion=matrix_to_quat(R), meta=meta, extra=extra, overwrite=True)
    return ds_path


def _dynamic_nuisance(path: Path, say) -> dict:
    """Load-cell offsets and time delay from the dynamics over the whole recording."""
    from ..real import identify_real, prepare_real, weight_at_rest
    from .dataset import read_dataset

    ds = read_dataset(path)
    data = prepare_real(ds)
    say("dynamic nuisances (offsets, delay) by nonlinear LS over the whole recording ...")
    r = identify_real(data, model="full", train_until=float(data.t[-1]) + 1.0, offsets=True,
                      delay=True, gains=False)
    out = {
        "note": ("estimated by cdprid.real.identify_real (full model, offsets + delay, taut "
                 "phases, every cable > 5 N) over the whole recording; tensions.csv is NOT "
                 "corrected. Model: tau_true(t) = tau_meas(t + delay) - offset. std inflated "
                 "by the residual correlation length"),
        "offset_N": r.offset.tolist(),
        "offset_std_N": [r.std[f"offset_{i + 1}"] for i in range(len(r.offset))],
        "delay_s": r.delay,
        "delay_std_s": r.std["delay"],
        "mass_from_motion_kg": r.values["m"],
        "mass_from_motion_std_kg": r.std["m"],
        "force_residual_rms_N": r.train_rms["force_N"],
        "n_taut_samples": r.n_train,
    }
    try:
        w = weight_at_rest(data, offset=r.offset)
        out["mass_at_rest_kg"] = w["mass"]
        out["rest_windows_s"] = [list(x) for x in w["windows"]]
    except ValueError:
        pass
    return out
