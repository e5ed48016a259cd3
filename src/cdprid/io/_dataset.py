"""Spec-v1 datasets (see ``../shared/spec/dataset-format.md``): read, validate, align, write.

Every validation failure raises :class:`DatasetError` whose message is one sentence naming
the file, the line or column, and what is wrong; the CLI prints it and exits with code 2.

Reading: CSV files may start with a UTF-8 byte-order mark and may quote their header cells
(``"t","x"``). Implausible input is refused when nothing sensible can be computed from it:
non-finite values, magnitudes beyond :data:`MAX_ABS_TENSION_N` / :data:`MAX_ABS_POSITION_M`,
tensions that are all zero or mostly negative (cables only pull).

Alignment (:func:`align`): the pose stream is the master time base; **data are never
invented**. A period longer than :data:`GAP_FACTOR` median periods in the pose stream, or a
gap of the tension stream, splits the recording into segments that are differentiated
separately (:func:`cdprid.core.estimate_motion`) and never bridged; pose samples outside the
tension stream's range are dropped (the share is reported). Inside a segment, tensions are
linearly interpolated onto the pose times and a pose sampling with jitter above 1 % of the
median period is resampled onto a uniform grid by a cubic spline (reported in the notes).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import tomllib

from cdprid.base import InputError, UserError

if TYPE_CHECKING:  # geometry imports JAX: loaded only when a dataset is read or written
    from cdprid.model import CableRobot


QUAT_COLS = ("qw", "qx", "qy", "qz")
#: The files of a spec-v1 dataset folder that cdprid writes (``lengths.csv`` optional): the
#: only files a dataset-writing command replaces or removes in an existing folder with --force.
DATASET_FILES = ("robot.toml", "pose.csv", "tensions.csv", "meta.toml", "lengths.csv",
                 "currents.csv")


def dataset_inputs(path) -> list:
    """A dataset folder and the files of it a reader reads: what no output may be or hold.

    Parameters
    ----------
    path : path-like
        The dataset folder.

    Returns
    -------
    list of Path
        The folder, then each of :data:`DATASET_FILES` inside it (present or not).
    """
    return [Path(path)] + [Path(path) / f for f in DATASET_FILES]


GAP_FACTOR: float = 2.5


"""A sampling period longer than this many median periods is a gap: never bridged."""


MIN_SEGMENT_SAMPLES: int = 50


"""Gap-free segments shorter than this are dropped (too short to differentiate), reported."""


MAX_ABS_TENSION_N: float = 1e6


"""A cable tension beyond this magnitude (N) is not plausible: refused."""


MAX_ABS_POSITION_M: float = 1e4


"""A platform position beyond this magnitude (m) is not plausible: refused."""


STATIONARY_RANGE_M: float = 1e-3


"""A platform whose position range stays below this (m), with rotation range below
:data:`STATIONARY_RANGE_RAD`, does not move: nothing dynamic can be identified."""


STATIONARY_RANGE_RAD: float = 1e-3


"""Rotation range (rad) below which a platform is considered not rotating."""


NEGATIVE_TENSION_N: float = -5.0


"""A cable whose median tension is below this (N) is mostly negative: a sign error, refused."""


class DatasetError(UserError, ValueError):
    """Invalid dataset; the message is one sentence naming file, line/column and problem."""


@dataclasses.dataclass(frozen=True)
class Dataset:
    """A spec-v1 dataset in memory.

    Attributes
    ----------
    path : Path or None
    robot : CableRobot
    pose_t : ndarray (n,)
    position : ndarray (n, 3)
        P in the base frame, m.
    quaternion : ndarray (n, 4) or None
        Scalar-first unit quaternions platform -> base; None when absent (identity).
    tension_t : ndarray (k,) or None
    tension : ndarray (k, m) or None
        None only when read with ``require_tensions=False`` from a dataset without
        tensions.csv (format 1.2: drives' currents instead of load cells).
    meta : dict
        Parsed meta.toml ({} when absent).
    extra : dict
        Further streams ``name -> (columns, ndarray)`` with ``t`` as first column.
    """

    path: Path | None
    robot: CableRobot
    pose_t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray | None
    tension_t: np.ndarray
    tension: np.ndarray
    meta: dict = dataclasses.field(default_factory=dict)
    extra: dict = dataclasses.field(default_factory=dict)

    @property
    def truth(self) -> dict:
        """The ``[truth]`` table of meta.toml ({} for measured data)."""
        return dict(self.meta.get("truth", {}))


def _fmt_num(s: str) -> str:
    return s if len(s) < 30 else s[:27] + "..."


def _header(path: Path, line: str) -> list[str]:
    cols = []
    for c in line.split(","):
        c = c.strip()
        if len(c) >= 2 and c[0] == c[-1] and c[0] in "\"'":
            c = c[1:-1].strip()
        cols.append(c)
    if any(not c for c in cols):
        raise DatasetError(f"{path}: line 1 (header) has an empty column name.")
    return cols


def _parse_rows_slowly(path: Path, columns: list[str]) -> np.ndarray:
    """Line-by-line parse that names the first bad line and column (error path only)."""
    ncol = len(columns)
    rows = []
    with open(path, encoding="utf-8-sig") as fh:
        fh.readline()
        for lineno, line in enumerate(fh, start=2):
            if not line.strip():
                continue
            fields = line.rstrip("\r\n").split(",")
            if len(fields) != ncol:
                raise DatasetError(
                    f"{path}: line {lineno} has {len(fields)} fields but the header has {ncol}."
                )
            row = []
            for col, f in zip(columns, fields, strict=False):
                f = f.strip().strip('"').strip()
                try:
                    if "_" in f:  # Python reads '1_17.27' as 117.27: a typo, not a number
                        raise InputError(f)
                    v = float(f)
                except ValueError:
                    raise DatasetError(
                        f"{path}: line {lineno}, column '{col}': '{_fmt_num(f)}' is not a number."
                    ) from None
                if not math.isfinite(v):
                    raise DatasetError(
                        f"{path}: line {lineno}, column '{col}': value '{f}' is not finite."
                    )
                row.append(v)
            rows.append(row)
    return np.asarray(rows, dtype=float).reshape(len(rows), ncol)


def read_csv_stream(path: Path, required: tuple[str, ...] = ("t",)) -> tuple[list[str], np.ndarray]:
    """Read a CSV stream (one header line, numeric rows) with spec-v1 error messages.

    A UTF-8 byte-order mark and quoted header cells are accepted. The rows are parsed by
    NumPy's C reader (lean on multi-hour recordings); on any problem the file is re-read line
    by line to name the first bad line and column.

    Parameters
    ----------
    path : Path
        The CSV file.
    required : tuple of str
        Columns that must be present.

    Returns
    -------
    columns : list of str
    values : ndarray (n, len(columns))

    Raises
    ------
    DatasetError
        One sentence naming the file, line and column.
    """
    path = Path(path)
    if not path.is_file():
        if path.is_dir():
            raise DatasetError(f"{path}: is a folder, expected a CSV file.")
        raise DatasetError(f"{path}: required file is missing.")
    try:
        with open(path, encoding="utf-8-sig") as fh:
            first = fh.readline()
            if not first.strip():
                raise DatasetError(f"{path}: the file is empty (no header line).")
            columns = _header(path, first)
            for sep, name in ((";", "semicolons"), ("\t", "tabs")):
                if len(columns) == 1 and sep in first:
                    raise DatasetError(f"{path}: line 1 (header) is separated by {name}; spec-v1 "
                                       "CSV files use commas (`cdprid import table` reads other "
                                       "separators).")
            for c in required:
                if c not in columns:
                    raise DatasetError(f"{path}: line 1 (header) lacks the required column '{c}'.")
            if len(set(columns)) != len(columns):
                raise DatasetError(f"{path}: line 1 (header) has duplicate column names.")
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # "input contained no data" (checked below)
                    values = np.loadtxt(fh, delimiter=",", ndmin=2, quotechar='"', comments=None,
                                        dtype=float)
                ok = values.shape[1] == len(columns) or values.size == 0
                ok = ok and bool(np.isfinite(values).all())
            except ValueError:
                ok = False
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not valid UTF-8 text.") from None
    except OSError as exc:
        raise DatasetError(f"{path}: cannot be read ({exc.strerror}).") from None
    if not ok:
        values = _parse_rows_slowly(path, columns)
    if values.size == 0:
        raise DatasetError(f"{path}: the stream is empty (a header but no data rows).")
    t = values[:, columns.index("t")]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        k = int(bad[0])
        raise DatasetError(
            f"{path}: column 't' is not strictly increasing at data row {k + 2} "
            f"(t = {t[k + 1]:g} after {t[k]:g})."
        )
    return columns, values


def _read_toml(path: Path) -> dict:
    try:
        return tomllib.loads(path.read_bytes().removeprefix(b"\xef\xbb\xbf").decode("utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise DatasetError(f"{path}: not valid TOML ({exc}).") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not valid UTF-8 text.") from None
    except RecursionError:
        raise DatasetError(f"{path}: arrays or tables nested too deeply.") from None
    except ValueError as exc:  # a 5000-digit integer (int conversion limit)
        raise DatasetError(f"{path}: a value beyond the TOML parser's limits "
                           f"({str(exc).split(';')[0]}).") from None


def read_dataset(path: str | Path, require_tensions: bool = True) -> Dataset:
    """Read and validate a spec-v1 dataset folder.

    Parameters
    ----------
    path : str or Path
        The dataset folder.
    require_tensions : bool
        False: tensions.csv may be absent (format 1.2, identification from motor currents or
        free motion); the dataset's ``tension_t`` and ``tension`` are then None.

    Returns
    -------
    Dataset
        Robot, pose (t in s, position in m, unit quaternions), tensions (N), meta and the
        optional streams, validated.

    Raises
    ------
    DatasetError
        One sentence naming the file, line or column, and the problem.
    """
    from cdprid.model import RobotFileError, load_robot

    root = Path(path)
    if not root.exists():
        raise DatasetError(f"{root}: dataset folder does not exist.")
    if not root.is_dir():
        raise DatasetError(f"{root}: not a folder; a dataset is a folder holding robot.toml, "
                           "pose.csv and tensions.csv.")
    try:
        robot = load_robot(root / "robot.toml")
    except RobotFileError as exc:
        raise DatasetError(str(exc)) from None
    pose_cols, pose = read_csv_stream(root / "pose.csv", required=("t", "x", "y", "z"))
    has_q = [c in pose_cols for c in QUAT_COLS]
    if any(has_q) and not all(has_q):
        missing = [c for c, h in zip(QUAT_COLS, has_q, strict=False) if not h][0]
        raise DatasetError(
            f"{root / 'pose.csv'}: line 1 (header) has some quaternion columns but lacks "
            f"'{missing}' (qw, qx, qy, qz go together)."
        )
    idx = {c: i for i, c in enumerate(pose_cols)}
    pose_t = pose[:, idx["t"]]
    position = pose[:, [idx["x"], idx["y"], idx["z"]]]
    quaternion = None
    if all(has_q):
        quaternion = pose[:, [idx[c] for c in QUAT_COLS]]
        norms = np.linalg.norm(quaternion, axis=1)
        bad = np.nonzero(np.abs(norms - 1.0) > 1e-3)[0]
        if bad.size:
            k = int(bad[0])
            raise DatasetError(
                f"{root / 'pose.csv'}: data row {k + 1} (t = {pose_t[k]:g}) has a quaternion of "
                f"norm {norms[k]:.6g}, not 1 within 1e-3."
            )
        quaternion = quaternion / norms[:, None]
    meta = _read_toml(root / "meta.toml") if (root / "meta.toml").is_file() else {}
    extra = _extra_streams(root)
    if not require_tensions and not (root / "tensions.csv").exists():
        _check_magnitude(root / "pose.csv", position, ("x", "y", "z"), MAX_ABS_POSITION_M, "m")
        return Dataset(root, robot, pose_t, position, quaternion, None, None, meta, extra)
    if not (root / "tensions.csv").exists() and (root / "currents.csv").exists():
        raise DatasetError(f"{root / 'tensions.csv'}: required file is missing (the dataset has "
                           "currents.csv: identify it with --source currents).")
    tension_t, tension = _read_tensions(root, robot.n_cables)
    _check_magnitude(root / "pose.csv", position, ("x", "y", "z"), MAX_ABS_POSITION_M, "m")
    if pose_t[-1] < tension_t[0] or tension_t[-1] < pose_t[0]:
        raise DatasetError(
            f"{root}: the time ranges of pose.csv [{pose_t[0]:g}, {pose_t[-1]:g}] s and "
            f"tensions.csv [{tension_t[0]:g}, {tension_t[-1]:g}] s do not overlap."
        )
    return Dataset(root, robot, pose_t, position, quaternion, tension_t, tension, meta, extra)


def _extra_streams(root: Path) -> dict:
    """Further ``*.csv`` streams: a malformed stream cdprid reads (:data:`DATASET_FILES`) is
    refused, any other malformed file ignored (spec: anything else ignored)."""
    extra = {}
    for f in sorted(root.glob("*.csv")):
        if f.name in ("pose.csv", "tensions.csv"):
            continue
        try:
            extra[f.stem] = read_csv_stream(f, required=("t",))
        except DatasetError:
            if f.name in DATASET_FILES:  # lengths.csv: a stream cdprid reads, refused like the
                raise  # others (a `nan` dropped it silently and cable_elasticity went untested)
            continue  # other files are ignored when malformed (spec: anything else ignored)
    return extra


def _read_tensions(root: Path, m: int):
    """``(tension_t, tension)`` of tensions.csv, validated (columns, magnitude, signs)."""
    tcols, tens = read_csv_stream(root / "tensions.csv", required=("t",))
    tau_cols = [c for c in tcols if c != "t"]
    if len(tau_cols) != m:
        raise DatasetError(
            f"{root / 'tensions.csv'}: line 1 (header) has {len(tau_cols)} tension columns but "
            f"robot.toml defines {m} cables."
        )
    expected = [f"tau_{i}" for i in range(1, m + 1)]
    for i, c in enumerate(expected):
        if c not in tcols:
            raise DatasetError(
                f"{root / 'tensions.csv'}: line 1 (header) lacks the column '{c}' for cable "
                f"{i + 1}."
            )
    tidx = {c: i for i, c in enumerate(tcols)}
    tension_t = tens[:, tidx["t"]]
    tension = tens[:, [tidx[c] for c in expected]]
    _check_magnitude(root / "tensions.csv", tension, expected, MAX_ABS_TENSION_N, "N")
    _check_tension_signs(root / "tensions.csv", tension, expected)
    return tension_t, tension


def _check_magnitude(path: Path, values: np.ndarray, names, limit: float, unit: str) -> None:
    """Refuse absurd magnitudes (one sentence naming the data row and the column)."""
    big = np.abs(values) > limit
    if big.any():
        k, j = (int(v) for v in np.argwhere(big)[0])
        raise DatasetError(
            f"{path}: data row {k + 1}, column '{names[j]}': {values[k, j]:.6g} {unit} is not "
            f"plausible (beyond {limit:g} {unit}); check the units or the recording."
        )


def _check_tension_signs(path: Path, tension: np.ndarray, names) -> None:
    """Refuse tensions that are all zero or mostly negative: nothing physical follows."""
    if not np.any(tension):
        raise DatasetError(f"{path}: every tension is zero; the cable forces were not recorded, "
                           "so no dynamics can be identified.")
    med = np.median(tension, axis=0)
    neg = np.nonzero(med < NEGATIVE_TENSION_N)[0]
    if neg.size:
        j = int(neg[0])
        raise DatasetError(
            f"{path}: column '{names[j]}' is mostly negative (median {med[j]:.4g} N) but cables "
            "can only pull; check the sign convention of the load cells."
        )
