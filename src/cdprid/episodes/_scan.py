"""The change-point scan of the episodes stage: where the whitened wrench residual's mean moves
away from zero, with a threshold from a stated false-alarm rate per hour.

The residual ``r`` (n, k) of a fit (measured ``W tau`` minus the model's wrench, both through
the same matched filter; k = 6 rows, fewer when rows of the wrench are identically zero, as
for a point-mass platform) is whitened by its own noise model: a robust k x k covariance
(from the rows' MAD, then samples beyond the 99.9 % chi-squared quantile left out,
iterated) and the autocovariances of the whitened residual up to several correlation
lengths (Bartlett-tapered, the HAC covariance of :mod:`cdprid.core`), never below those of
white noise through the matched filter (a floor the taper and short records cannot lower).
For a window of L samples the sum ``M = sum z_k`` then has the covariance
``V_L = sum_{|l| < L} (L - |l|) Gamma_l``, and ``T = M^T V_L^-1 M`` is chi-squared with k
degrees of freedom when the model holds. The scan evaluates T on every window of several
lengths (:data:`SCALES_S`); a recording of D hours holds about ``D 3600 sum_s 2 / L_s``
independent windows, so the per-window level that gives ``far_per_hour`` false alarms per
hour is ``far_per_hour / (3600 sum_s 2 / L_s)`` (Bonferroni over the windows: conservative
where windows overlap). :func:`locate` refines each flagged stretch to the interval where a
constant shift explains the most and scans again without it (binary segmentation).
"""

from __future__ import annotations

import math

import numpy as np

from cdprid.base import chi2_isf

__all__ = ["SCALES_S", "NoiseModel", "filter_autocorrelation", "noise_model",
           "robust_whitening", "scan", "refine", "window_level", "locate", "runs"]

#: window lengths of the scan, s (a push shorter than the shortest is seen only if strong)
SCALES_S = (0.2, 0.4, 0.8, 1.6, 3.2)

#: chi-squared quantile beyond which a sample is left out of the robust covariance
_ROBUST_Q = 0.999


class NoiseModel:
    """The residual's noise model: whitening matrix and the window-sum covariances.

    Attributes
    ----------
    whiten : ndarray (k, k)
        ``z = r @ whiten.T`` has unit covariance (robust, at lag 0).
    gammas : ndarray (L + 1, k, k)
        Empirical autocovariances of ``z`` at lags ``0..L`` (Bartlett-tapered).
    rho : ndarray (M,)
        Autocorrelation of the matched filter at lags ``0..M-1``: that of white noise
        through the filter, the floor of the window covariances.
    """

    def __init__(self, whiten: np.ndarray, gammas: np.ndarray, rho: np.ndarray):
        self.whiten = whiten
        self.gammas = gammas
        self.rho = rho

    def window_cov(self, length: int) -> np.ndarray:
        """Covariance (k, k) of the sum of ``z`` over ``length`` consecutive samples: the
        larger (in the positive-definite sense) of white noise through the filter and the
        empirical one, so that neither estimation noise nor coloured residual lowers it."""
        g, rho = self.gammas, self.rho
        lags = np.arange(min(length, len(g)))
        w = (length - lags).astype(float)
        Ve = w[0] * g[0]
        for lag in lags[1:]:
            Ve = Ve + w[lag] * (g[lag] + g[lag].T)
        lr = np.arange(min(length, len(rho)))
        Vf = float(length + 2.0 * np.sum((length - lr[1:]) * rho[lr[1:]])) * np.eye(len(g[0]))
        e, U = np.linalg.eigh(0.5 * (Ve + Ve.T) - Vf)
        return Vf + (U * np.maximum(e, 0.0)) @ U.T


def filter_autocorrelation(dt: float, cutoff_hz: float) -> np.ndarray:
    """Autocorrelation (lags 0, 1, ...) of white noise through the zero-phase matched filter,
    to where it has decayed to 1e-6.

    Parameters
    ----------
    dt : float
        Sampling period, s.
    cutoff_hz : float
        The filter's cutoff, Hz (:func:`cdprid.signal.zero_phase_filter`, order 2).

    Returns
    -------
    ndarray (M,)
        Autocorrelation at lags ``0..M-1`` samples, dimensionless (1 at lag 0).
    """
    from cdprid.signal import zero_phase_filter

    n = 2 * int(math.ceil(8.0 / (cutoff_hz * dt))) + 1
    x = np.zeros(n)
    x[n // 2] = 1.0
    h = np.asarray(zero_phase_filter(x, dt, cutoff_hz, 2))
    ac = np.correlate(h, h, mode="full")[n - 1:]
    ac = ac / ac[0]
    keep = np.flatnonzero(np.abs(ac) > 1e-6)
    return ac[: keep[-1] + 1]


def noise_model(r: np.ndarray, use: np.ndarray, max_lag: int, rho=None) -> NoiseModel:
    """The noise model of the residual ``r`` (n, 6) on the samples ``use`` (see module doc).

    Parameters
    ----------
    r : ndarray (n, 6)
        Residual, N and N m.
    use : ndarray (n,) of bool
        Samples that make the noise model (outside episodes, inside the used data).
    max_lag : int
        The correlation length, samples (autocovariances up to twice it).
    rho : ndarray, optional
        :func:`filter_autocorrelation` of the matched filter (default: white, ``[1]``).

    Returns
    -------
    NoiseModel
    """
    x = r[use]
    whiten, inlier = robust_whitening(x)
    ok = np.zeros(len(use), bool)
    ok[np.flatnonzero(use)[inlier]] = True
    ok = ~_near(~ok, max_lag // 4)  # outliers and their neighbours stay out of the lags
    z = np.where(ok[:, None], r @ whiten.T, 0.0)  # zero outside: products vanish there
    okf = ok.astype(float)
    gam, span, n = [], 2 * max_lag, len(z)  # Bartlett taper: a valid covariance
    for lag in range(span + 1):
        count = max(1.0, float(okf[lag:] @ okf[: n - lag]))
        g = z[lag:].T @ z[: n - lag] / count
        gam.append(g * (1.0 - lag / (span + 1.0)))
    return NoiseModel(whiten, np.asarray(gam), np.ones(1) if rho is None else np.asarray(rho))


def robust_whitening(x: np.ndarray):
    """The whitening of the rows' robust covariance (the noise model's lag 0).

    Parameters
    ----------
    x : ndarray (n, k)
        Residual samples, N and N m.

    Returns
    -------
    whiten : ndarray (k, k)
        ``x @ whiten.T`` has unit covariance on the inliers (the inverse Cholesky factor of
        the covariance from the rows' MAD, then samples beyond the :data:`_ROBUST_Q`
        chi-squared quantile left out, iterated).
    inlier : ndarray (n,) of bool
        The samples that made it.
    """
    k = x.shape[1]
    mad = 1.4826 * np.median(np.abs(x - np.median(x, 0)), 0)
    C = np.diag(np.maximum(mad, 1e-12) ** 2)  # robust start: a push is not noise
    q = chi2_isf(1.0 - _ROBUST_Q, k)
    inlier = np.ones(len(x), bool)
    for _ in range(4):  # leave out the outliers (the covariance then under-states by ~1 %)
        inside = np.einsum("ni,ij,nj->n", x, np.linalg.inv(C), x) < q
        if inside.sum() < max(10 * k, len(x) // 2):  # not a noise model of most samples
            break
        inlier = inside
        C = np.atleast_2d(np.cov(x[inlier].T)) + 1e-12 * np.eye(k)
    return np.linalg.inv(np.linalg.cholesky(C)), inlier


def _near(mask: np.ndarray, k: int) -> np.ndarray:
    """Samples within ``k`` of a True sample of ``mask``."""
    c = np.concatenate([[0], np.cumsum(mask.astype(int))])
    i = np.arange(len(mask))
    return (c[np.minimum(len(mask), i + k + 1)] - c[np.maximum(0, i - k)]) > 0


def window_level(far_per_hour: float, scales_s=SCALES_S) -> float:
    """The per-window significance level of :func:`scan` for ``far_per_hour``.

    Parameters
    ----------
    far_per_hour : float
        False alarms per hour of clean recording.
    scales_s : sequence of float
        The scan's window lengths, s.

    Returns
    -------
    float
        ``far_per_hour / (3600 sum_s 2 / L_s)``: Bonferroni over the about ``2 / L_s``
        independent windows per second and length.
    """
    return far_per_hour / (3600.0 * sum(2.0 / s for s in scales_s))


def _moving_sums(z, L):
    c = np.concatenate([np.zeros((1, z.shape[1])), np.cumsum(z, axis=0)])
    return c[L:] - c[:-L]


def scan(r: np.ndarray, use: np.ndarray, dt: float, model: NoiseModel, level: float,
         scales_s=SCALES_S) -> np.ndarray:
    """Samples inside at least one window whose statistic exceeds the threshold.

    Parameters
    ----------
    r : ndarray (n, 6)
    use : ndarray (n,) of bool
        Windows must lie wholly inside these samples.
    dt : float
        Sampling period, s.
    model : NoiseModel
    level : float
        Per-window significance level (:func:`window_level`).

    Returns
    -------
    ndarray (n,) of bool
    """
    n = len(r)
    z = np.where(use[:, None], r @ model.whiten.T, 0.0)
    bad = np.concatenate([[0], np.cumsum(~use)])
    thr = chi2_isf(level, r.shape[1])
    flagged = np.zeros(n, bool)
    for s in scales_s:
        L = max(2, int(round(s / dt)))
        if L > n:
            continue
        M = _moving_sums(z, L)
        Vi = np.linalg.inv(model.window_cov(L))
        T = np.einsum("ni,ij,nj->n", M, Vi, M)
        ok = (bad[L:] - bad[:-L]) == 0
        hit = np.flatnonzero(ok & (T > thr))
        if hit.size:
            mark = np.zeros(n + 1, int)
            np.add.at(mark, hit, 1)
            np.add.at(mark, hit + L, -1)
            flagged |= np.cumsum(mark)[:n] > 0
    return flagged


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges ``[a, b)`` of the True runs of ``mask``."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    e = np.flatnonzero(np.diff(m.astype(int)))
    return list(zip(e[::2].tolist(), e[1::2].tolist(), strict=True))


def refine(r: np.ndarray, a: int, b: int, model: NoiseModel, max_points: int = 400):
    """The sub-interval of ``[a, b)`` where a constant shift of the residual's mean explains
    the most: ``(a', b', T, mean residual (6,))`` maximising ``M^T V^-1 M`` over the
    sub-intervals (a grid of at most ``max_points`` candidate edges)."""
    z = r[a:b] @ model.whiten.T
    n, k = z.shape
    step = max(1, int(math.ceil(n / max_points)))
    edges = np.arange(0, n + 1, step)
    if edges[-1] != n:
        edges = np.append(edges, n)
    c = np.concatenate([np.zeros((1, k)), np.cumsum(z, axis=0)])[edges]
    best = (0, n, -1.0)
    Omega = model.window_cov(max(1, len(model.gammas) * 4)) / max(1, len(model.gammas) * 4)
    Oi = np.linalg.inv(Omega)
    for i in range(len(edges) - 1):
        M = c[i + 1:] - c[i]
        Ls = (edges[i + 1:] - edges[i]).astype(float)
        T = np.einsum("ni,ij,nj->n", M, Oi, M) / Ls
        j = int(np.argmax(T))
        if T[j] > best[2]:
            best = (int(edges[i]), int(edges[i + 1 + j]), float(T[j]))
    a2, b2 = a + best[0], a + best[1]
    V = model.window_cov(b2 - a2)
    M = (r[a2:b2] @ model.whiten.T).sum(0)
    T = float(M @ np.linalg.solve(V, M))
    return a2, b2, T, r[a2:b2].mean(0)


def locate(r: np.ndarray, use: np.ndarray, dt: float, model: NoiseModel, level: float,
           guard: int = 1, max_episodes: int = 50) -> list:
    """Every episode of the residual: scan, refine each flagged stretch, scan again without
    the episodes found (and ``guard`` samples on each side: the matched filter's transient,
    whose ringing would otherwise be found again), until nothing is flagged.

    Parameters
    ----------
    r : ndarray (n, k)
        The fit's residual, N and N m (k wrench rows in use).
    use : ndarray (n,) of bool
        Samples the windows may cover.
    dt : float
        Sampling period, s.
    model : NoiseModel
        The residual's noise model (:func:`noise_model`).
    level : float
        Per-window significance level (:func:`window_level`).
    guard : int
        Samples left out on each side of an episode found before the next scan.
    max_episodes : int
        Stop after this many.

    Returns
    -------
    list of ``(a, b, T, mean residual)`` (half-open sample ranges, :func:`refine`)
    """
    free, found = np.asarray(use, bool).copy(), []
    while len(found) < max_episodes:
        new = [refine(r, a, b, model) for a, b in runs(scan(r, free, dt, model, level))]
        if not new:
            break
        thr = chi2_isf(level, r.shape[1])
        for a, b, T, mean in new:
            if T > thr:  # a refined stretch below the threshold is not reported
                found.append((a, b, T, mean))
            free[max(0, a - guard):b + guard] = False
    return sorted(found, key=lambda e: e[0])
