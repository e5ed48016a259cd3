"""Trajectory CSV files: the 100 Hz samples ``cdprid excite`` writes and ``cdprid simulate
--trajectory`` reads (columns :data:`cdprid.model.POSITION_COLUMNS` and, with rotation,
:data:`cdprid.model.ROTATION_COLUMNS`)."""

from __future__ import annotations

from pathlib import Path

import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.io._dataset import read_csv_stream
from cdprid.model import POSITION_COLUMNS, ROTATION_COLUMNS, SampledTrajectory


def save_trajectory_csv(
    traj, path, rate_hz: float = 100.0, t=None, overwrite: bool = False
) -> Path:
    """Write a trajectory as CSV (columns of the module docstring).

    Parameters
    ----------
    traj : Trajectory or SampledTrajectory
    path : str or Path
    rate_hz : float
        Sampling rate when ``t`` is not given (samples from ``t_start`` to ``t_end``).
    t : array (n,), optional
        Sample times.
    overwrite : bool
        Refuse to replace an existing file unless True.

    Returns
    -------
    Path
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise FileExistsError(f"{path}: already exists; refusing to overwrite (use --force).")
    if t is None:
        n = int(np.floor((traj.t_end - traj.t_start) * rate_hz + 1e-9)) + 1
        t = traj.t_start + np.arange(n) / rate_hz
    s = traj.evaluate(np.asarray(t, float))
    cols = list(POSITION_COLUMNS)
    vals = [np.asarray(s.t)[:, None], np.asarray(s.p), np.asarray(s.v), np.asarray(s.a)]
    if traj.has_rotation:
        cols += list(ROTATION_COLUMNS)
        vals += [np.asarray(s.q), np.asarray(s.omega), np.asarray(s.alpha)]
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(",".join(cols) + "\n")
        np.savetxt(fh, np.hstack(vals), delimiter=",", fmt="%.17g")
    return path


def load_trajectory_csv(path) -> SampledTrajectory:
    """Read a trajectory CSV written by :func:`save_trajectory_csv` (or by hand).

    Parameters
    ----------
    path : path-like
        The CSV: ``t`` (s), position (m), optionally a quaternion and rates (module docstring).

    Returns
    -------
    SampledTrajectory
        Interpolating the samples (quintic Hermite).

    Raises
    ------
    InputError
        One sentence naming the file and what is wrong (a missing column, too few rows...).
    """
    path = Path(path)
    cols, vals = read_csv_stream(path, required=POSITION_COLUMNS)
    if vals.shape[0] < 2:
        raise InputError(f"{path}: a trajectory needs at least 2 samples, found {vals.shape[0]}.")
    idx = {c: i for i, c in enumerate(cols)}

    def block(names):
        return jnp.asarray(vals[:, [idx[c] for c in names]])

    present = [c in idx for c in ROTATION_COLUMNS]
    if any(present) and not all(present):
        missing = [c for c, h in zip(ROTATION_COLUMNS, present, strict=True) if not h]
        raise InputError(
            f"{path}: line 1 (header) has some rotation columns but lacks {', '.join(missing)} "
            f"(the columns {', '.join(ROTATION_COLUMNS)} go together)."
        )
    q = w = al = None
    if all(present):
        q = np.asarray(block(ROTATION_COLUMNS[:4]))
        nrm = np.linalg.norm(q, axis=1)
        if np.any(np.abs(nrm - 1) > 1e-3):
            k = int(np.nonzero(np.abs(nrm - 1) > 1e-3)[0][0])
            raise InputError(
                f"{path}: data row {k + 1} has a quaternion of norm {nrm[k]:.6g}, not 1."
            )
        q = jnp.asarray(q / nrm[:, None])
        w, al = block(ROTATION_COLUMNS[4:7]), block(ROTATION_COLUMNS[7:10])
    return SampledTrajectory(
        t=block(["t"])[:, 0],
        p=block(["x", "y", "z"]),
        v=block(["vx", "vy", "vz"]),
        a=block(["ax", "ay", "az"]),
        q=q,
        omega=w,
        alpha=al,
        name=path.stem,
    )
