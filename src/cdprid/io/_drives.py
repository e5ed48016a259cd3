"""Winch drives (dataset format 1.2): the drive fields of robot.toml and the streams
``currents.csv`` and ``lengths.csv`` (see ``docs/drives.md``).

robot.toml, per ``[[cable]]`` (all three of the first fields on every cable, or on none)::

    drum_radius = 0.05                 # m, radius at which the cable leaves the drum
    gear_ratio = 10.0                  # motor turns per drum turn
    torque_constant = 0.12             # N m / A, motor torque per ampere (datasheet)
    torque_constant_tolerance = 0.10   # optional, relative half-width (0 = calibrated)
    drive_reference = true             # optional: this drive is the scale reference

The nominal current-to-force constant is ``k = torque_constant * gear_ratio / drum_radius``
(N/A). ``currents.csv`` is ``t,i_1..i_m`` (A, its own clock, positive current = torque that
winds the cable in = tension); ``lengths.csv`` is ``t,l_1..l_m`` (m, length paid out, as in
``docs/lengths.md``).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from cdprid.io._dataset import DatasetError, _read_toml, read_csv_stream

__all__ = ["DRIVE_FIELDS", "DriveData", "read_drives", "read_stream", "drive_table"]

#: the drive fields of a ``[[cable]]`` table (format 1.2)
DRIVE_FIELDS = ("drum_radius", "gear_ratio", "torque_constant", "torque_constant_tolerance",
                "drive_reference")
_REQUIRED = DRIVE_FIELDS[:3]


@dataclasses.dataclass(frozen=True)
class DriveData:
    """Nominal drive data of every winch (robot.toml, format 1.2).

    Attributes
    ----------
    drum_radius : ndarray (m,)
        m.
    gear_ratio : ndarray (m,)
        Motor turns per drum turn.
    torque_constant : ndarray (m,)
        N m / A (datasheet).
    tolerance : ndarray (m,)
        Relative half-width of the interval the true torque constant lies in (NaN: not
        stated).
    reference : ndarray (m,) of bool
        Drives marked ``drive_reference = true``.
    """

    drum_radius: np.ndarray
    gear_ratio: np.ndarray
    torque_constant: np.ndarray
    tolerance: np.ndarray
    reference: np.ndarray

    @property
    def k_nominal(self) -> np.ndarray:
        """Nominal current-to-force constants ``K_t N / r`` (m,), N/A."""
        return self.torque_constant * self.gear_ratio / self.drum_radius

    @property
    def n(self) -> int:
        """Number of drives."""
        return int(self.drum_radius.size)


def _number(src, where: str, key: str, value, positive: bool) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise DatasetError(f"{src}: {where} field '{key}' must be a finite number, got {value!r}.")
    if positive and value <= 0:
        raise DatasetError(f"{src}: {where} field '{key}' must be > 0, got {value}.")
    if not positive and value < 0:
        raise DatasetError(f"{src}: {where} field '{key}' must be >= 0, got {value}.")
    return float(value)


def drive_table(cables: list, source="robot.toml") -> DriveData | None:
    """The drive data of parsed ``[[cable]]`` tables; None when no cable has drive fields.

    Parameters
    ----------
    cables : list of dict
        The ``[[cable]]`` tables.
    source : str or Path
        Named in the error messages.

    Returns
    -------
    DriveData or None

    Raises
    ------
    DatasetError
        One sentence naming the file, the cable table and the field.
    """
    if not any(k in c for c in cables for k in DRIVE_FIELDS):
        return None
    cols = {k: [] for k in DRIVE_FIELDS}
    for i, c in enumerate(cables, start=1):
        where = f"[[cable]] number {i}"
        for k in _REQUIRED:
            if k not in c:
                raise DatasetError(f"{source}: {where} lacks the drive field '{k}' (drum_radius, "
                                   "gear_ratio and torque_constant go together on every cable).")
            cols[k].append(_number(source, where, k, c[k], True))
        tol = c.get("torque_constant_tolerance")
        cols["torque_constant_tolerance"].append(
            math.nan if tol is None else _number(source, where, "torque_constant_tolerance",
                                                 tol, False))
        ref = c.get("drive_reference", False)
        if not isinstance(ref, bool):
            raise DatasetError(f"{source}: {where} field 'drive_reference' must be true or false.")
        cols["drive_reference"].append(ref)
    if sum(cols["drive_reference"]) > 1:
        raise DatasetError(f"{source}: more than one [[cable]] has drive_reference = true; mark "
                           "one drive as the scale reference.")
    return DriveData(*(np.asarray(cols[k], float) for k in _REQUIRED),
                     np.asarray(cols["torque_constant_tolerance"], float),
                     np.asarray(cols["drive_reference"], bool))


def read_drives(path) -> DriveData | None:
    """The drive data of a dataset's robot.toml (folder or file); None without drive fields.

    Parameters
    ----------
    path : str or Path
        Dataset folder or robot.toml.

    Returns
    -------
    DriveData or None
    """
    p = Path(path)
    p = p / "robot.toml" if p.is_dir() else p
    data = _read_toml(p)
    cables = data.get("cable") or []
    return drive_table([c for c in cables if isinstance(c, dict)], p)


def read_stream(path, name: str, prefix: str, m: int, min_rows: int = 50):
    """A per-cable stream ``<name>.csv`` with columns ``t,<prefix>_1..<prefix>_m``.

    Parameters
    ----------
    path : str or Path
        Dataset folder.
    name : str
        Stream name (``currents`` or ``lengths``).
    prefix : str
        Column prefix (``i`` or ``l``).
    m : int
        Number of cables.
    min_rows : int
        Fewer rows are refused.

    Returns
    -------
    (t (k,), values (k, m)) or None when the file is absent.

    Raises
    ------
    DatasetError
        One sentence naming the file and the column or line.
    """
    f = Path(path) / f"{name}.csv"
    if not f.is_file():
        return None
    cols, vals = read_csv_stream(f, required=("t",))
    want = [f"{prefix}_{i}" for i in range(1, m + 1)]
    for c in want:
        if c not in cols:
            raise DatasetError(f"{f}: line 1 (header) lacks the column '{c}' (robot.toml "
                               f"defines {m} cables).")
    extra = [c for c in cols if c != "t" and c not in want]
    if extra:
        raise DatasetError(f"{f}: line 1 (header) has the column '{extra[0]}', which is not "
                           f"one of t, {want[0]}..{want[-1]}.")
    if len(vals) < min_rows:
        raise DatasetError(f"{f}: has {len(vals)} data rows, fewer than {min_rows}.")
    idx = {c: j for j, c in enumerate(cols)}
    return vals[:, idx["t"]], vals[:, [idx[c] for c in want]]
