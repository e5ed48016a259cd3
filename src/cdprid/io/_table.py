# ruff: noqa: F722  (jaxtyping shape strings)
"""Pose and tension tables from any logger (CSV/TSV) -> spec-v1 dataset (``cdprid import table``).

A table is one header line and numeric rows. The delimiter is detected from the header line
(tab, then semicolon, then comma, else runs of whitespace); a UTF-8 byte-order mark and quoted
header names are handled, and semicolon tables may use a decimal comma (``1,25``). Columns
are chosen by a mapping such as ``t=time,x=px,y=py,z=pz``
(:func:`parse_mapping`); units are given per quantity (:data:`UNITS`) and converted to SI.
Orientation comes from quaternion columns ``qw,qx,qy,qz`` (scalar first, platform -> base) or
from three Euler angles ``e1,e2,e3`` with a scipy sequence (``Rotation.from_euler``: upper
case intrinsic, lower case extrinsic, angles in the order of the sequence).

Data are never invented: a row with an empty or non-numeric field in a used column is dropped
and counted (the count goes to meta.toml ``[import]``), never interpolated. Everything the
importer assumed (files, delimiters, column mapping, units, time offset, rotation convention)
is written to meta.toml ``[import]``; the dataset itself is in SI units.

This module also holds the parts every importer shares: unit tables (:func:`unit_scale`) and
the writer of an imported dataset (:func:`write_imported`).
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
from jaxtyping import Float

from cdprid.base import UserError

__all__ = ["UNITS", "Table", "import_table", "parse_mapping", "parse_units", "read_table",
           "read_tension_table", "unit_scale", "euler_to_quaternion", "write_imported"]

#: quantity -> unit -> factor to SI (s, m, rad, N).
UNITS: dict = {
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0},
    "length": {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "in": 0.0254},
    "angle": {"rad": 1.0, "deg": np.pi / 180.0},
    "force": {"N": 1.0, "kN": 1e3, "mN": 1e-3, "kgf": 9.80665, "lbf": 4.4482216152605},
}

POSE_KEYS = ("t", "x", "y", "z")
QUAT_KEYS = ("qw", "qx", "qy", "qz")
EULER_KEYS = ("e1", "e2", "e3")


def unit_scale(quantity: str, unit: str, option: str) -> float:
    """Factor from ``unit`` of ``quantity`` to SI; UserError naming ``option`` if unknown."""
    table = UNITS[quantity]
    if unit not in table:
        raise UserError(f"{option}: unknown {quantity} unit {unit!r}; use one of "
                        f"{', '.join(table)}.")
    return float(table[unit])


def parse_mapping(text: str | None, option: str) -> dict[str, str]:
    """Parse ``key=COL,key=COL`` into a dict (column names may hold spaces, not commas or '=')."""
    out: dict[str, str] = {}
    if not text:
        return out
    for item in text.split(","):
        if not item.strip():
            continue
        key, sep, col = item.partition("=")
        key, col = key.strip(), col.strip()
        if not sep or not key or not col:
            raise UserError(f"{option}: {item.strip()!r} is not of the form key=COLUMN.")
        if key in out:
            raise UserError(f"{option}: the key {key!r} is given twice.")
        twice = [k for k, c in out.items() if c == col]
        if twice:
            raise UserError(f"{option}: the column {col!r} is mapped to both {twice[0]!r} and "
                            f"{key!r}; each key needs its own column.")
        out[key] = col
    return out


def parse_units(text: str | None, option: str, allowed: tuple[str, ...]) -> dict[str, str]:
    """Parse ``time=ms,length=mm`` into {quantity: unit} (SI for the quantities not given)."""
    si = {"time": "s", "length": "m", "angle": "rad", "force": "N"}
    out = {q: si[q] for q in allowed}
    for q, u in parse_mapping(text, option).items():
        if q not in allowed:
            raise UserError(f"{option}: unknown quantity {q!r}; use {', '.join(allowed)}.")
        unit_scale(q, u, option)
        out[q] = u
    return out


@dataclasses.dataclass(frozen=True)
class Table:
    """A numeric table read from a text file.

    Attributes
    ----------
    path : Path
    columns : tuple of str
        Header names (quotes and surrounding spaces removed).
    values : ndarray (n, c)
        NaN where a field was empty or not a number.
    delimiter : str
        ``","``, ``";"``, ``"\\t"`` or ``"whitespace"``.
    """

    path: Path
    columns: tuple
    values: np.ndarray
    delimiter: str

    def column(self, name: str, option: str) -> np.ndarray:
        """The column called ``name``; UserError naming the file and ``option`` if absent."""
        if name not in self.columns:
            raise UserError(f"{self.path}: has no column {name!r} (asked by {option}); its "
                            f"columns are {', '.join(self.columns)}.")
        return self.values[:, self.columns.index(name)]


def _detect_delimiter(header: str) -> str:
    for d in ("\t", ";", ","):
        if d in header:
            return d
    return "whitespace"


def _to_float(field: str, decimal_comma: bool = False) -> float:
    try:
        return float(field)
    except ValueError:
        if decimal_comma and field.count(",") == 1:
            return _to_float(field.replace(",", "."))
        return float("nan")


def _split_rows(lines: list, delim: str, path: Path, option: str, numbered: list) -> list:
    """The fields of every non-empty line; a field beyond the csv module's size limit is one
    sentence naming its line (a 131,072-character header cell gave an internal error)."""
    if delim == "whitespace":
        return [ln.split() for ln in lines]
    reader = csv.reader(iter(lines), delimiter=delim)
    rows = []
    try:
        for row in reader:
            rows.append(row)
    except csv.Error as exc:
        k = min(max(reader.line_num, 1), len(numbered)) - 1
        raise UserError(f"{option} {path}: line {numbered[k][0]} cannot be read as a table row "
                        f"({exc}).") from None
    if len(rows) != len(lines):  # a quoted field spanning lines: no row numbers to trust
        raise UserError(f"{option} {path}: a quoted field spans several lines; a table has "
                        "one row per line.")
    return rows


def read_table(path: str | Path, option: str = "--pose") -> Table:
    """Read a delimited text table (see the module docstring for the detection rules).

    Raises
    ------
    UserError
        A missing or empty file, a file that is not text, or duplicate header names.
    """
    path = Path(path)
    if not path.is_file():
        raise UserError(f"{option} {path}: file is missing.")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise UserError(f"{option} {path}: not UTF-8 text (a CSV/TSV table was expected).") \
            from None
    numbered = [(k + 1, ln) for k, ln in enumerate(text.splitlines()) if ln.strip()]
    lines = [ln for _, ln in numbered]
    if len(lines) < 2:
        raise UserError(f"{option} {path}: needs a header line and at least one data row.")
    delim = _detect_delimiter(lines[0])
    rows = _split_rows(lines, delim, path, option, numbered)
    header = [h.strip().strip('"').strip("'") if delim == "whitespace" else h.strip()
              for h in rows[0]]
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise UserError(f"{option} {path}: the header names the column {dup!r} twice.")
    ncol = len(header)
    wide = next((i for i, row in enumerate(rows[1:], 1) if len(row) > ncol), None)
    if wide is not None:  # a decimal comma in a comma-separated file shifts the row
        name = {",": "commas", ";": "semicolons", "\t": "tabs"}.get(delim, "spaces")
        raise UserError(f"{option} {path}: line {numbered[wide][0]} has {len(rows[wide])} "
                        f"fields separated by {name}, the header {ncol}: a decimal comma in a "
                        "comma-separated file, or a missing header name?")
    values = np.full((len(rows) - 1, ncol), np.nan)
    for i, row in enumerate(rows[1:]):
        for j, f in enumerate(row[:ncol]):
            values[i, j] = _to_float(f.strip(), decimal_comma=delim == ";")
    return Table(path, tuple(header), values, delim)


def euler_to_quaternion(angles: Float[np.ndarray, "n 3"], seq: str,
                        option: str = "--euler") -> Float[np.ndarray, "n 4"]:
    """Scalar-first quaternions (platform -> base) of Euler angles in rad (scipy convention)."""
    from scipy.spatial.transform import Rotation

    try:
        q = Rotation.from_euler(seq, angles).as_quat()  # scalar last
    except ValueError as exc:
        raise UserError(f"{option} {seq!r}: not a valid Euler sequence ({exc}).") from None
    return np.concatenate([q[:, 3:], q[:, :3]], axis=1)


def _keep_finite(t, cols: np.ndarray, path: Path, option: str):
    ok = np.isfinite(t) & np.all(np.isfinite(cols), axis=1)
    if ok.sum() < 2:
        raise UserError(f"{option} {path}: fewer than 2 rows have numbers in every mapped column.")
    t, cols = t[ok], cols[ok]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        k = int(bad[0])
        raise UserError(f"{option} {path}: the time column is not strictly increasing at "
                        f"data row {k + 2} (t = {t[k + 1]:g} after {t[k]:g}).")
    return t, cols, int((~ok).sum())


def _quaternion_columns(tab: Table, cmap: dict, euler: str | None, units: dict):
    """(n, 4) quaternions or None, and a description of the convention."""
    has_q = [k in cmap for k in QUAT_KEYS]
    has_e = [k in cmap for k in EULER_KEYS]
    if any(has_q) and any(has_e):
        raise UserError("--pose-columns: give either qw,qx,qy,qz or e1,e2,e3, not both.")
    if any(has_q) and not all(has_q):
        raise UserError(f"--pose-columns: lacks {[k for k in QUAT_KEYS if k not in cmap][0]!r} "
                        "(qw, qx, qy, qz go together).")
    if any(has_e) and not all(has_e):
        raise UserError(f"--pose-columns: lacks {[k for k in EULER_KEYS if k not in cmap][0]!r} "
                        "(e1, e2, e3 go together).")
    if all(has_e) and not euler:
        raise UserError("--euler: is required with Euler-angle columns e1, e2, e3 "
                        "(e.g. --euler ZYX for intrinsic yaw-pitch-roll).")
    if euler and not all(has_e):
        raise UserError("--euler: given but --pose-columns maps no e1, e2, e3 columns.")
    if all(has_q):
        q = np.column_stack([tab.column(cmap[k], "--pose-columns") for k in QUAT_KEYS])
        return q, "quaternion columns (qw, qx, qy, qz), scalar first, platform -> base"
    if all(has_e):
        a = np.column_stack([tab.column(cmap[k], "--pose-columns") for k in EULER_KEYS])
        a = a * unit_scale("angle", units["angle"], "--pose-units")
        return a, (f"Euler angles e1, e2, e3 = {', '.join(cmap[k] for k in EULER_KEYS)} in "
                   f"{units['angle']}, scipy Rotation.from_euler({euler!r}) "
                   f"({'intrinsic' if euler.isupper() else 'extrinsic'}), platform -> base")
    return None, "none (pure translation: identity orientation)"


def _read_pose(path, cmap, euler, units):
    tab = read_table(path, "--pose")
    missing = [k for k in POSE_KEYS if k not in cmap]
    if missing:
        raise UserError(f"--pose-columns: lacks {missing[0]!r} (t, x, y, z are required).")
    unknown = [k for k in cmap if k not in POSE_KEYS + QUAT_KEYS + EULER_KEYS]
    if unknown:
        raise UserError(f"--pose-columns: unknown key {unknown[0]!r}; use t, x, y, z and "
                        "qw, qx, qy, qz or e1, e2, e3.")
    t = tab.column(cmap["t"], "--pose-columns") * unit_scale("time", units["time"], "--pose-units")
    xyz = np.column_stack([tab.column(cmap[k], "--pose-columns") for k in "xyz"])
    xyz = xyz * unit_scale("length", units["length"], "--pose-units")
    rot, convention = _quaternion_columns(tab, cmap, euler, units)
    cols = xyz if rot is None else np.hstack([xyz, rot])
    t, cols, dropped = _keep_finite(t, cols, tab.path, "--pose")
    q = None
    if rot is not None:
        q = cols[:, 3:]
        if q.shape[1] == 3:
            q = euler_to_quaternion(q, euler)
        norm = np.linalg.norm(q, axis=1)
        if np.any(np.abs(norm - 1.0) > 1e-3):
            k = int(np.argmax(np.abs(norm - 1.0)))
            raise UserError(f"--pose {tab.path}: a quaternion has norm {norm[k]:.6g} (t = "
                            f"{t[k]:g} s), not 1 within 1e-3; check the qw, qx, qy, qz mapping.")
        q = q / norm[:, None]
    return tab, t, cols[:, :3], q, convention, dropped


def read_tension_table(path, cmap: dict, m: int, units: dict, offset: float):
    """Tension table -> (Table, t (k,) s on the pose clock, tension (k, m) N, rows dropped)."""
    tab = read_table(path, "--tensions")
    want = ["t"] + [f"tau_{i}" for i in range(1, m + 1)]
    missing = [k for k in want if k not in cmap]
    if missing:
        raise UserError(f"--tension-columns: lacks {missing[0]!r} (robot.toml has {m} cables: "
                        f"t and tau_1..tau_{m} are required).")
    extra = [k for k in cmap if k not in want]
    if extra:
        raise UserError(f"--tension-columns: {extra[0]!r} is not one of t, tau_1..tau_{m} "
                        f"(robot.toml has {m} cables).")
    t = tab.column(cmap["t"], "--tension-columns") * unit_scale("time", units["time"],
                                                                  "--tension-units")
    tau = np.column_stack([tab.column(cmap[k], "--tension-columns") for k in want[1:]])
    tau = tau * unit_scale("force", units["force"], "--tension-units")
    t, tau, dropped = _keep_finite(t, tau, tab.path, "--tensions")
    return tab, t + offset, tau, dropped


def _unmapped_notes(ptab, pmap: dict, ttab, tmap: dict, m: int) -> list[str]:
    """Say what the import leaves out: a tension column past the robot's cables is refused
    (a 7-cable robot.toml with tau_1..tau_8 is a mistake), unmapped rotation columns noted."""
    extra_tau = [c for c in ttab.columns if c.startswith("tau_") and c not in tmap.values()]
    if extra_tau:
        raise UserError(f"--tensions {ttab.path}: has the column {extra_tau[0]!r} but robot.toml "
                        f"has {m} cables; check the robot file or map the columns with "
                        "--tension-columns.")
    rot = [c for c in ptab.columns if c in QUAT_KEYS + EULER_KEYS and c not in pmap.values()]
    if rot:
        return [f"the pose table's columns {', '.join(rot)} were not imported (not in "
                "--pose-columns): the dataset has no orientation"]
    return []


def _validate_with_reader(tmp: Path, out) -> None:
    """Read the dataset just written with the reader every command uses: an importer never
    writes what its reader would reject (NaN from a bag or C3D, a broken time column)."""
    from cdprid.io._dataset import DatasetError, read_dataset

    try:
        read_dataset(tmp)
    except DatasetError as exc:
        msg = str(exc).replace(str(tmp), str(out))
        raise UserError(f"the imported data would not be a valid dataset: {msg}") from None


def write_imported(out: str | Path, robot, pose_t, position, tension_t, tension,
                   quaternion=None, meta: dict | None = None, force: bool = False,
                   extra: dict | None = None) -> Path:
    """Write an imported dataset folder atomically (whole or not at all).

    Checks that the pose and tension time ranges overlap (UserError otherwise), then writes
    with :func:`cdprid.io.write_dataset` inside :func:`cdprid.base.atomic_dir`.
    """
    from cdprid.base import atomic_dir
    from cdprid.io._dataset import DATASET_FILES
    from cdprid.io._writer import write_dataset

    if pose_t[-1] < tension_t[0] or tension_t[-1] < pose_t[0]:
        raise UserError(f"the pose time range [{pose_t[0]:g}, {pose_t[-1]:g}] s and the tension "
                        f"time range [{tension_t[0]:g}, {tension_t[-1]:g}] s do not overlap; "
                        "check the time units and the time offset.")
    with atomic_dir(out, force=force, owned=DATASET_FILES) as tmp:
        write_dataset(tmp, robot, pose_t, position, tension_t, tension, quaternion=quaternion,
                      meta=meta, extra=extra, overwrite=True)
        _validate_with_reader(tmp, out)
    return Path(out)


def import_table(pose: str | Path, tensions: str | Path, robot: str | Path, out: str | Path,
                 pose_columns: str | None = None, tension_columns: str | None = None,
                 euler: str | None = None, pose_units: str | None = None,
                 tension_units: str | None = None, tension_time_offset: float = 0.0,
                 force: bool = False) -> Path:
    """Convert a pose table and a tension table into a spec-v1 dataset folder.

    Parameters
    ----------
    pose, tensions : path
        CSV/TSV files (see the module docstring).
    robot : path
        robot.toml of the robot (copied into the dataset).
    out : path
        Dataset folder to create.
    pose_columns : str, optional
        ``t=COL,x=COL,y=COL,z=COL`` plus ``qw=,qx=,qy=,qz=`` or ``e1=,e2=,e3=``; default: the
        spec-v1 names (``t,x,y,z`` and ``qw..qz`` when the file has them).
    tension_columns : str, optional
        ``t=COL,tau_1=COL,...``; default ``t`` and ``tau_1..tau_m``.
    euler : str, optional
        scipy Euler sequence of e1, e2, e3 (e.g. ``ZYX`` intrinsic, ``xyz`` extrinsic).
    pose_units, tension_units : str, optional
        ``time=ms,length=mm,angle=deg`` and ``time=s,force=kN``; SI by default.
    tension_time_offset : float
        Seconds (SI) added to the tension clock, after its unit conversion, to put it on the
        pose clock.
    force : bool
        Replace an existing ``out``.

    Returns
    -------
    Path
        The dataset folder.
    """
    from cdprid.base import check_output
    from cdprid.model import load_robot

    check_output(out, force, "--out", kind="dir", inputs=[pose, tensions, robot])
    rob = load_robot(robot)
    pu = parse_units(pose_units, "--pose-units", ("time", "length", "angle"))
    tu = parse_units(tension_units, "--tension-units", ("time", "force"))
    if not np.isfinite(tension_time_offset):
        raise UserError(f"--tension-time-offset: {tension_time_offset} is not a finite number.")
    m = rob.n_cables
    pmap = parse_mapping(pose_columns, "--pose-columns")
    if not pmap:
        head = read_table(pose, "--pose").columns
        pmap = {k: k for k in POSE_KEYS + (QUAT_KEYS if "qw" in head else ())}
    tmap = parse_mapping(tension_columns, "--tension-columns") or \
        {k: k for k in ["t"] + [f"tau_{i}" for i in range(1, m + 1)]}
    ptab, pt, pos, q, convention, pdrop = _read_pose(pose, pmap, euler, pu)
    ttab, tt, tau, tdrop = read_tension_table(tensions, tmap, m, tu, float(tension_time_offset))
    notes = _unmapped_notes(ptab, pmap, ttab, tmap, m)
    meta = _table_meta(ptab, ttab, pmap, tmap, pu, tu, convention, tension_time_offset, pdrop,
                       tdrop, notes, euler)
    return write_imported(out, rob, pt, pos, tt, tau, quaternion=q, meta=meta, force=force)


def _table_meta(ptab, ttab, pmap, tmap, pu, tu, convention, tension_time_offset, pdrop, tdrop,
                notes, euler) -> dict:
    """meta.toml of a table import: its ``[import]`` record (files, delimiters, column
    mappings, units, orientation convention, dropped rows, notes, assumptions)."""
    names = {",": "comma", ";": "semicolon", "\t": "tab", "whitespace": "whitespace"}
    meta = {
        "description": f"imported from the tables {ptab.path.name} and {ttab.path.name} by "
                       "`cdprid import table`",
        "source": "imported",
        "import": {
            "format": "table",
            "pose_file": str(ptab.path),
            "tension_file": str(ttab.path),
            "pose_delimiter": names[ptab.delimiter],
            "tension_delimiter": names[ttab.delimiter],
            "pose_columns": pmap,
            "tension_columns": tmap,
            "pose_units": pu,
            "tension_units": tu,
            "orientation": convention,
            "tension_time_offset_s": float(tension_time_offset),
            "pose_rows_dropped": pdrop,
            "tension_rows_dropped": tdrop,
            "notes": notes,
            "assumptions": [
                "positions are of the platform reference point P in the robot's base frame",
                "tensions are in robot.toml's cable order",
                "rows with an empty or non-numeric mapped field were dropped, not interpolated",
                "the tension clock plus tension_time_offset_s is the pose clock",
            ],
        },
        "units": {"t": "s", "position": "m", "quaternion": "scalar first, platform -> base",
                  "tension": "N"},
    }
    if euler:
        meta["import"]["euler"] = euler
    return meta
