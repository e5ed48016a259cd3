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
import os
import warnings
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import tomllib

from cdprid.base._errors import OutputError, OutputExistsError, UserError

if TYPE_CHECKING:  # geometry imports JAX: loaded only when a dataset is read or written
    from cdprid.model._geometry import CableRobot

__all__ = ["Dataset", "DatasetError", "AlignedSignals", "read_dataset", "write_dataset", "align",
           "sampling_report", "read_csv_stream", "GAP_FACTOR", "MIN_SEGMENT_SAMPLES",
           "MAX_ABS_TENSION_N", "MAX_ABS_POSITION_M", "STATIONARY_RANGE_M"]

QUAT_COLS = ("qw", "qx", "qy", "qz")

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
    tension_t : ndarray (k,)
    tension : ndarray (k, m)
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
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise DatasetError(f"{path}: not valid TOML ({exc}).") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not valid UTF-8 text.") from None


def read_dataset(path: str | Path) -> Dataset:
    """Read and validate a spec-v1 dataset folder.

    Raises
    ------
    DatasetError
        One sentence naming the file, line or column, and the problem.
    """
    from cdprid.model._geometry import RobotFileError, load_robot

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
    m = robot.n_cables
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
    _check_magnitude(root / "pose.csv", position, ("x", "y", "z"), MAX_ABS_POSITION_M, "m")
    _check_magnitude(root / "tensions.csv", tension, expected, MAX_ABS_TENSION_N, "N")
    _check_tension_signs(root / "tensions.csv", tension, expected)
    if pose_t[-1] < tension_t[0] or tension_t[-1] < pose_t[0]:
        raise DatasetError(
            f"{root}: the time ranges of pose.csv [{pose_t[0]:g}, {pose_t[-1]:g}] s and "
            f"tensions.csv [{tension_t[0]:g}, {tension_t[-1]:g}] s do not overlap."
        )
    meta = _read_toml(root / "meta.toml") if (root / "meta.toml").is_file() else {}
    extra = {}
    for f in sorted(root.glob("*.csv")):
        if f.name in ("pose.csv", "tensions.csv"):
            continue
        try:
            extra[f.stem] = read_csv_stream(f, required=("t",))
        except DatasetError:
            continue  # optional streams are ignored when malformed (spec: anything else ignored)
    return Dataset(root, robot, pose_t, position, quaternion, tension_t, tension, meta, extra)


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


def sampling_report(t, tol: float = 0.01) -> dict:
    """Describe the sampling of a time vector.

    Returns
    -------
    dict with ``uniform`` (bool, jitter within ``tol`` of the median period), ``dt`` (median
    period, s), ``rate_hz``, ``max_jitter`` (largest relative deviation of a period) and ``n``.
    """
    t = np.asarray(t, float)
    if t.size < 2:
        return {"uniform": True, "dt": float("nan"), "rate_hz": float("nan"), "max_jitter": 0.0,
                "n": int(t.size)}
    d = np.diff(t)
    dt = float(np.median(d))
    jitter = float(np.max(np.abs(d - dt)) / dt)
    return {"uniform": jitter <= tol, "dt": dt, "rate_hz": 1.0 / dt, "max_jitter": jitter,
            "n": int(t.size)}


@dataclasses.dataclass(frozen=True)
class AlignedSignals:
    """Pose and tensions on the pose time base, as gap-free segments (never bridged).

    Attributes
    ----------
    t : ndarray (n,)
        Times of the kept samples; uniform (period ``dt``) inside each segment.
    dt : float
        Median sampling period, s.
    position : ndarray (n, 3)
    quaternion : ndarray (n, 4)
        Sign-continuous unit quaternions (identity when the dataset has none).
    tension : ndarray (n, m)
    has_rotation : bool
        Whether the dataset carried quaternions.
    resampled : bool
        True when a segment's pose sampling was not uniform and was resampled.
    notes : tuple of str
        Human-readable notes on what alignment did (gaps, drops, resampling, warnings).
    segments : tuple of (int, int)
        Half-open index ranges ``[start, stop)`` of the gap-free segments in ``t``; each is
        differentiated on its own (:func:`cdprid.core.estimate_motion`). One segment
        ``((0, n),)`` when the recording has no gap.
    """

    t: np.ndarray
    dt: float
    position: np.ndarray
    quaternion: np.ndarray
    tension: np.ndarray
    has_rotation: bool
    resampled: bool
    notes: tuple = ()
    segments: tuple = ()

    def __post_init__(self):
        if not self.segments:
            object.__setattr__(self, "segments", ((0, len(self.t)),))

    @property
    def n_segments(self) -> int:
        """Number of gap-free segments."""
        return len(self.segments)

    def segment_times(self) -> list[tuple[float, float]]:
        """``(t_first, t_last)`` of each segment, s."""
        return [(float(self.t[a]), float(self.t[b - 1])) for a, b in self.segments]


def _continuous_quaternions(q: np.ndarray) -> np.ndarray:
    """Flip signs so consecutive quaternions agree (vectorised; same rule as
    :func:`cdprid.model.quat_continuity`)."""
    q = np.asarray(q, float)
    if len(q) < 2:
        return q.copy()
    flips = np.where(np.einsum("ij,ij->i", q[1:], q[:-1]) < 0, -1.0, 1.0)
    sign = np.concatenate([[1.0], np.cumprod(flips)])
    return q * sign[:, None]


def _runs(mask: np.ndarray, breaks: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index runs where ``mask`` is True, also cut before every index in ``breaks``."""
    edge = np.zeros(len(mask) + 1, bool)
    edge[breaks] = True
    runs, start = [], None
    for k in np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])) != 0):
        if start is None:
            start = int(k)
        else:
            runs.append((start, int(k)))
            start = None
    out = []
    for a, b in runs:
        cuts = [a, *(int(c) for c in np.flatnonzero(edge[a + 1:b]) + a + 1), b]
        out += [(c0, c1) for c0, c1 in zip(cuts[:-1], cuts[1:], strict=False)]
    return out


def _fmt_s(x: float) -> str:
    return f"{x:.4g} s" if x < 120 else f"{x / 60:.3g} min"


def _tension_coverage(t: np.ndarray, tt: np.ndarray, dt: float) -> tuple[np.ndarray, list]:
    """Pose samples where tensions were measured (inside the stream's range, not in its gaps)."""
    notes = []
    n_all = len(t)
    keep = (t >= tt[0] - 1e-9) & (t <= tt[-1] + 1e-9)
    lost_range = int(n_all - keep.sum())
    if lost_range:
        notes.append(
            f"tensions cover only [{tt[0]:g}, {tt[-1]:g}] s of the pose stream "
            f"[{t[0]:g}, {t[-1]:g}] s: {100 * lost_range / n_all:.1f} % of the pose samples "
            "dropped (never extrapolated)"
        )
    lost_tgap = 0
    if len(tt) > 2:
        dtt = np.diff(tt)
        big = np.flatnonzero(dtt > GAP_FACTOR * max(float(np.median(dtt)), dt))
        if big.size:
            k = np.searchsorted(tt, t, side="right") - 1  # tension interval of each pose sample
            inside = np.isin(k, big) & (t > tt[np.clip(k, 0, len(tt) - 1)] + 1e-9)
            lost_tgap = int((inside & keep).sum())
            keep &= ~inside
            worst = int(big[np.argmax(dtt[big])])
            notes.append(
                f"tension stream has {big.size} gap(s) (largest {_fmt_s(dtt[worst])} at "
                f"t = {tt[worst]:g} s): {lost_tgap} pose samples inside them dropped, never "
                "interpolated"
            )
    return keep, notes


def _segment_arrays(ds: Dataset, runs, dt: float):
    """Per gap-free segment: uniform times (jitter resampled), pose, quaternions, tensions."""
    t, tt = ds.pose_t, ds.tension_t
    q_all = ds.quaternion if ds.quaternion is not None else None
    parts, segs, n0, resampled, worst_jit = [], [], 0, False, 0.0
    for a, b in runs:
        ts, ps = t[a:b], ds.position[a:b]
        qs = (_continuous_quaternions(q_all[a:b]) if q_all is not None
              else np.tile([1.0, 0.0, 0.0, 0.0], (b - a, 1)))
        jit = float(np.max(np.abs(np.diff(ts) - dt)) / dt)
        if jit > 0.01:
            from scipy.interpolate import CubicSpline

            tu = ts[0] + dt * np.arange(int(np.floor((ts[-1] - ts[0]) / dt + 1e-9)) + 1)
            ps = CubicSpline(ts, ps, axis=0)(tu)
            if q_all is not None:
                qs = CubicSpline(ts, qs, axis=0)(tu)
                qs = qs / np.linalg.norm(qs, axis=1, keepdims=True)
            else:
                qs = np.tile([1.0, 0.0, 0.0, 0.0], (len(tu), 1))
            ts, resampled, worst_jit = tu, True, max(worst_jit, jit)
        tau = np.empty((len(ts), ds.tension.shape[1]))
        for i in range(ds.tension.shape[1]):
            tau[:, i] = np.interp(ts, tt, ds.tension[:, i])
        parts.append((ts, ps, qs, tau))
        segs.append((n0, n0 + len(ts)))
        n0 += len(ts)
    return parts, segs, resampled, worst_jit


def align(ds: Dataset, t_start: float | None = None, t_end: float | None = None,
          split_gaps: bool = False) -> AlignedSignals:
    """Put pose and tensions on the pose time base without inventing samples.

    Parameters
    ----------
    ds : Dataset
    t_start, t_end : float, optional
        Keep only ``t_start <= t <= t_end``.
    split_gaps : bool
        How a recording with gaps is returned. False (for callers that differentiate the
        whole signal at once): only the longest gap-free segment, the others dropped and
        reported. True: every segment of at least :data:`MIN_SEGMENT_SAMPLES` samples, listed in
        ``segments``; the caller must differentiate them separately
        (:func:`cdprid.core.estimate_motion` does) and trim their edges like the ends
        (:func:`cdprid.core.segment_mask`).

    Returns
    -------
    AlignedSignals

    Raises
    ------
    DatasetError
        Fewer than 10 usable samples in the window, or a platform that does not move.
    """
    t = ds.pose_t
    n_all = len(t)
    rep = sampling_report(t)
    dt = rep["dt"] if np.isfinite(rep["dt"]) else 1.0
    tt = ds.tension_t
    keep, notes = _tension_coverage(t, tt, dt)
    lo = -np.inf if t_start is None else t_start
    hi = np.inf if t_end is None else t_end
    keep &= (t >= lo - 1e-12) & (t <= hi + 1e-12)
    # 2. gap-free segments of the pose stream
    d = np.diff(t)
    gaps = np.flatnonzero(d > GAP_FACTOR * dt) + 1
    if gaps.size:
        worst = int(gaps[np.argmax(d[gaps - 1])])
        notes.append(
            f"pose stream has {gaps.size} gap(s) longer than {GAP_FACTOR:g} sample periods "
            f"(largest {_fmt_s(d[worst - 1])} at t = {t[worst - 1]:g} s); segments are "
            "differentiated separately and never bridged"
        )
    runs = _runs(keep, gaps)
    short = [r for r in runs if r[1] - r[0] < MIN_SEGMENT_SAMPLES]
    runs = [r for r in runs if r[1] - r[0] >= MIN_SEGMENT_SAMPLES]
    if short:
        notes.append(f"{len(short)} segment(s) shorter than {MIN_SEGMENT_SAMPLES} samples "
                     f"({sum(b - a for a, b in short)} samples) dropped: too short to "
                     "differentiate")
    if not runs or sum(b - a for a, b in runs) < 10:
        raise DatasetError(
            f"{ds.path}: fewer than {MIN_SEGMENT_SAMPLES} gap-free pose samples lie in the "
            f"selected time window [{max(lo, tt[0]):g}, {min(hi, tt[-1]):g}] s where tensions "
            "are also available."
        )
    if len(runs) > 1 and not split_gaps:
        best = max(runs, key=lambda r: t[r[1] - 1] - t[r[0]])
        used = best[1] - best[0]
        notes.append(
            f"using the longest gap-free segment [{t[best[0]]:g}, {t[best[1] - 1]:g}] s "
            f"({used} samples, {100 * used / n_all:.1f} % of the pose stream); "
            f"{len(runs) - 1} other segment(s) dropped"
        )
        runs = [best]
    elif len(runs) > 1:
        notes.append(
            f"{len(runs)} gap-free segments used: " + ", ".join(
                f"[{t[a]:g}, {t[b - 1]:g}] s" for a, b in runs[:6]) + (" ..." if len(runs) > 6
                                                                      else "")
        )
    parts, segs, resampled, worst_jit = _segment_arrays(ds, runs, dt)
    if resampled:
        notes.append(
            f"pose sampling is not uniform (max jitter {100 * worst_jit:.1f} % of the median "
            f"period {dt:.4g} s, below the {GAP_FACTOR:g}-period gap limit); resampled onto a "
            "uniform grid by cubic spline within each segment"
        )
    if len(parts) == 1:
        t_o, p_o, q_o, tau_o = parts[0]
    else:
        t_o, p_o, q_o, tau_o = (np.concatenate([pp[k] for pp in parts]) for k in range(4))
    if not np.array_equal(tt, ds.pose_t):
        notes.append("tensions linearly interpolated onto the pose time base")
    notes += _plausibility_notes(ds, p_o, q_o, tau_o)
    return AlignedSignals(t_o, float(dt), p_o, q_o, tau_o, ds.quaternion is not None, resampled,
                          tuple(notes), tuple(segs))


def _plausibility_notes(ds: Dataset, pos: np.ndarray, q: np.ndarray, tau: np.ndarray) -> list:
    """Refuse a platform that does not move; warn on dead or partly negative cables."""
    span = float(np.max(np.ptp(pos, axis=0)))
    rot = float(2 * np.arccos(np.clip(np.min(np.abs(q @ q[0])), -1, 1)))
    if span < STATIONARY_RANGE_M and rot < STATIONARY_RANGE_RAD:
        raise DatasetError(
            f"{ds.path}: the platform does not move in the selected window (position range "
            f"{span:.3g} m, rotation range {rot:.3g} rad); no dynamic parameter can be identified "
            "from a stationary record."
        )
    notes = []
    dead = [i + 1 for i in range(tau.shape[1]) if not np.any(tau[:, i])]
    if dead:
        notes.append(f"warning: tension of cable(s) {', '.join(map(str, dead))} is zero "
                     "throughout: a dead load cell or a slack cable")
    share = float(np.mean(tau < NEGATIVE_TENSION_N))
    if share > 0.01:
        notes.append(f"warning: {100 * share:.1f} % of the tension samples are below "
                     f"{NEGATIVE_TENSION_N:g} N (cables only pull): check the load-cell offsets")
    return notes


def _write_csv(path: Path, columns: list[str], values: np.ndarray) -> None:
    values = np.asarray(values, float)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(columns) + "\n")
        np.savetxt(fh, values, delimiter=",", fmt="%.17g")


def write_dataset(
    path: str | Path,
    robot: CableRobot,
    pose_t,
    position,
    tension_t,
    tension,
    quaternion=None,
    meta: dict | None = None,
    extra: dict | None = None,
    overwrite: bool = False,
) -> Path:
    """Write a spec-v1 dataset folder, whole or not at all.

    The folder is built under a temporary name beside ``path`` and renamed into place when
    every file is complete (:func:`cdprid.base.atomic_dir`): an interrupted or failed write
    leaves ``path`` as it was and no partial dataset that parses.

    Parameters
    ----------
    path : folder to create
    robot : CableRobot
    pose_t, position, tension_t, tension, quaternion
        Streams as in :class:`Dataset`.
    meta : dict, optional
        Written to meta.toml.
    extra : dict, optional
        ``name -> (columns, values)`` further streams (first column ``t``).
    overwrite : bool
        Replace an existing non-empty folder (as a whole); refused otherwise.

    Returns
    -------
    Path

    Raises
    ------
    OutputError
        ``path`` exists (non-empty, without ``overwrite``), is a file, or its folder cannot be
        written (:class:`~cdprid.base.OutputExistsError`, also a ``FileExistsError``, for the
        first).
    """
    import tomli_w

    from cdprid.base._outputs import atomic_dir
    from cdprid.model._geometry import robot_to_dict

    root = Path(path)
    if root.exists() and not root.is_dir():
        raise OutputError(f"{root}: is a file, expected a dataset folder name.")
    if root.exists() and not overwrite and any(root.iterdir()):
        files = ["robot.toml", "pose.csv", "tensions.csv", "meta.toml"]
        clash = [f for f in files if (root / f).exists()] or ["other files"]
        raise OutputExistsError(
            f"{root}: already holds {', '.join(clash)}; refusing to overwrite (use --force)."
        )
    with atomic_dir(root, force=True) as tmp:
        with open(tmp / "robot.toml", "wb") as fh:
            tomli_w.dump(robot_to_dict(robot), fh)
        pose_cols = ["t", "x", "y", "z"]
        pose_vals = [np.asarray(pose_t)[:, None], np.asarray(position)]
        if quaternion is not None:
            pose_cols += list(QUAT_COLS)
            pose_vals.append(np.asarray(quaternion))
        _write_csv(tmp / "pose.csv", pose_cols, np.hstack(pose_vals))
        m = np.asarray(tension).shape[1]
        _write_csv(tmp / "tensions.csv", ["t"] + [f"tau_{i}" for i in range(1, m + 1)],
                   np.hstack([np.asarray(tension_t)[:, None], np.asarray(tension)]))
        if meta:
            with open(tmp / "meta.toml", "wb") as fh:
                tomli_w.dump(_toml_clean(meta), fh)
        for name, (cols, vals) in (extra or {}).items():
            _write_csv(tmp / f"{name}.csv", list(cols), vals)
        tmp.chmod(0o777 & ~_umask())
    return root


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _toml_clean(obj):
    """Convert numpy scalars/arrays to plain Python for tomli_w."""
    if isinstance(obj, dict):
        return {str(k): _toml_clean(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, (list, tuple)):
        return [_toml_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _toml_clean(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj
