"""White-noise level of sampled signals (one estimator for the diagnosis and the tuning)."""

from __future__ import annotations

import math

import numpy as np


def estimate_noise(x, order: int = 4) -> np.ndarray:
    """White-noise standard deviation of each column of a smooth signal plus noise.

    The ``order``-th difference of white noise of variance s^2 has variance
    ``C(2 order, order) s^2`` while a smooth signal's is negligible at 100 Hz; a median
    absolute deviation keeps it robust.

    Parameters
    ----------
    x : array_like (n,) or (n, k)
        Uniformly sampled signal(s), time first (any unit U).
    order : int
        Order of the differences.

    Returns
    -------
    ndarray () or (k,)
        Noise std per column, U.
    """
    x = np.asarray(x, float)
    d = np.diff(x, n=order, axis=0)
    c = math.comb(2 * order, order)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) * 1.4826
    return mad / math.sqrt(c)
