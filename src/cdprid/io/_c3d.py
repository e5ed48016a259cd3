"""C3D motion-capture files -> spec-v1 dataset (``cdprid import c3d``), read with ``ezc3d``.

Vicon, Qualisys and OptiTrack export C3D. The platform's markers (``markers``: names in the
file; default every marker) give the platform pose by the shared rigid-body fit of
:mod:`cdprid.io._markers`:

- with a **given layout** (``layout``: a CSV ``name,x,y,z`` of the markers in the platform
  frame, origin P), the pose is the platform's in the motion-capture frame;
- without it, the layout is **estimated from the data**, and the pose is that of a marker
  frame (origin at ``origin_marker``, axes = the capture axes at the first frame where every
  marker is seen): a nuisance that :mod:`cdprid.identify._calibration` or the user must relate to
  the
  robot's platform frame. meta.toml says which.

The motion-capture frame is taken as the robot's base frame (stated in meta.toml).

Marker gaps are never bridged: a frame where fewer than ``min_markers`` (>= 3) platform
markers are seen gets no pose; it is dropped from pose.csv, counted and listed as time
intervals in meta.toml ``[import] gaps`` (the dataset reader segments at such gaps).

Tensions: analog channels named by ``analog_tensions`` (one per cable, in robot.toml's order)
at the analog rate. Values are those returned by ezc3d (with ANALOG:SCALE, GEN_SCALE and
OFFSET applied) in the channel's ANALOG:UNITS, converted to N; a channel whose unit is not a
force (e.g. V) needs ``analog_units`` to state the force unit it holds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cdprid.base import UserError
from cdprid.io._table import UNITS, unit_scale

__all__ = ["import_c3d", "marker_gaps", "platform_pose", "read_c3d_markers", "read_layout"]


def _param(c, group: str, name: str, default=None):
    try:
        v = c["parameters"][group][name]["value"]
    except KeyError:
        return default
    return list(np.ravel(v)) if isinstance(v, np.ndarray) else v


def _labels(c, group: str) -> list[str]:
    return [str(v).strip() for v in (_param(c, group, "LABELS", []) or [])]


def _load(path: str | Path):
    import ezc3d

    path = Path(path)
    if not path.is_file():
        raise UserError(f"{path}: C3D file is missing.")
    cut = _truncated_header(path)
    if cut:
        raise UserError(f"{path}: the file is truncated: {cut} (copy it again from the capture "
                        "system).")
    try:
        return ezc3d.c3d(str(path))
    except Exception as exc:  # noqa: BLE001 - ezc3d raises plain RuntimeError/IOError
        raise UserError(f"{path}: cannot be read as a C3D file ({exc}).") from None


def _select(names: list[str], wanted: list[str] | None, path, option: str, what: str) -> list[int]:
    if not wanted:
        return list(range(len(names)))
    idx = []
    for w in wanted:
        if w not in names:
            raise UserError(f"{option}: the C3D {path} has no {what} {w!r}; its {what}s are "
                            f"{', '.join(names) or 'none'}.")
        idx.append(names.index(w))
    return idx


def _truncated_header(path) -> str | None:
    """Where a file ends before its own header says its sections end, or None: the parameter
    section (block ``head[0]``, ``param[2]`` blocks long) and the start of the data (header
    word 9); a file cut inside its parameters was blamed on the markers."""
    try:
        size = Path(path).stat().st_size
        with open(path, "rb") as fh:
            head = fh.read(512)
            fh.seek(max(head[0] - 1, 0) * 512 if head else 0)
            param = fh.read(4)
    except OSError:
        return None
    if len(head) < 512 or head[1] != 0x50:  # not a C3D header: ezc3d says what it is
        return None if len(head) >= 512 else "it ends inside its 512-byte header"
    start = (head[0] - 1) * 512
    if len(param) < 4:
        return f"it ends at byte {size}, before its parameter section (byte {start})"
    end = start + param[2] * 512
    if size < end:
        return f"it ends at byte {size}, inside its parameter section (bytes {start}-{end})"
    if param[3] == 84:  # Intel: the data start is readable as a little-endian word
        data = (int.from_bytes(head[16:18], "little") - 1) * 512
        if size < data:
            return f"it ends at byte {size}, before its data (byte {data})"
    return None


def _declared_frames(path) -> int | None:
    """Frames the file's own header declares (ezc3d rewrites its copy of the header to what it
    could read, so a truncated file looks whole): words 4-5 of the 512-byte header, read only
    for Intel (little-endian) files; None when it cannot be told."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
            fh.seek(max(head[0] - 1, 0) * 512)
            param = fh.read(4)
    except OSError:
        return None
    if len(head) < 10 or len(param) < 4 or param[3] != 84:  # 84: Intel processor type
        return None
    first = int.from_bytes(head[6:8], "little")
    last = int.from_bytes(head[8:10], "little")
    if last == 0xFFFF or last < first:  # long files keep the count in a parameter only
        return None
    return last - first + 1


def read_c3d_markers(c, path, markers: list[str] | None):
    """Marker names, positions (n, k, 3) in m with NaN where unseen, rate (Hz), unit."""
    names = _labels(c, "POINT")
    idx = _select(names, markers, path, "--markers", "marker")
    if len(idx) < 3:
        raise UserError(f"--markers: {len(idx)} marker(s) selected in {path}; a rigid-body pose "
                        "needs at least 3.")
    unit = str((_param(c, "POINT", "UNITS", ["mm"]) or ["mm"])[0]).strip() or "mm"
    scale = unit_scale("length", unit, f"{path} POINT:UNITS")
    pts = np.asarray(c["data"]["points"], float)[:3, idx, :]  # (3, k, n)
    V_m = np.transpose(pts, (2, 1, 0)) * scale
    res = np.asarray(c["data"]["meta_points"]["residuals"], float)[0, idx, :].T  # (n, k)
    V_m[res < 0] = np.nan
    V_m[np.all(V_m == 0.0, axis=2)] = np.nan  # some exporters write zeros for unseen markers
    rate = float(_param(c, "POINT", "RATE", [c["header"]["points"]["frame_rate"]])[0])
    declared = _declared_frames(path)
    if declared is not None and declared > V_m.shape[0]:  # truncated: never import a part
        raise UserError(f"{path}: the header declares {declared} frames but the file holds "
                        f"{V_m.shape[0]}: the file is truncated (copy it again from the "
                        "capture system).")
    return [names[i] for i in idx], V_m, rate, unit


def read_layout(path: str | Path, names: list[str], units: str = "m"):
    """Marker layout (k, 3) in the platform frame, m, from a CSV ``name,x,y,z`` (header line)."""
    from cdprid.io._table import read_table

    tab = read_table(path, "--layout")
    raw = Path(path).read_text(encoding="utf-8-sig").splitlines()
    s = unit_scale("length", units, "--layout-units")
    for c in ("name", "x", "y", "z"):
        if c not in tab.columns:
            raise UserError(f"--layout {path}: lacks the column {c!r} (name, x, y, z expected).")
    delim = {"whitespace": None}.get(tab.delimiter, tab.delimiter)
    rows = [r.split(delim) for r in raw[1:] if r.strip()]
    j = tab.columns.index("name")
    lnames = [r[j].strip().strip('"') for r in rows]
    xyz = np.column_stack([tab.column(c, "--layout") for c in "xyz"]) * s
    out = []
    for n in names:
        if n not in lnames:
            raise UserError(f"--layout {path}: has no row for the marker {n!r}.")
        out.append(xyz[lnames.index(n)])
    M = np.asarray(out)
    if not np.all(np.isfinite(M)):
        raise UserError(f"--layout {path}: a coordinate is not a number.")
    return M


def marker_gaps(t, good) -> list[list[float]]:
    """Time intervals ``[first, last]`` (s) of consecutive frames without a pose."""
    bad = ~np.asarray(good, bool)
    out = []
    i = 0
    while i < len(bad):
        if bad[i]:
            j = i
            while j + 1 < len(bad) and bad[j + 1]:
                j += 1
            out.append([float(t[i]), float(t[j])])
            i = j + 1
        else:
            i += 1
    return out


def _per_channel(c, name: str, idx: list[int]) -> list[float]:
    v = _param(c, "ANALOG", name, []) or []
    return [float(v[i]) for i in idx] if len(v) > max(idx) else []


def _analog_tensions(c, path, channels: list[str], m: int, units_override: str | None):
    names = _labels(c, "ANALOG")
    if len(channels) != m:
        raise UserError(f"--analog-tensions: names {len(channels)} channel(s) but robot.toml has "
                        f"{m} cables (one channel per cable, in order).")
    idx = _select(names, channels, path, "--analog-tensions", "analog channel")
    data = np.asarray(c["data"]["analogs"], float)[0][idx].T  # (n_analog, m)
    units = [str(u).strip() for u in (_param(c, "ANALOG", "UNITS", []) or [])]
    scales = []
    for i in idx:
        u = units_override or (units[i] if i < len(units) else "")
        if u not in UNITS["force"]:
            raise UserError(f"--analog-tensions: the channel {names[i]!r} is in {u or 'no unit'!r}"
                            ", not a force unit; give --analog-units with the force unit it "
                            f"holds ({', '.join(UNITS['force'])}).")
        scales.append(unit_scale("force", u, "--analog-units"))
    rate = float(_param(c, "ANALOG", "RATE", [c["header"]["analogs"]["frame_rate"]])[0])
    t = np.arange(data.shape[0]) / rate
    info = {
        "channels": [names[i] for i in idx],
        "units": [units_override or (units[i] if i < len(units) else "") for i in idx],
        "rate_hz": rate,
        "scale": _per_channel(c, "SCALE", idx),
        "gen_scale": [float(v) for v in _param(c, "ANALOG", "GEN_SCALE", []) or []],
        "offset": _per_channel(c, "OFFSET", idx),
        "note": "values as returned by ezc3d, which applies ANALOG:SCALE, GEN_SCALE and OFFSET; "
                "then converted from the channel unit to N",
    }
    return t, data * np.asarray(scales), info


#: Marker fit RMS above which the import is refused (a wrong layout unit gave 125,795 mm).
MAX_FIT_RMS_MM = 20.0


def platform_pose(V_m, names: list[str], t, path, layout=None, layout_units: str = "m",
                  origin_marker: str | None = None, min_markers: int = 3):
    """Rigid-body pose of every frame (:mod:`cdprid.io._markers`), NaN where too few markers.

    Returns
    -------
    V_R_M : (n, 3, 3), V_p_M : (n, 3), residual : (n, k) m, layout M_m : (k, 3) m, and a
    sentence saying which frame the pose is of.
    """
    from cdprid.io._markers import estimate_layout, fit_rigid_body

    if layout is not None:
        M_m = read_layout(layout, names, layout_units)
        R, p, res = fit_rigid_body(V_m, M_m, min_markers)
        frame_note = "platform frame (layout given) in the motion-capture frame"
    else:
        o = 0 if origin_marker is None else _select(names, [origin_marker], path,
                                                    "--origin-marker", "marker")[0]
        try:
            fit = estimate_layout(V_m, origin_marker=o)
        except ValueError as exc:
            raise UserError(f"{path}: cannot estimate the marker layout ({exc}); give --layout.") \
                from None
        M_m = fit.M_m
        R, p, res = fit_rigid_body(V_m, M_m, min_markers)
        frame_note = (f"marker frame (layout estimated from the data; origin at marker "
                      f"{names[o]!r}, axes = capture axes at t = {t[fit.reference_frame]:g} s) in "
                      "the motion-capture frame: not the robot's platform frame unless calibrated")
    return R, p, res, M_m, frame_note


def import_c3d(path: str | Path, robot: str | Path, out: str | Path,
               markers: list[str] | None = None, analog_tensions: list[str] | None = None,
               layout: str | Path | None = None, layout_units: str = "m",
               origin_marker: str | None = None, min_markers: int = 3,
               analog_units: str | None = None, tensions: str | Path | None = None,
               tension_columns: str | None = None, tension_units: str | None = None,
               tension_time_offset: float = 0.0, force: bool = False) -> Path:
    """Convert a C3D file (markers, optional load-cell analogs) into a spec-v1 dataset folder.

    Parameters
    ----------
    path : path
        The C3D file.
    robot : path
        robot.toml (copied into the dataset).
    out : path
        Dataset folder to create.
    markers : list of str, optional
        Platform marker names (default: every marker of the file).
    analog_tensions : list of str, optional
        Analog channels holding the cable tensions, in robot.toml's order.
    layout : path, optional
        CSV ``name,x,y,z`` of the markers in the platform frame (default: estimated).
    layout_units : str
        Length unit of ``layout``.
    origin_marker : str, optional
        Marker at the marker-frame origin when the layout is estimated (default the first).
    min_markers : int
        Frames with fewer seen markers get no pose (>= 3).
    analog_units : str, optional
        Force unit of the tension channels when ANALOG:UNITS does not give one.
    tensions, tension_columns, tension_units, tension_time_offset
        Tensions from a separate table instead of analog channels (as ``cdprid import table``).
    force : bool
        Replace an existing ``out``.

    Returns
    -------
    Path
    """
    from cdprid.base import check_output
    from cdprid.io._table import write_imported
    from cdprid.model import load_robot

    check_output(out, force, "--out", kind="dir", inputs=[path, robot, layout, tensions])
    rob = load_robot(robot)
    if min_markers < 3:
        raise UserError(f"--min-markers: {min_markers} is below 3, the least a rigid-body pose "
                        "needs.")
    if (analog_tensions is None) == (tensions is None):
        raise UserError("--analog-tensions / --tensions: give exactly one source of tensions "
                        "(analog channels of the C3D, or a separate table).")
    c = _load(path)
    names, V_m, rate, unit = read_c3d_markers(c, path, markers)
    n = V_m.shape[0]
    t = np.arange(n) / rate
    R, p, res, M_m, frame_note = platform_pose(V_m, names, t, path, layout, layout_units,
                                               origin_marker, min_markers)
    good = np.isfinite(p).all(1)
    _check_pose_fit(path, res, good, min_markers, layout_units)
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(R[good]).as_quat()
    q = np.concatenate([q[:, 3:], q[:, :3]], axis=1)
    imp = _import_record(path, names, unit, rate, min_markers, frame_note, M_m, V_m, t, good,
                         res)
    tt, tau, imp["tensions"] = _c3d_tensions(c, path, rob.n_cables, analog_tensions,
                                             analog_units, tensions, tension_columns,
                                             tension_units, tension_time_offset)
    meta = {
        "description": f"imported from the C3D file {Path(path).name} by `cdprid import c3d`",
        "source": "imported",
        "import": imp,
        "units": {"t": "s", "position": "m", "quaternion": "scalar first, platform -> base",
                  "tension": "N"},
    }
    return write_imported(out, rob, t[good], p[good], tt, tau, quaternion=q, meta=meta,
                          force=force)


def _check_pose_fit(path, res, good, min_markers: int, layout_units: str) -> None:
    """Refuse (:class:`UserError`) a recording with fewer than 2 posed frames or whose markers
    fit the rigid body worse than :data:`MAX_FIT_RMS_MM`."""
    if good.sum() < 2:
        raise UserError(f"{path}: fewer than 2 frames show {min_markers} of the platform markers.")
    fit_mm = float(1e3 * np.sqrt(np.nanmean(res[good] ** 2)))
    if fit_mm > MAX_FIT_RMS_MM:  # a rigid body fits its markers to about a millimetre
        raise UserError(f"{path}: the markers fit the rigid-body layout with an RMS of "
                        f"{fit_mm:.4g} mm (more than {MAX_FIT_RMS_MM:g} mm): is the layout in "
                        f"another unit (--layout-units, now {layout_units!r}) or are the markers "
                        "misnamed?")


def _import_record(path, names, unit, rate, min_markers, frame_note, M_m, V_m, t, good,
                   res) -> dict:
    """meta.toml ``[import]`` of a C3D import (its ``tensions`` entry is added by the caller):
    markers, rate, pose frame, layout, frames without pose, gaps and fit RMS."""
    n = V_m.shape[0]
    seen = np.all(np.isfinite(V_m), axis=2)
    gaps = marker_gaps(t, good)
    return {
        "format": "c3d",
        "file": str(path),
        "markers": names,
        "marker_unit": unit,
        "rate_hz": rate,
        "min_markers": int(min_markers),
        "pose_frame": frame_note,
        "base_frame": "the motion-capture frame is taken as the robot's base frame",
        "layout_m": M_m.tolist(),
        "frames": int(n),
        "frames_without_pose": int((~good).sum()),
        "marker_seen_fraction": [float(v) for v in seen.mean(0)],
        "gaps": gaps[:200],
        "gaps_note": "frames with fewer than min_markers seen markers are dropped, never bridged",
        "fit_rms_mm": float(1e3 * np.sqrt(np.nanmean(res[good] ** 2))),
        "time": "frame index / rate, from the first frame of the file",
    }


def _c3d_tensions(c, path, m: int, analog_tensions, analog_units, tensions, tension_columns,
                  tension_units, tension_time_offset):
    """The tensions of a C3D import, from its analog channels or from a separate table:
    ``(t, tau (n, m) N, the [import] tensions entry)``."""
    if analog_tensions is not None:
        return _analog_tensions(c, path, analog_tensions, m, analog_units)
    from cdprid.io._table import parse_mapping, parse_units, read_tension_table

    tu = parse_units(tension_units, "--tension-units", ("time", "force"))
    tmap = parse_mapping(tension_columns, "--tension-columns") or \
        {k: k for k in ["t"] + [f"tau_{i}" for i in range(1, m + 1)]}
    _tab, tt, tau, drop = read_tension_table(tensions, tmap, m, tu, float(tension_time_offset))
    return tt, tau, {"file": str(tensions), "columns": tmap, "units": tu,
                     "time_offset_s": float(tension_time_offset), "rows_dropped": drop}
