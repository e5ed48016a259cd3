"""Spec-v1 datasets (see ``../shared/spec/dataset-format.md``): read, validate, align, write.

Every validation failure raises :class:`DatasetError` whose message is one sentence naming
the file, the line or column, and what is wrong; the CLI prints it and exits with code 2.

Alignment (:func:`align`): the pose stream is the master time base. Tensions are linearly
interpolated onto the pose times; pose samples outside the tension stream's time range are
dropped (no extrapolation). A pose stream whose sampling is not uniform (jitter above 1 % of
the median period) is reported and resampled onto a uniform grid by a cubic spline, since
every differentiator assumes a constant step.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np

from ..geometry import CableRobot, RobotFileError, load_robot, robot_to_dict

__all__ = ["Dataset", "DatasetError", "AlignedSignals", "read_dataset", "write_dataset", "align",
           "sampling_report", "read_csv_stream"]

QUAT_COLS = ("qw", "qx", "qy", "qz")


class DatasetError(ValueError):
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


def read_csv_stream(path: Path, required: tuple[str, ...] = ("t",)) -> tuple[list[str], np.ndarray]:
    """Read a CSV stream (one header line, numeric rows) with spec-v1 error messages.

    Returns
    -------
    columns : list of str
    values : ndarray (n, len(columns))
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: required file is missing.")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not valid UTF-8 text.") from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise DatasetError(f"{path}: the file is empty (no header line).")
    columns = [c.strip() for c in lines[0].split(",")]
    for c in required:
        if c not in columns:
            raise DatasetError(f"{path}: line 1 (header) lacks the required column '{c}'.")
    if len(set(columns)) != len(columns):
        raise DatasetError(f"{path}: line 1 (header) has duplicate column names.")
    ncol = len(columns)
    rows = []
    for lineno, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.split(",")
        if len(fields) != ncol:
            raise DatasetError(
                f"{path}: line {lineno} has {len(fields)} fields but the header has {ncol}."
            )
        row = []
        for col, f in zip(columns, fields):
            f = f.strip()
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
    if not rows:
        raise DatasetError(f"{path}: the stream is empty (a header but no data rows).")
    values = np.asarray(rows, dtype=float)
    t = values[:, columns.index("t")]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if bad.size:
        k = int(bad[0])
        # data row k+1 (0-based) is file line k+3 when no blank lines precede it
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
        missing = [c for c, h in zip(QUAT_COLS, has_q) if not h][0]
        raise DatasetError(
            f"{root / 'pose.csv'}: line 1 (header) has some quaternion columns but lacks '{missing}'"
            " (qw, qx, qy, qz go together)."
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
                f"{root / 'tensions.csv'}: line 1 (header) lacks the column '{c}' for cable {i + 1}."
            )
    tidx = {c: i for i, c in enumerate(tcols)}
    tension_t = tens[:, tidx["t"]]
    tension = tens[:, [tidx[c] for c in expected]]
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
    """Pose and tensions on one uniform time base.

    Attributes
    ----------
    t : ndarray (n,)
    dt : float
    position : ndarray (n, 3)
    quaternion : ndarray (n, 4)
        Sign-continuous unit quaternions (identity when the dataset has none).
    tension : ndarray (n, m)
    has_rotation : bool
        Whether the dataset carried quaternions.
    resampled : bool
        True when the pose stream was not uniform and was resampled.
    notes : tuple of str
        Human-readable notes on what alignment did.
    """

    t: np.ndarray
    dt: float
    position: np.ndarray
    quaternion: np.ndarray
    tension: np.ndarray
    has_rotation: bool
    resampled: bool
    notes: tuple = ()


def align(ds: Dataset, t_start: float | None = None, t_end: float | None = None) -> AlignedSignals:
    """Put pose and tensions on the pose time base (see module docstring).

    Parameters
    ----------
    ds : Dataset
    t_start, t_end : float, optional
        Keep only ``t_start <= t <= t_end``.
    """
    from ..rotations import quat_continuity

    notes = []
    t = ds.pose_t
    pos = ds.position
    q = ds.quaternion if ds.quaternion is not None else np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    q = quat_continuity(q)
    rep = sampling_report(t)
    resampled = False
    if not rep["uniform"]:
        from scipy.interpolate import CubicSpline

        tu = np.arange(t[0], t[-1] + 0.5 * rep["dt"], rep["dt"])
        tu = tu[tu <= t[-1]]
        pos = CubicSpline(t, pos, axis=0)(tu)
        q = CubicSpline(t, q, axis=0)(tu)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        notes.append(
            f"pose sampling is not uniform (max jitter {100 * rep['max_jitter']:.1f} % of the "
            f"median period {rep['dt']:.4g} s); resampled onto a uniform grid by cubic spline"
        )
        t = tu
        resampled = True
    lo = max(ds.tension_t[0], -np.inf if t_start is None else t_start)
    hi = min(ds.tension_t[-1], np.inf if t_end is None else t_end)
    keep = (t >= lo - 1e-12) & (t <= hi + 1e-12)
    if keep.sum() < 10:
        raise DatasetError(
            f"{ds.path}: fewer than 10 pose samples lie in the selected time window "
            f"[{lo:g}, {hi:g}] s where tensions are also available."
        )
    t, pos, q = t[keep], pos[keep], q[keep]
    tau = np.column_stack([np.interp(t, ds.tension_t, ds.tension[:, i])
                           for i in range(ds.tension.shape[1])])
    if not np.array_equal(ds.tension_t, ds.pose_t):
        notes.append("tensions linearly interpolated onto the pose time base")
    return AlignedSignals(t, float(np.median(np.diff(t))), pos, q, tau,
                          ds.quaternion is not None, resampled, tuple(notes))


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
    """Write a spec-v1 dataset folder.

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
        Existing dataset files are never overwritten unless this is True.
    """
    import tomli_w

    root = Path(path)
    files = ["robot.toml", "pose.csv", "tensions.csv", "meta.toml"]
    if root.exists() and not overwrite:
        clash = [f for f in files if (root / f).exists()]
        if clash:
            raise FileExistsError(
                f"{root}: already holds {', '.join(clash)}; refusing to overwrite (use --force)."
            )
    root.mkdir(parents=True, exist_ok=True)
    with open(root / "robot.toml", "wb") as fh:
        tomli_w.dump(robot_to_dict(robot), fh)
    pose_cols = ["t", "x", "y", "z"]
    pose_vals = [np.asarray(pose_t)[:, None], np.asarray(position)]
    if quaternion is not None:
        pose_cols += list(QUAT_COLS)
        pose_vals.append(np.asarray(quaternion))
    _write_csv(root / "pose.csv", pose_cols, np.hstack(pose_vals))
    m = np.asarray(tension).shape[1]
    _write_csv(root / "tensions.csv", ["t"] + [f"tau_{i}" for i in range(1, m + 1)],
               np.hstack([np.asarray(tension_t)[:, None], np.asarray(tension)]))
    if meta:
        with open(root / "meta.toml", "wb") as fh:
            tomli_w.dump(_toml_clean(meta), fh)
    for name, (cols, vals) in (extra or {}).items():
        _write_csv(root / f"{name}.csv", list(cols), vals)
    return root


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
