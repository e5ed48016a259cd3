"""Pose glitches: a few marker samples displaced far from the motion, found robustly.

A glitch is a sample whose position departs from the running median of its neighbours
(:data:`WINDOW` samples, so a burst of up to ``WINDOW // 2`` displaced samples does not move
the median) by more than :data:`GLITCH_SIGMAS` robust standard deviations of that
innovation and by at least :data:`GLITCH_MIN_M`. The median of a monotone stretch is its
centre sample, so smooth motion gives no innovation except near a turning point, where it is
at most ``|a| (WINDOW dt / 2)^2 / 2`` (1.6 mm at 2 m/s^2 and 100 Hz): the floor keeps those
out. A glitch's samples are excluded from every fit with the differentiator's transient on
both sides (the caller's margin); nothing is interpolated.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import median_filter

__all__ = ["GLITCH_MIN_M", "GLITCH_SIGMAS", "WINDOW", "find_glitches", "add_glitches"]

#: running-median window, samples
WINDOW = 9
#: a glitch departs from the running median by more than this many robust std
GLITCH_SIGMAS = 10.0
#: ... and by at least this much, m (far above motion-capture noise and the median's bias)
GLITCH_MIN_M = 5e-3


def find_glitches(position: np.ndarray, segments=None) -> tuple[np.ndarray, np.ndarray]:
    """Samples of ``position`` (n, 3) that are pose glitches, and their displacement.

    Parameters
    ----------
    position : ndarray (n, 3)
        Measured positions, m.
    segments : sequence of (int, int), optional
        Gap-free segments (each filtered on its own); default the whole array.

    Returns
    -------
    glitch : ndarray (n,) of bool
    size : ndarray (n,)
        Distance from the running median, m.
    """
    x = np.asarray(position, float)
    n = len(x)
    segments = segments or ((0, n),)
    dev = np.zeros((n, 3))
    for a, b in segments:
        if b - a >= WINDOW:
            dev[a:b] = x[a:b] - median_filter(x[a:b], size=(WINDOW, 1), mode="nearest")
    size = np.linalg.norm(dev, axis=1)
    mad = 1.4826 * np.median(np.abs(dev - np.median(dev, 0)), 0)
    limit = np.maximum(GLITCH_SIGMAS * mad, GLITCH_MIN_M)
    glitch = np.any(np.abs(dev) > limit[None, :], axis=1)
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
