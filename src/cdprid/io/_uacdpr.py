"""Importer of UACDPR recordings (Univ. Bologna GRAB lab) into spec-v1 datasets.

Inputs (see ``docs/importers.md``):

- a raw Vicon "Trajectories" export (:mod:`cdprid.io._vicon`), 100 Hz, markers in mm;
- the robot log ``<name>_exp.mat`` with the struct ``st_out`` (fields ``t`` 1 x N at 1 kHz on
  the Vicon clock, ``tensions`` 4 x N in N, ``swivel`` 4 x N in rad, ``cable_length`` 4 x N,
  ``epsilon`` 3 x N inclinometer angles in rad); Vicon frame f is at ``t = (f - 1) / rate``;
- the robot configuration ``.mat`` with the struct ``s`` (``Trasmission.Pulley(i)`` with
  ``r``, ``CableEnterPosition``, ``FixedFrame``; ``EndEffector.Platform`` with ``m``,
  ``PtoG``, ``InertialMatrix``, ``points``).

The written pose is that of the MARKER frame in the VICON frame (both defined in
:mod:`cdprid.io._vicon`: origin at marker 9, axes = Vicon axes at the first frame); robot.toml
holds the configuration's geometry in the robot base frame and attachments in the platform
frame. The two frames pairs differ by transforms that :mod:`cdprid.identify._calibration` estimates;
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

from cdprid.base import InputError
from cdprid.io._vicon import MarkerFit, ViconTrajectories, estimate_layout, read_vicon_trajectories
from cdprid.model import CableRobot, robot_from_dict

__all__ = [
    "RobotLog",
    "UacdprRecording",
    "read_robot_log",
    "read_config",
    "config_to_dict",
    "load_uacdpr",
    "import_uacdpr",
    "sources_of",
    "uacdpr_meta",
    "write_uacdpr",
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
        raise InputError(f"{path}: {what} file is missing.")
    try:
        return scipy.io.loadmat(str(path), squeeze_me=True, struct_as_record=False)
    except NotImplementedError:
        raise InputError(f"{path}: MATLAB v7.3 (HDF5) files are not supported; save with "
                         "-v7 instead.") from None
    except Exception as exc:  # noqa: BLE001  (scipy raises several types for non-MAT input)
        raise InputError(f"{path}: not a readable MATLAB .mat file ({type(exc).__name__}).") \
            from None


def _field(obj, name: str, path: Path, where: str):
    if not hasattr(obj, name) or (hasattr(obj, "_fieldnames") and name not in obj._fieldnames):
        raise InputError(f"{path}: struct {where} has no field '{name}'.")
    return getattr(obj, name)


def _numeric(val, path: Path, where: str, shape=None) -> np.ndarray:
    try:
        arr = np.asarray(val, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: {where} is not numeric.") from None
    if shape is not None and arr.shape != shape:
        raise InputError(f"{path}: {where} has shape {arr.shape}, expected {shape}.")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{path}: {where} holds non-finite values.")
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
        raise InputError(f"{path}: holds no struct 'st_out' (a UACDPR _exp.mat log was expected).")
    st = d["st_out"]
    t = _numeric(_field(st, "t", path, "st_out"), path, "st_out.t").ravel()
    n = t.size
    if n < 2 or np.any(np.diff(t) <= 0):
        raise InputError(f"{path}: st_out.t is not a strictly increasing time vector.")

    def rows(name, k):
        a = _numeric(_field(st, name, path, "st_out"), path, f"st_out.{name}")
        a = np.atleast_2d(a)
        if a.shape == (n, k):
            return a
        if a.shape != (k, n):
            raise InputError(f"{path}: st_out.{name} has shape {a.shape}, expected ({k}, {n}) "
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
        raise InputError(f"swivel_axis must be 'first' or 'third', got {swivel_axis!r}.")
    path = Path(path)
    d = _loadmat(path, "configuration")
    if "s" not in d:
        raise InputError(f"{path}: holds no struct 's' (a UACDPR configuration was expected).")
    s = d["s"]
    tr = _field(s, "Trasmission", path, "s")
    pulleys = np.atleast_1d(_field(tr, "Pulley", path, "s.Trasmission"))
    ee = _field(s, "EndEffector", path, "s")
    plat = _field(ee, "Platform", path, "s.EndEffector")
    points = np.atleast_1d(_field(plat, "points", path, "s.EndEffector.Platform"))
    if points.dtype != object:  # stored as a numeric m x 3 matrix instead of a cell
        points = list(np.atleast_2d(points))
    if len(points) != len(pulleys):
        raise InputError(f"{path}: s.EndEffector.Platform.points has {len(points)} entries but "
                         f"s.Trasmission.Pulley has {len(pulleys)}.")
    cables = []
    for i, (p, b) in enumerate(zip(pulleys, points, strict=True), start=1):
        where = f"s.Trasmission.Pulley({i})"
        r = float(_numeric(_field(p, "r", path, where), path, f"{where}.r", ()))
        A = _numeric(_field(p, "CableEnterPosition", path, where), path,
                     f"{where}.CableEnterPosition", (3,))
        ff = list(np.atleast_1d(_field(p, "FixedFrame", path, where)))
        if len(ff) != 3:
            raise InputError(f"{path}: {where}.FixedFrame has {len(ff)} vectors, expected 3.")
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
    """A :class:`~cdprid.model.CableRobot` from a UACDPR configuration ``.mat``."""
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


def load_uacdpr(vicon: str | Path, robot_log: str | Path, config: str | Path,
                swivel_axis: str = DEFAULT_SWIVEL_AXIS) -> UacdprRecording:
    """Read the three inputs and fit the marker frame's pose (no file written).

    Parameters
    ----------
    vicon : path-like
        The Vicon trajectories export (raw markers).
    robot_log : path-like
        The robot's ``_exp.mat`` log (tensions, swivel, inclinometer, cable lengths).
    config : path-like
        The UACDPR configuration ``.mat`` (exits, anchors, pulleys).
    swivel_axis : {"first", "third"}
        Which ``FixedFrame`` vector of the configuration is the swivel axis.

    Returns
    -------
    UacdprRecording
        Robot, Vicon markers, marker-frame fit, robot log and pose times (s).

    Raises
    ------
    InputError
        Malformed input (one sentence naming the file), or Vicon and log times that do not
        overlap.
    """
    robot = read_config(config, swivel_axis)
    log = read_robot_log(robot_log, robot.n_cables)
    vt = read_vicon_trajectories(vicon)
    origin = ORIGIN_MARKER if vt.V_m.shape[1] > ORIGIN_MARKER else 0
    fit = estimate_layout(vt.V_m, origin_marker=origin)
    t = vt.t[np.all(np.isfinite(fit.V_p_M), axis=1)]
    if t[-1] < log.t[0] or log.t[-1] < t[0]:
        raise InputError(f"{vicon}: Vicon time range [{t[0]:g}, {t[-1]:g}] s does not overlap "
                         f"the robot log's [{log.t[0]:g}, {log.t[-1]:g}] s.")
    return UacdprRecording(robot, vt, fit, log, t)


def uacdpr_meta(rec: UacdprRecording, sources: dict, swivel_axis: str) -> dict:
    """meta.toml mapping of a converted recording (pose of the marker frame in the Vicon frame).

    Parameters
    ----------
    rec : UacdprRecording
    sources : dict
        Input file names by role (``vicon``, ``robot_log``, ``config``).
    swivel_axis : str

    Returns
    -------
    dict
    """
    rms = rec.fit.rms_per_marker
    log = rec.log
    return {
        "description": "UACDPR (Univ. Bologna) recording with locked winches, imported by "
                       "cdprid.io._uacdpr: pose of the marker frame in the Vicon frame from a "
                       "rigid-body fit of the raw markers; tensions at the robot's rate.",
        "source": "; ".join(f"{k}: {v}" for k, v in sources.items()),
        "frames": {
            "pose": "marker frame M in the Vicon frame V (NOT the platform frame in the base "
                    "frame): run cdprid.identify._calibration to estimate V->B and M->P",
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


def write_uacdpr(rec: UacdprRecording, out: str | Path, meta: dict, R=None, p=None,
                 overwrite: bool = False) -> Path:
    """Write a recording as a spec-v1 dataset folder (no computation beyond the format).

    Writes robot.toml (configuration), pose.csv (100 Hz), tensions.csv (1 kHz, raw load-cell
    readings), swivel.csv, inclinometer.csv, cable_length.csv and meta.toml.

    Parameters
    ----------
    rec : UacdprRecording
    out : path-like
        The dataset folder.
    meta : dict
        meta.toml content (:func:`uacdpr_meta`, possibly extended by the caller).
    R, p : ndarray (n, 3, 3), (n, 3), optional
        Pose to write at ``rec.pose_t`` (rotation; position, m); default: the marker frame in
        the Vicon frame.
    overwrite : bool
        Replace an existing folder.

    Returns
    -------
    Path
        The dataset folder.
    """
    from cdprid.io._writer import write_dataset
    from cdprid.model import matrix_to_quat

    v = rec.valid
    R = rec.fit.V_R_M[v] if R is None else R
    p = rec.fit.V_p_M[v] if p is None else p
    log = rec.log
    m = rec.robot.n_cables
    extra = {
        "swivel": (["t"] + [f"swivel_{i}" for i in range(1, m + 1)],
                   np.column_stack([log.t, log.swivel])),
        "inclinometer": (["t", "eps_1", "eps_2", "eps_3"], np.column_stack([log.t, log.epsilon])),
        "cable_length": (["t"] + [f"dl_{i}" for i in range(1, m + 1)],
                         np.column_stack([log.t, log.cable_length])),
    }
    return write_dataset(out, rec.robot, rec.pose_t, p, log.t, log.tensions,
                         quaternion=matrix_to_quat(R), meta=meta, extra=extra,
                         overwrite=overwrite)


def sources_of(vicon, robot_log, config) -> dict:
    """Input file names by role, for meta.toml ``source``.

    Parameters
    ----------
    vicon : path-like
        The Vicon trajectories export (raw markers).
    robot_log : path-like
        The robot's ``_exp.mat`` log (tensions, swivel, inclinometer, cable lengths).
    config : path-like
        The UACDPR configuration ``.mat`` (exits, anchors, pulleys).

    Returns
    -------
    dict
        ``{"vicon": name, "robot_log": name, "config": name}`` (file names without folders).
    """
    return {"vicon": Path(vicon).name, "robot_log": Path(robot_log).name,
            "config": Path(config).name}


def import_uacdpr(vicon: str | Path, robot_log: str | Path, config: str | Path,
                  out: str | Path, overwrite: bool = False,
                  swivel_axis: str = DEFAULT_SWIVEL_AXIS) -> Path:
    """Convert a UACDPR recording into a spec-v1 dataset folder (format conversion only).

    The pose is that of the marker frame in the Vicon frame; the geometric calibration and
    the nuisance fit are separate stages
    (:func:`cdprid.identify.import_calibrated_uacdpr` runs all three, as
    ``cdprid import uacdpr`` does). The folder appears whole or not at all.

    Parameters
    ----------
    vicon : path-like
        The Vicon trajectories export (raw markers).
    robot_log : path-like
        The robot's ``_exp.mat`` log (tensions, swivel, inclinometer, cable lengths).
    config : path-like
        The UACDPR configuration ``.mat`` (exits, anchors, pulleys).
    out : path-like
        The dataset folder to write.
    overwrite : bool
        Replace this command's files in an existing folder.
    swivel_axis : {"first", "third"}
        Which ``FixedFrame`` vector of the configuration is the swivel axis.

    Returns
    -------
    Path
        ``out``.

    Raises
    ------
    InputError
        Malformed input (one sentence naming the file).
    OutputError
        ``out`` exists and ``overwrite`` is False, or is an input (checked before reading).
    """
    from cdprid.base import atomic_dir, check_output
    from cdprid.io._dataset import DATASET_FILES

    check_output(out, force=overwrite, kind="dir", inputs=[vicon, robot_log, config])
    rec = load_uacdpr(vicon, robot_log, config, swivel_axis)
    meta = uacdpr_meta(rec, sources_of(vicon, robot_log, config), swivel_axis)
    with atomic_dir(out, force=overwrite, owned=DATASET_FILES) as tmp:
        write_uacdpr(rec, tmp, meta, overwrite=True)
    return Path(out)
