"""The energy balance, a second test independent of the wrench residual, for locked winches.

When every cable keeps its length (the winches are locked: the geometric lengths from the
poses vary by less than :data:`LOCKED_RANGE_M`), a taut cable pulls along itself while its
attachment moves on a sphere about its exit point: it does no work. The platform's mechanical
energy (the fitted rigid body: mass, first moment and inertia about P)

    E = 1/2 m |v|^2 + v . (omega x R m s) + 1/2 omega_P^T I_P omega_P - g . (m p + R m s)

can then rise only by outside work (friction and drag take energy away). Its trend (a
moving mean over :data:`TREND_S`, which averages out most of the exchange between kinetic
and potential energy
within a swing) rises at a rate whose null spread comes from the recording itself (see
:func:`energy_runs`); a stretch of at least :data:`MIN_S` where it rises beyond the
threshold of the stated false-alarm rate (one window per ``TREND_S``) is an episode of kind
``energy``; its size is the work done, J.
"""

from __future__ import annotations

import numpy as np
from scipy import stats
from scipy.ndimage import uniform_filter1d

from cdprid.episodes._scan import runs

__all__ = ["LOCKED_RANGE_M", "TREND_S", "MIN_S", "locked", "energy_runs"]

#: winches locked: every geometric cable length stays within this range (1-99 %), m (a
#: calibration error moves them by millimetres on a swinging platform, a winch by decimetres)
LOCKED_RANGE_M = 2e-2
#: window of the energy trend, s
TREND_S = 2.0
#: shortest energy episode above the threshold, s (the trend is already a 2 s mean)
MIN_S = 0.1


def locked(lengths: np.ndarray, use: np.ndarray) -> bool:
    """Whether the cable lengths ``(n, m)`` (m) stay constant on the samples ``use``."""
    x = np.asarray(lengths, float)[use]
    if len(x) < 10:
        return False
    lo, hi = np.percentile(x, [1, 99], axis=0)
    return bool(np.all(hi - lo < LOCKED_RANGE_M))


def mechanical_energy(beta, model: str, v, om, R, p, gravity) -> np.ndarray:
    """The platform's mechanical energy (n,), J, from the fitted parameters ``beta``."""
    m, ms = float(beta[0]), np.asarray(beta[1:4], float)
    Rms = np.einsum("nij,j->ni", R, ms)
    E = 0.5 * m * np.sum(v * v, 1) + np.sum(v * np.cross(om, Rms), 1)
    if model == "full":
        Ixx, Ixy, Ixz, Iyy, Iyz, Izz = (float(x) for x in beta[4:10])
        I_P = np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
        wP = np.einsum("nji,nj->ni", R, om)
        E = E + 0.5 * np.einsum("ni,ij,nj->n", wP, I_P, wP)
    return E - (m * p + Rms) @ np.asarray(gravity, float)


def energy_runs(t, E, use, exclude, far_per_hour: float):
    """Stretches of outside work: ``[(a, b, work J, p-value)]`` (half-open sample ranges).

    One-sided: a passive platform on locked cables can only lose energy, so a rise is
    tested. The rate's null spread is the robust std (MAD) of its part faster than the
    trend (the rate minus its own moving mean over :data:`TREND_S`) on the samples outside
    ``exclude``; a stretch whose rate exceeds the threshold for at least :data:`MIN_S` is
    widened to where the rate stays positive (the whole rise).

    Parameters
    ----------
    t : ndarray (n,)
        Times, s (uniform within the used samples).
    E : ndarray (n,)
        Mechanical energy, J.
    use : ndarray (n,) of bool
        Samples of the test.
    exclude : ndarray (n,) of bool
        Samples left out of the null spread (episodes already found).
    far_per_hour : float
        False alarms per hour on a clean recording.
    """
    dt = float(np.median(np.diff(t)))
    k = max(1, int(round(TREND_S / dt)))
    trend = uniform_filter1d(E, k, mode="nearest")
    rate = np.gradient(trend, dt)
    hp = rate - uniform_filter1d(rate, k, mode="nearest")
    ref = use & ~exclude
    if ref.sum() < 2 * k:
        return []
    scale = max(1.4826 * float(np.median(np.abs(hp[ref] - np.median(hp[ref])))), 1e-12)
    n_windows = max(1.0, (t[-1] - t[0]) / TREND_S)
    z_thr = float(stats.norm.isf(far_per_hour * TREND_S / 3600.0))
    found = []
    rising = runs((rate > 0) & use)
    for a, b in runs((rate > z_thr * scale) & use):
        if t[b - 1] - t[a] < MIN_S:
            continue
        a, b = next(((a2, b2) for a2, b2 in rising if a2 <= a and b2 >= b), (a, b))
        work = float(trend[b - 1] - trend[a])
        zmax = float(np.max(rate[a:b]) / scale)
        p = float(min(1.0, stats.norm.sf(zmax) * n_windows))
        found.append((a, b, work, p))
    return found
