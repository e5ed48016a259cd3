"""Sample budget of the diagnosis: bounded memory on long recordings.

The diagnosis holds per-sample Jacobians of every candidate effect (about 50 kB per pose
sample, measured on a 10 min 100 Hz recording: 3.55 GB peak for 60 000 samples). Above
:data:`MAX_SAMPLES` pose samples it analyses a documented subset: ``n_blocks`` evenly spaced
contiguous time blocks that together hold :data:`MAX_SAMPLES` samples and span the whole
recording. The blocks are put end to end on a continuous time axis (each block keeps its own
pose and tension samples, shifted in time; nothing is interpolated across a join; the
recording's own clock, on which time-dependent effects are evaluated, is kept:
:meth:`Subset.clock`), and the
samples within ``margin_s`` of a join are excluded from every fit and test (filter and
differentiator transients), like the trimmed ends of a recording. :func:`subset` returns the
shortened dataset, the join times and a note that the CLI, the JSON and the report print.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.io import Dataset

#: Pose samples the diagnosis analyses at most (about 2.5 GB peak; see results/benchmarks.md).
MAX_SAMPLES: int = 36_000
#: Number of evenly spaced blocks when a recording is above the budget.
N_BLOCKS: int = 10


@dataclasses.dataclass(frozen=True)
class Subset:
    """The analysed part of a recording that is above the sample budget."""

    dataset: Dataset
    joins: tuple  # times (s, on the new axis) where two blocks meet
    windows: tuple  # (start, end) of each block in the original recording's time (s)
    n_samples_total: int
    n_samples_used: int
    note: str
    #: the original recording's first tension time stamp (the clock's zero), s
    t0: float = 0.0
    #: per block: the shift added to its time stamps on the joined axis, s
    shifts: tuple = ()

    def clock(self, t_joined) -> np.ndarray:
        """The recording's own clock at joined-axis times, s from its first tension stamp.

        Each block keeps its real time stamps: a joined time inside block k is the original
        time ``t - shift_k`` (one clock for every time-dependent effect and the delay).
        """
        t = np.asarray(t_joined, float)
        starts = np.array([a + sh for (a, _), sh in zip(self.windows, self.shifts, strict=True)])
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
        return t - np.asarray(self.shifts)[k] - self.t0

    def as_json(self) -> dict:
        """The ``info["subset"]`` entry of the diagnosis JSON."""
        return {"n_samples_total": self.n_samples_total,
                "n_samples_analysed": self.n_samples_used,
                "windows_s": [[float(a), float(b)] for a, b in self.windows],
                "note": self.note}


def subset(ds: Dataset, max_samples: int = MAX_SAMPLES, n_blocks: int = N_BLOCKS,
           margin_s: float = 1.0, min_block_s: float = 20.0) -> Subset | None:
    """Evenly spaced contiguous blocks of ``ds`` holding ``max_samples`` pose samples.

    Parameters
    ----------
    ds : Dataset
    max_samples : int
        Sample budget; recordings with at most this many pose samples are returned whole
        (the function returns None).
    n_blocks : int
        Number of blocks (evenly spaced, each ``max_samples // n_blocks`` samples), fewer
        when the blocks would be shorter than ``min_block_s``.
    margin_s : float
        Seconds on each side of a join that the diagnosis excludes (reported in the note).
    min_block_s : float
        Shortest block (s).

    Returns
    -------
    Subset or None
        None when the recording is within the budget.
    """
    pt = np.asarray(ds.pose_t, float)
    n = len(pt)
    if n <= max_samples:
        return None
    dt = float(np.median(np.diff(pt)))
    n_blocks = max(1, min(n_blocks, int(max_samples * dt // min_block_s)))
    per = max(1, max_samples // n_blocks)
    starts = np.round(np.linspace(0, n - per, n_blocks)).astype(int)
    pos, quat, ptn, tau, ttn, windows, joins, shifts = [], [], [], [], [], [], [], []
    t_new = float(pt[0])
    for k, s in enumerate(starts):
        a, b = float(pt[s]), float(pt[s + per - 1])
        sl = slice(s, s + per)
        ti = (ds.tension_t >= a) & (ds.tension_t < a + per * dt)
        shift = t_new - a
        if k:
            joins.append(t_new - 0.5 * dt)
        ptn.append(pt[sl] + shift)
        pos.append(ds.position[sl])
        if ds.quaternion is not None:
            quat.append(ds.quaternion[sl])
        ttn.append(ds.tension_t[ti] + shift)
        tau.append(ds.tension[ti])
        windows.append((a, b))
        shifts.append(shift)
        t_new = b + shift + dt
    sub = dataclasses.replace(
        ds, pose_t=np.concatenate(ptn), position=np.concatenate(pos),
        quaternion=np.concatenate(quat) if quat else None,
        tension_t=np.concatenate(ttn), tension=np.concatenate(tau), extra={})
    used = per * n_blocks
    note = (f"recording above the diagnosis's sample budget ({n} pose samples > {max_samples}):"
            f" analysed {n_blocks} evenly spaced contiguous blocks of {per * dt:.4g} s "
            f"({used} samples, {100 * used / n:.1f} % of the recording, from t = "
            f"{windows[0][0]:.4g} s to {windows[-1][1]:.4g} s), put end to end; samples within "
            f"{margin_s:g} s of a join are excluded; times in the arrays and figures are on the "
            "joined axis (time-dependent effects are evaluated on the real time stamps); "
            "held-out blocks are contiguous in the joined record")
    return Subset(sub, tuple(joins), tuple(windows), n, used, note,
                  float(ds.tension_t[0]), tuple(shifts))


def joined_time(sub: Subset, t_original: float) -> float:
    """The joined-axis time of an original time (the start of the next block if between)."""
    pt = np.asarray(sub.dataset.pose_t)
    per = len(pt) // len(sub.windows)
    for k, (a, b) in enumerate(sub.windows):
        if t_original <= b:
            return float(pt[k * per] + max(0.0, t_original - a))
    return float(pt[-1]) + 1.0
