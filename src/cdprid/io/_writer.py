"""Writing spec-v1 datasets: CSV streams and TOML files, written whole or not at all."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cdprid.base import OutputError, OutputExistsError
from cdprid.io._dataset import DATASET_FILES, QUAT_COLS

if TYPE_CHECKING:  # geometry imports JAX
    from cdprid.model import CableRobot


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return json.dumps(v)  # a TOML basic string for every character
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"robot.toml cannot hold a {type(v).__name__}")


def robot_toml(d: dict) -> str:
    """``robot.toml`` text in the spec's layout.

    One field a line, vectors and matrices inline (``exit = [1.065, -1.155, 1.839]``), not one
    number a line as a generic TOML writer does.

    Parameters
    ----------
    d : dict
        The robot mapping (:func:`cdprid.model.robot_to_dict`): scalars, lists, tables and
        arrays of tables (``[[cable]]``).

    Returns
    -------
    str
        The TOML text, ending in a newline.

    Raises
    ------
    TypeError
        A value TOML cannot hold.
    """
    lines = [f"{k} = {_toml_value(v)}" for k, v in d.items() if not isinstance(v, dict | list)
             or (isinstance(v, list) and not (v and isinstance(v[0], dict)))]
    for k, v in d.items():
        if isinstance(v, dict):
            lines += ["", f"[{k}]"] + [f"{a} = {_toml_value(b)}" for a, b in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                lines += ["", f"[[{k}]]"] + [f"{a} = {_toml_value(b)}" for a, b in item.items()]
    return "\n".join(lines) + "\n"


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
    drives: list | None = None,
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
    drives : list of dict, optional
        Per cable, the drive fields of format 1.2 (``drum_radius``, ``gear_ratio``,
        ``torque_constant``, ...) added to its ``[[cable]]`` table. With drives, ``tension``
        may be None: no tensions.csv (a robot without load cells).

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

    from cdprid.base import atomic_dir

    root = Path(path)
    if root.exists() and not root.is_dir():
        raise OutputError(f"{root}: is a file, expected a dataset folder name.")
    if root.exists() and not overwrite and any(root.iterdir()):
        files = ["robot.toml", "pose.csv", "tensions.csv", "meta.toml"]
        clash = [f for f in files if (root / f).exists()] or ["other files"]
        raise OutputExistsError(
            f"{root}: already holds {', '.join(clash)}; refusing to overwrite (use --force)."
        )
    with atomic_dir(root, force=True, owned=DATASET_FILES) as tmp:
        with open(tmp / "robot.toml", "wb") as fh:
            fh.write(_robot_text(robot, drives).encode("utf-8"))
        pose_cols = ["t", "x", "y", "z"]
        pose_vals = [np.asarray(pose_t)[:, None], np.asarray(position)]
        if quaternion is not None:
            pose_cols += list(QUAT_COLS)
            pose_vals.append(np.asarray(quaternion))
        _write_csv(tmp / "pose.csv", pose_cols, np.hstack(pose_vals))
        if tension is not None or not drives:
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


def _robot_text(robot, drives) -> str:
    """robot.toml text, each cable's drive fields (format 1.2) added when given."""
    from cdprid.model import robot_to_dict

    d = robot_to_dict(robot)
    for c, extra_fields in zip(d["cable"], drives or [{}] * len(d["cable"]), strict=True):
        c.update(extra_fields)
    return robot_toml(d)


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
