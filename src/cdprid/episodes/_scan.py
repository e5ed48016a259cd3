"""The change-point scan of the episodes stage: where the whitened wrench residual's mean moves
away from zero, with a threshold from a stated false-alarm rate per hour.

The residual ``r`` (n, 6) of a fit (measured ``W tau`` minus the model's wrench, both through
the same matched filter) is whitened by its own noise model: a robust 6 x 6 covariance
(samples beyond the 99.9 % chi-squared quantile left out, iterated) and the autocovariances
of the whitened residual up to its correlation length (Bartlett taper, as the HAC covariance
of :mod:`cdprid.core`). For a window of L samples the sum ``M = sum z_k`` then has the
covariance ``V_L = sum_{|l| < L} (L - |l|) k(l) Gamma_l``, and ``T = M^T V_L^-1 M`` is
chi-squared with 6 degrees of freedom when the model holds. The scan evaluates T on every
window of several lengths (:data:`SCALES_S`); a recording of D hours holds about
``D 3600 sum_s 2 / L_s`` independent windows, so the per-window level that gives
``far_per_hour`` false alarms per hour is ``far_per_hour / (3600 sum_s 2 / L_s)``
(Bonferroni over the windows: conservative where windows overlap).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

__all__ = ["SCALES_S", "NoiseModel", "noise_model", "scan", "refine", "window_level"]

#: window lengths of the scan, s (a push shorter than the shortest is seen only if strong)
SCALES_S = (0.2, 0.4, 0.8, 1.6, 3.2)

#: chi-squared quantile beyond which a sample is left out of the robust covariance
_ROBUST_Q = 0.999


class NoiseModel:
    """The residual's noise model: whitening matrix and the window-sum covariances.

    Attributes
    ----------
    whiten : ndarray (6, 6)
        ``z = r @ whiten.T`` has unit covariance (robust, at lag 0).
    gammas : ndarray (L + 1, 6, 6)
        Autocovariances of ``z`` at lags ``0..L``, Bartlett-tapered.
    """

    def __init__(self, whiten: np.ndarray, gammas: np.ndarray):
        self.whiten = whiten
        self.gammas = gammas

    def window_cov(self, length: int) -> np.ndarray:
        """Covariance (6, 6) of the sum of ``z`` over ``length`` consecutive samples."""
        g = self.gammas
        lags = np.arange(min(length, len(g)))
        w = (length - lags).astype(float)
        V = w[0] * g[0]
        for lag in lags[1:]:
            V = V + w[lag] * (g[lag] + g[lag].T)
        return V


def noise_model(r: np.ndarray, use: np.ndarray, max_lag: int) -> NoiseModel:
    """The noise model of the residual ``r`` (n, 6) on the samples ``use`` (see module doc).

    Parameters
    ----------
    r : ndarray (n, 6)
        Residual, N and N m.
    use : ndarray (n,) of bool
        Samples that make the noise model (outside episodes, inside the used data).
    max_lag : int
        Longest lag of the autocovariances, samples (the correlation length).

    Returns
    -------
    NoiseModel
    """
    x = r[use]
    C = np.cov(x.T) + 1e-12 * np.eye(6)
    q = stats.chi2.isf(1.0 - _ROBUST_Q, 6)
    for _ in range(3):  # leave out the outliers (the covariance then under-states by ~1 %)
        d2 = np.einsum("ni,ij,nj->n", x, np.linalg.inv(C), x)
        C = np.cov(x[d2 < q].T) + 1e-12 * np.eye(6)
    L = np.linalg.cholesky(C)
    whiten = np.linalg.inv(L)
    z = np.where(use[:, None], r @ whiten.T, 0.0)
    gam = []
    for lag in range(max_lag + 1):
        both = use[lag:] & use[: len(use) - lag]
        g = z[lag:][both].T @ z[: len(z) - lag][both] / max(1, int(both.sum()))
        gam.append(g * (1.0 - lag / (max_lag + 1.0)))
    return NoiseModel(whiten, np.asarray(gam))


def window_level(far_per_hour: float, scales_s=SCALES_S) -> float:
    """The per-window significance level of :func:`scan` for ``far_per_hour``."""
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
    thr = stats.chi2.isf(level, 6)
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
    n = len(z)
    step = max(1, int(math.ceil(n / max_points)))
    edges = np.arange(0, n + 1, step)
    if edges[-1] != n:
        edges = np.append(edges, n)
    c = np.concatenate([np.zeros((1, 6)), np.cumsum(z, axis=0)])[edges]
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
