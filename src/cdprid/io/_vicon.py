"""Raw Vicon marker exports and rigid-body pose fitting (Kabsch/Horn).

A Vicon Nexus "Trajectories" export (tab- or comma-separated) looks like::

    Trajectories
    100                                   <- frame rate, Hz
    ,,platform:points1,,,platform:points2,...      <- marker names (every third column)
    Frame,Sub Frame,X,Y,Z,X,Y,Z,...
    ,,mm,mm,mm,mm,mm,mm,...
    1,0,80.37,-39.55,806.31,...

Missing markers appear as empty fields (or, in some exports, as exact zeros); both are read
as NaN. :func:`read_vicon_trajectories` returns positions in metres.

Pose from markers: :mod:`cdprid.io._markers` (the one Kabsch/Horn rigid-body fit shared with the
C3D importer; re-exported here). The UACDPR authors take marker 9, the lowest one, as the
marker-frame origin. The relation between this marker frame and the robot's platform frame is
a nuisance that :mod:`cdprid.identify._calibration` estimates.

Names carry their frame: ``V_`` Vicon frame, ``M_`` marker frame; ``V_R_M`` rotates
marker-frame vectors into the Vicon frame and ``V_p_M`` is the marker-frame origin.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from cdprid.base import InputError
from cdprid.io._markers import MarkerFit as MarkerFit
from cdprid.io._markers import estimate_layout as estimate_layout
from cdprid.io._markers import fit_rigid_body as fit_rigid_body
from cdprid.io._markers import kabsch as kabsch

__all__ = [
    "ViconTrajectories",
    "MarkerFit",
    "read_vicon_trajectories",
    "kabsch",
    "fit_rigid_body",
    "estimate_layout",
]


@dataclasses.dataclass(frozen=True)
class ViconTrajectories:
    """Marker trajectories of one Vicon export.

    Attributes
    ----------
    frame : ndarray (n,) of int
        Vicon frame numbers (1-based in Nexus exports).
    rate_hz : float
        Frame rate from the header.
    names : tuple of str
        Marker names, e.g. ``platform:points1``.
    V_m : ndarray (n, k, 3)
        Marker positions, Vicon frame, m; NaN where a marker was not seen.
    """

    frame: np.ndarray
    rate_hz: float
    names: tuple
    V_m: np.ndarray

    @property
    def t(self) -> np.ndarray:
        """Time of each frame, s, with frame 1 at t = 0: ``(frame - 1) / rate``."""
        return (self.frame - 1) / self.rate_hz


def _split(line: str) -> list[str]:
    sep = "\t" if "\t" in line else ","
    return [f.strip() for f in line.rstrip("\r\n").split(sep)]


def read_vicon_trajectories(path: str | Path, units: str | None = None) -> ViconTrajectories:
    """Read a Vicon Nexus "Trajectories" export (5 header lines, then numeric rows).

    Parameters
    ----------
    path : file
    units : {"mm", "m"}, optional
        Overrides the units row of the header (default: read it; ``mm`` when absent).

    Raises
    ------
    ValueError
        One sentence naming the file and the line: a missing file, a header that is not a
        Vicon trajectories header, a non-numeric value or a truncated row.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: Vicon file is missing.")
    try:
        lines = path.read_text(encoding="utf-8", errors="strict").splitlines()
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file (a Vicon trajectories export was expected).") \
            from None
    if len(lines) < 6:
        raise InputError(f"{path}: has {len(lines)} lines, fewer than the 5 header lines and one "
                         "data row of a Vicon trajectories export.")
    if not lines[0].strip().lower().startswith("trajectories"):
        raise InputError(f"{path}: line 1 is {lines[0].strip()[:40]!r}, not 'Trajectories' "
                         "(expected a Vicon Nexus trajectories export).")
    rate, names, k, ncol, scale = _vicon_header(path, lines, units)
    rows = _vicon_rows(path, lines, ncol)
    data = np.asarray(rows, float)
    frame = data[:, 0]
    if not np.all(np.isfinite(frame)) or np.any(np.diff(frame) <= 0):
        raise InputError(f"{path}: the Frame column is not strictly increasing.")
    V_m = data[:, 2:].reshape(len(data), k, 3) * scale
    zero = np.all(V_m == 0.0, axis=2)
    V_m[zero] = np.nan
    V_m[~np.all(np.isfinite(V_m), axis=2)] = np.nan
    return ViconTrajectories(frame.astype(int), rate, names, V_m)


def _vicon_header(path: Path, lines: list[str], units: str | None):
    """Lines 2-5 of a Vicon trajectories export: ``(rate Hz, marker names, number of markers,
    number of columns, metres per unit)``; :class:`InputError` naming the line otherwise."""
    try:
        rate = float(_split(lines[1])[0])
    except ValueError:
        rate = float("nan")
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"{path}: line 2 should hold the frame rate in Hz, got "
                         f"{lines[1].strip()[:40]!r}.")
    head = _split(lines[3])
    if len(head) < 5 or head[0].lower() != "frame" or head[1].lower() != "sub frame":
        raise InputError(f"{path}: line 4 should start with 'Frame', 'Sub Frame', 'X', 'Y', 'Z', "
                         f"got {', '.join(head[:5])!r}.")
    coord = [h for h in head[2:] if h]
    if len(coord) % 3 != 0 or any(c.upper() != "XYZ"[j % 3] for j, c in enumerate(coord)):
        raise InputError(f"{path}: line 4 should list X, Y, Z columns after 'Sub Frame'.")
    k = len(coord) // 3
    ncol = 2 + 3 * k
    name_fields = _split(lines[2])
    names = tuple(f for f in name_fields if f)
    if len(names) != k:
        names = tuple(f"marker{j + 1}" for j in range(k))
    unit_fields = [u for u in _split(lines[4]) if u]
    if units is None:
        units = unit_fields[0] if unit_fields else "mm"
    scale = {"mm": 1e-3, "m": 1.0}.get(units.lower())
    if scale is None:
        raise InputError(f"{path}: line 5 gives the unit {units!r}; only 'mm' and 'm' are known.")
    return rate, names, k, ncol, scale


def _vicon_rows(path: Path, lines: list[str], ncol: int) -> list[list[float]]:
    """The numeric rows after the 5 header lines (blank lines skipped, empty marker fields as
    NaN); :class:`InputError` naming the line of a truncated, long or non-numeric row."""
    rows = []
    for lineno, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        fields = _split(line)
        while len(fields) > ncol and fields[-1] == "":
            fields.pop()
        if len(fields) < ncol:
            raise InputError(f"{path}: line {lineno} is truncated ({len(fields)} fields, "
                             f"{ncol} expected).")
        if len(fields) > ncol:
            raise InputError(f"{path}: line {lineno} has {len(fields)} fields, {ncol} expected.")
        row = []
        for j, f in enumerate(fields):
            if f == "" and j >= 2:
                row.append(np.nan)
                continue
            try:
                row.append(float(f))
            except ValueError:
                raise InputError(f"{path}: line {lineno}, field {j + 1}: {f[:20]!r} is not a "
                                 "number.") from None
        rows.append(row)
    if not rows:
        raise InputError(f"{path}: no data rows after the 5 header lines.")
    return rows
