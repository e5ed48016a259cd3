"""Alignment of a dataset's streams on the pose clock: segments without gaps, tension
coverage, quaternion continuity, plausibility notes."""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.io._dataset import (
    GAP_FACTOR,
    MIN_SEGMENT_SAMPLES,
    NEGATIVE_TENSION_N,
    STATIONARY_RANGE_M,
    STATIONARY_RANGE_RAD,
    Dataset,
    DatasetError,
)


def sampling_report(t, tol: float = 0.01) -> dict:
    """Describe the sampling of a time vector.

    Parameters
    ----------
    t : array (n,)
        Sample times, s.
    tol : float
        Largest relative deviation of a period from the median still called uniform.

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
        """``(t_first, t_last)`` of each gap-free segment.

        Returns
        -------
        list of (float, float)
            First and last sample time of each segment, s.
        """
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


def _gap_free_runs(t: np.ndarray, keep: np.ndarray, dt: float, notes: list) -> list:
    """Gap-free segments of the pose stream among the ``keep`` samples, those shorter than
    :data:`MIN_SEGMENT_SAMPLES` dropped; the gaps and the dropped segments are noted."""
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
    return runs


def _select_runs(t: np.ndarray, runs: list, split_gaps: bool, notes: list) -> list:
    """The segments :func:`align` returns: all of them with ``split_gaps``, else the longest
    (in time); the choice is noted."""
    n_all = len(t)
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
    return runs


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
    rep = sampling_report(t)
    dt = rep["dt"] if np.isfinite(rep["dt"]) else 1.0
    tt = ds.tension_t
    keep, notes = _tension_coverage(t, tt, dt)
    lo = -np.inf if t_start is None else t_start
    hi = np.inf if t_end is None else t_end
    keep &= (t >= lo - 1e-12) & (t <= hi + 1e-12)
    runs = _gap_free_runs(t, keep, dt, notes)
    if not runs or sum(b - a for a, b in runs) < 10:
        raise DatasetError(
            f"{ds.path}: fewer than {MIN_SEGMENT_SAMPLES} gap-free pose samples lie in the "
            f"selected time window [{max(lo, tt[0]):g}, {min(hi, tt[-1]):g}] s where tensions "
            "are also available."
        )
    runs = _select_runs(t, runs, split_gaps, notes)
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
