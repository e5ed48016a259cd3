"""The energy balance, a second test independent of the wrench residual, for locked winches.

When every cable keeps its length (the winches are locked: the winch lengths stream, or
without one the geometric lengths from the poses, varies by less than
:data:`LOCKED_RANGE_M`), a taut cable pulls along itself while its
attachment moves on a sphere about its exit point: it does no work. The platform's mechanical
energy (the fitted rigid body: mass, first moment and inertia about P)

    E = 1/2 m |v|^2 + v . (omega x R m s) + 1/2 omega_P^T I_P omega_P - g . (m p + R m s)

can then rise only by outside work (friction and drag take energy away). With a lengths
stream the little the winches still move is booked too: the outside work is ``E`` plus
the work the cables carried away, ``int sum_i tau_i dl_i/dt dt`` (:func:`outside_work`). Its
trend (a
moving mean over :data:`TREND_S`, which averages out most of the exchange between kinetic
and potential energy
within a swing) rises by more than its null spread, which comes from the recording itself
(:func:`energy_runs`), over windows of 1 to 4 s: such a stretch is an episode of kind
``energy``; its size is the work done, J.
"""

from __future__ import annotations

import numpy as np

from cdprid.base import normal_isf, normal_sf
from cdprid.episodes._scan import runs

__all__ = ["LOCKED_RANGE_M", "TREND_S", "MIN_S", "locked", "energy_runs", "braking_runs",
           "passive_loss", "winch_power", "outside_work"]


def _uniform_filter1d(x, k: int, mode: str = "nearest"):
    """:func:`scipy.ndimage.uniform_filter1d`, imported when the energy test runs (locked
    winches only): ``cdprid identify`` on moving winches never pays scipy.ndimage's import."""
    from scipy.ndimage import uniform_filter1d as f

    return f(x, k, mode=mode)


#: winches locked: every geometric cable length stays within this range (1-99 %), m (a
#: calibration error moves them by millimetres on a swinging platform, a winch by decimetres)
LOCKED_RANGE_M = 2e-2
#: window of the energy trend, s
TREND_S = 2.0
#: shortest energy episode, s
MIN_S = 0.3
#: window lengths over which the trend's rise is tested, s
WINDOWS_S = (1.0, 2.0, 4.0)


def locked(lengths: np.ndarray, use: np.ndarray) -> bool:
    """Whether the cable lengths ``(n, m)`` (m) stay constant on the samples ``use``."""
    x = np.asarray(lengths, float)[use]
    if len(x) < 10:
        return False
    lo, hi = np.percentile(x, [1, 99], axis=0)
    return bool(np.all(hi - lo < LOCKED_RANGE_M))


def winch_power(tension, lengths, dt: float) -> np.ndarray:
    """Power the cables carry away from the platform through the winches, ``sum_i tau_i
    dl_i/dt`` (n,), W.

    A cable of reeled length ``l_i`` under tension ``tau_i`` pulls its attachment towards its
    exit; when the winch pays out (``dl_i/dt > 0``) the attachment moves away against that
    pull, so the platform loses ``tau_i dl_i/dt`` (the cable's stretch, below a millimetre
    here, is neglected). With locked winches it is the creep of the encoders times the
    tensions, close to zero.

    Parameters
    ----------
    tension : ndarray (n, m)
        Tensions, N.
    lengths : ndarray (n, m)
        Reeled cable lengths (the winches' encoders) at the same times, m.
    dt : float
        Sampling period, s.

    Returns
    -------
    ndarray (n,)
    """
    rate = np.gradient(np.asarray(lengths, float), dt, axis=0)
    return np.sum(np.asarray(tension, float) * rate, axis=1)


def outside_work(E, power, dt: float) -> np.ndarray:
    """Work done on the platform from outside the robot since the first sample (n,), J: the
    rise of its mechanical energy ``E`` (J) plus what the cables carried away through the
    winches (``power``, :func:`winch_power`, W; trapezoidal integral)."""
    P = np.asarray(power, float)
    carried = np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1])) * dt])
    return np.asarray(E, float) - float(np.asarray(E)[0]) + carried


def mechanical_energy(beta, model: str, v, om, R, p, gravity) -> np.ndarray:
    """The platform's mechanical energy (n,), J, from the fitted parameters ``beta``.

    Parameters
    ----------
    beta : ndarray (4,) or (10,)
        The rigid body's parameters, the paper's order: ``m`` (kg), ``m s_G`` (kg m, platform
        frame) and, for the full model, the inertia about P (kg m^2: Ixx, Ixy, Ixz, Iyy, Iyz,
        Izz).
    model : {"translation", "full"}
        Which parameters ``beta`` holds (``translation``: no rotational energy).
    v : ndarray (n, 3)
        Velocity of P, m/s (base frame).
    om : ndarray (n, 3)
        Angular velocity, rad/s (base frame).
    R : ndarray (n, 3, 3)
        Platform orientation (platform to base).
    p : ndarray (n, 3)
        Position of P, m (base frame).
    gravity : array_like (3,)
        Gravity, m/s^2 (base frame).

    Returns
    -------
    ndarray (n,)
        Kinetic plus potential energy, J (potential zero at the base origin).
    """
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
    tested. The trend's rise over windows of :data:`WINDOWS_S` is compared with its null
    spread, ``sqrt(2)`` times the robust std (MAD) of the trend's part faster than
    :data:`TREND_S` (the exchange left by the mean, measurement noise) on the samples
    outside ``exclude``. Windows beyond the threshold of the stated false-alarm rate
    (Bonferroni over ``2 / L`` windows per second and length) are joined, kept where the
    trend rises, and stretches of at least :data:`MIN_S` are reported.

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

    Returns
    -------
    list of (int, int, float, float)
        ``(a, b, work, p)``: the half-open sample range, the energy's rise over it (J, > 0)
        and its p-value adjusted for the windows tested (Bonferroni).
    """
    dt = float(np.median(np.diff(t)))
    n, k = len(t), max(1, int(round(TREND_S / dt)))
    trend = _uniform_filter1d(E, k, mode="nearest")
    hp = trend - _uniform_filter1d(trend, k, mode="nearest")
    ref = use & ~exclude
    if ref.sum() < 2 * k:
        return []
    scale = max(1.4826 * float(np.median(np.abs(hp[ref] - np.median(hp[ref])))), 1e-12)
    scale *= np.sqrt(2.0)
    n_per_s = sum(2.0 / w for w in WINDOWS_S)
    z_thr = float(normal_isf(far_per_hour / (3600.0 * n_per_s)))
    bad = np.concatenate([[0], np.cumsum(~use)])
    mark, zstart, longest = np.zeros(n + 1, int), np.zeros(n), 1
    for w in WINDOWS_S:
        L = max(1, int(round(w / dt)))
        if L >= n:
            continue
        longest = max(longest, L)
        z = (trend[L:] - trend[:-L]) / scale
        hit = np.flatnonzero((z > z_thr) & ((bad[L + 1:] - bad[:-L - 1]) == 0))
        np.add.at(mark, hit, 1)
        np.add.at(mark, np.minimum(hit + L + 1, n), -1)
        zstart[hit] = np.maximum(zstart[hit], z[hit])
    flagged = np.cumsum(mark)[:n] > 0
    rising = np.gradient(trend, dt) > 0
    found, joined = [], []
    for a, b in runs(flagged & rising & use):  # a rise paused for less than MIN_S is one
        if joined and t[a] - t[joined[-1][1] - 1] < MIN_S:
            joined[-1] = (joined[-1][0], b)
        else:
            joined.append((a, b))
    for a, b in joined:
        if t[b - 1] - t[a] < MIN_S:
            continue
        zmax = float(zstart[max(0, a - longest):b].max())
        p = float(min(1.0, normal_sf(zmax) * n_per_s * (t[-1] - t[0])))
        found.append((a, b, float(trend[b - 1] - trend[a]), p))
    return found


def passive_loss(t, E, speed, ref) -> tuple:
    """The energy a passive platform loses, fitted on the samples ``ref``: ``(lost (n,) J,
    coefficients)``. On locked winches the swing loses energy to friction that does not grow
    with speed (joints, the cables' bending over their pulleys: power ``d |v|``) and to
    viscous drag (``c |v|^2``); both coefficients are passive (>= 0, non-negative least
    squares of the trend's rate on the speeds' trends over :data:`TREND_S`). Samples of a
    hand's braking in ``ref`` raise the fitted loss: the braking test is conservative.

    Parameters
    ----------
    t : ndarray (n,)
        Times, s.
    E : ndarray (n,)
        Mechanical energy (or outside work), J.
    speed : ndarray (n,)
        The platform's speed, m/s.
    ref : ndarray (n,) of bool

    Returns
    -------
    lost : ndarray (n,)
        Energy the passive losses took since the first sample, J (trapezoidal integral).
    coef : ndarray (2,)
        ``d`` (N) and ``c`` (N s/m).
    """
    dt = float(np.median(np.diff(t)))
    k = max(1, int(round(TREND_S / dt)))
    v = np.abs(np.asarray(speed, float))
    X = np.stack([_uniform_filter1d(v, k, mode="nearest"),
                  _uniform_filter1d(v * v, k, mode="nearest")], axis=1)
    rate = np.gradient(_uniform_filter1d(np.asarray(E, float), k, mode="nearest"), dt)
    if np.sum(ref) < 2 * k:
        return np.zeros(len(t)), np.zeros(2)
    from scipy.optimize import nnls  # locked winches only (see _uniform_filter1d)

    coef = nnls(-X[ref], rate[ref])[0]
    P = np.stack([v, v * v], axis=1) @ coef
    return np.concatenate([[0.0], np.cumsum(0.5 * (P[1:] + P[:-1])) * dt]), coef


def braking_runs(t, E, speed, use, exclude, far_per_hour: float):
    """Stretches where the energy falls faster than a passive platform loses it (a hand that
    stops it): ``[(a, b, work J (< 0), p-value)]``.

    ``D`` = the energy plus the passive loss (:func:`passive_loss`, fitted on the samples of
    ``use`` outside ``exclude``) stays level on a passive platform. Its :data:`TREND_S` mean's
    change over each window of :data:`WINDOWS_S` is compared with the robust spread (MAD
    about the median) of the same changes over the windows inside those samples: the null
    takes the passive model's own mismatch, not only the fast noise. Windows beyond the
    threshold of the stated false-alarm rate (Bonferroni over ``2 / L`` windows per second
    and length, one-sided) are joined where ``D`` falls; stretches of at least
    :data:`MIN_S` are reported. Only samples whose mean lies inside the recording count."""
    t, E = np.asarray(t, float), np.asarray(E, float)
    dt = float(np.median(np.diff(t)))
    n, k = len(t), max(1, int(round(TREND_S / dt)))
    use = np.asarray(use, bool).copy()
    use[:k // 2], use[n - k // 2:] = False, False  # the moving mean is whole only here
    ref = use & ~np.asarray(exclude, bool)
    lost, _ = passive_loss(t, E, speed, ref)
    trend = _uniform_filter1d(E + lost, k, mode="nearest")
    n_per_s = sum(2.0 / w for w in WINDOWS_S)
    z_thr = float(normal_isf(far_per_hour / (3600.0 * n_per_s)))
    bad, cref = (np.concatenate([[0], np.cumsum(~x)]) for x in (use, ref))
    mark, zstart, longest = np.zeros(n + 1, int), np.zeros(n), 1
    for w in WINDOWS_S:
        L = max(1, int(round(w / dt)))
        if L >= n:
            continue
        d = trend[:-L] - trend[L:]  # the fall over the window
        inside = (cref[L + 1:] - cref[:-L - 1]) == 0
        if inside.sum() < 10:
            continue
        med = float(np.median(d[inside]))
        scale = max(1.4826 * float(np.median(np.abs(d[inside] - med))), 1e-12)
        z = (d - med) / scale
        hit = np.flatnonzero((z > z_thr) & ((bad[L + 1:] - bad[:-L - 1]) == 0))
        longest = max(longest, L)
        np.add.at(mark, hit, 1)
        np.add.at(mark, np.minimum(hit + L + 1, n), -1)
        zstart[hit] = np.maximum(zstart[hit], z[hit])
    flagged = (np.cumsum(mark)[:n] > 0) & (np.gradient(trend, dt) < 0) & use
    found = []
    for a, b in runs(flagged):
        if t[b - 1] - t[a] < MIN_S:
            continue
        zmax = float(zstart[max(0, a - longest):b].max())
        p = float(min(1.0, normal_sf(zmax) * n_per_s * (t[-1] - t[0])))
        found.append((a, b, float(trend[b - 1] - trend[a]), p))
    return found
