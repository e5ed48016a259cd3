"""Pose glitches: a few marker samples displaced far from the motion, found robustly.

Candidates: samples whose second difference ``x_i - (x_{i-1} + x_{i+1}) / 2`` exceeds half
the limit (smooth motion gives ``a dt^2 / 2``, a hundredth of a millimetre at 2 m/s^2 and
100 Hz; a displaced sample gives half its displacement, to it and to its neighbours), with
:data:`SPREAD` samples on each side (the inside of a burst). A candidate is a glitch when it
departs from a cubic fitted to the other samples within :data:`FIT_HALF` on each side (every
candidate left out) by more than the limit: :data:`GLITCH_SIGMAS` robust standard deviations
of the second difference, and at least :data:`GLITCH_MIN_M`. A glitch's samples are excluded
from every fit with the differentiator's transient on both sides (the caller's margin);
nothing is interpolated.

With orientations, a glitch may also (or only) turn the platform: the test then runs on the
positions of three points :data:`LEVER_M` from P along the platform's axes as well (a marker
that far from P moves by the lever times the angle), with the same limits.
"""

from __future__ import annotations

import numpy as np

__all__ = ["GLITCH_MIN_M", "GLITCH_SIGMAS", "LEVER_M", "SPREAD", "find_glitches",
           "add_glitches"]

#: candidates extend this many samples on each side of a large second difference
SPREAD = 2
#: a glitch departs from the local cubic by more than this many robust std
GLITCH_SIGMAS = 10.0
#: ... and by at least this much, m (far above motion-capture noise)
GLITCH_MIN_M = 5e-3
#: half-width of the local cubic that confirms a candidate, samples
FIT_HALF = 12
#: distance from P of the three points whose positions test the orientation, m (a marker on
#: a platform of about half a metre: a 2 deg glitch moves it by 9 mm)
LEVER_M = 0.25


def find_glitches(position: np.ndarray, segments=None,
                  quaternion: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Samples of ``position`` (n, 3) (and ``quaternion``) that are pose glitches, and their
    displacement.

    Parameters
    ----------
    position : ndarray (n, 3)
        Measured positions, m.
    segments : sequence of (int, int), optional
        Gap-free segments (each on its own); default the whole array.
    quaternion : ndarray (n, 4), optional
        Measured orientations ``[qw, qx, qy, qz]``: a sample whose orientation jumps is a
        glitch too (tested on points :data:`LEVER_M` from P along the platform's axes).

    Returns
    -------
    glitch : ndarray (n,) of bool
    size : ndarray (n,)
        Distance of a glitch from the local cubic, m (0 elsewhere): the largest of P's and
        of the three lever points'.
    """
    x = np.asarray(position, float)
    if quaternion is not None:
        from cdprid.core import rotation_matrices

        R = rotation_matrices(np.asarray(quaternion, float))  # columns: the platform's axes
        x = np.concatenate([x, LEVER_M * np.transpose(R, (0, 2, 1)).reshape(len(x), 9)], 1)
    n, d = x.shape
    segments = tuple(segments or ((0, n),))
    c = np.zeros((n, d))
    for a, b in segments:
        if b - a >= 3:
            c[a + 1:b - 1] = x[a + 1:b - 1] - 0.5 * (x[a:b - 2] + x[a + 2:b])
    mad = 1.4826 * np.median(np.abs(c - np.median(c, 0)), 0)
    limit = np.maximum(GLITCH_SIGMAS * mad, GLITCH_MIN_M)
    flag = np.any(np.abs(c) > 0.5 * limit[None, :], axis=1)
    k = np.concatenate([[0], np.cumsum(flag.astype(int))])
    i = np.arange(n)
    candidate = (k[np.minimum(n, i + SPREAD + 1)] - k[np.maximum(0, i - SPREAD)]) > 0
    return _confirmed(x, candidate, limit, segments)


def _confirmed(x, candidate, limit, segments):
    """The candidates confirmed by a local cubic fitted to the other samples within
    :data:`FIT_HALF` on each side (a candidate's neighbours share its second difference)."""
    n = len(x)
    glitch, size = np.zeros(n, bool), np.zeros(n)
    seg_of = np.zeros(n, int)
    for k, (a, b) in enumerate(segments):
        seg_of[a:b] = k
    for i in np.flatnonzero(candidate):
        a, b = segments[seg_of[i]]
        lo, hi = max(a, i - FIT_HALF), min(b, i + FIT_HALF + 1)
        idx = np.arange(lo, hi)
        ref = idx[~candidate[lo:hi]]
        if len(ref) < 8:
            continue
        tt = (ref - i).astype(float)
        coef = np.polyfit(tt, x[ref], 3)
        d = x[i] - coef[-1]  # the cubic at the candidate (tt = 0)
        size[i] = float(np.max(np.linalg.norm(d.reshape(-1, 3), axis=1)))
        glitch[i] = bool(np.any(np.abs(d) > limit))
    return glitch, size


def add_glitches(position: np.ndarray, t: np.ndarray, times_s, displacement_m,
                 n_samples: int = 2) -> np.ndarray:
    """Positions with marker glitches: at each time, ``n_samples`` samples displaced.

    For tests and benchmarks (a marker swapped or reflected for a few frames).

    Parameters
    ----------
    position : ndarray (n, 3)
        Positions, m.
    t : ndarray (n,)
        Their times, s.
    times_s : sequence of float
        When the glitches start, s.
    displacement_m : array (3,) or (k, 3)
        Displacement of the glitched samples, m (one per glitch or one for all).
    n_samples : int
        Consecutive samples displaced per glitch.

    Returns
    -------
    ndarray (n, 3)
    """
    out = np.array(position, float)
    d = np.broadcast_to(np.asarray(displacement_m, float), (len(times_s), 3))
    for ts, dk in zip(times_s, d, strict=True):
        i = int(np.searchsorted(t, ts))
        out[i:i + n_samples] += dk
    return out
