"""The noise of ``identify --source currents`` seen through its filter chain: the variance
gain and the autocovariance of white noise on a stream's own clock after the low-pass, the
interpolation onto the pose clock and the matched filter, and the HAC covariance at the
bandwidth that autocovariance implies (:mod:`cdprid.identify._currents`).

Why not the AR(1) plug-in bandwidth of the tension path: every column and the residual pass a
zero-phase low-pass of a few Hz at 100 Hz, so the scores' lag-1 correlation is near 1 and the
AR(1) fit (clipped at 0.995) returns 400-550 samples on a 30 s recording, n / 5: a handful of
Bartlett windows (a noisy std) and ``n_eff`` = 5-6 in the weak-identification check (its
``sqrt(2 / n_eff)`` then doubled the mass's std on the six-cable Monte Carlo). The residual is
the currents', encoders' and poses' white noise through that chain, so the chain's own
autocovariance gives Andrews' ``alpha`` directly (60-90 samples there).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.core import hac_covariance_blocks, sample_scores
from cdprid.signal import zero_phase_filter

__all__ = ["chain_alpha", "filter_gain", "hac_bandwidth", "hac_fixed", "period"]


def period(t) -> float:
    """The median sampling period (s) of the times ``t`` (s)."""
    return float(np.median(np.diff(t)))


def filter_gain(t_src, t, wf, pre=None, seed: int = 1) -> float:
    """Variance of ``F[interp(P[x])]`` for unit white noise ``x`` on the stream's own clock,
    low-passed (``P``, cutoff ``pre`` or none), interpolated onto the pose clock and filtered
    (10 % of each end dropped)."""
    x = np.random.default_rng(seed).normal(size=(len(t_src), 3))
    if pre is not None:
        x = zero_phase_filter(x, period(t_src), pre)
    xi = np.column_stack([np.interp(t, t_src, x[:, c]) for c in range(3)])
    f = np.asarray(wf(xi, np.ones(3)))
    k = slice(len(t) // 10, len(t) - len(t) // 10)
    return float(np.mean(np.var(f[k], axis=0)))


def chain_alpha(t_src, t, wf, pre=None, seed: int = 3) -> float:
    """Andrews' ``alpha = (sum_j |j| gamma_j / sum_j gamma_j)^2`` (samples^2) of white noise
    on the stream's own clock passed through the chain of :func:`filter_gain` (low-pass,
    interpolation, matched filter), ``gamma_j`` its autocovariance measured on white noise.
    The HAC bandwidth is then ``1.1447 (alpha n)^(1/3)`` (:func:`hac_bandwidth`)."""
    n = len(t)
    x = np.random.default_rng(seed).normal(size=(len(t_src), 4))
    if pre is not None:
        x = zero_phase_filter(x, period(t_src), pre)
    xi = np.column_stack([np.interp(t, t_src, x[:, c]) for c in range(4)])
    f = np.asarray(wf(xi, np.ones(4)))[n // 10:n - n // 10]
    f = f - f.mean(axis=0)
    L = min(len(f) // 4, 1000)
    g = np.array([np.mean(np.sum(f[j:] * f[:len(f) - j], axis=1)) for j in range(L)])
    j = np.arange(L)
    den = g[0] + 2.0 * np.sum(g[1:])
    if not den > 0:
        return float("inf")
    return float((2.0 * np.sum(j * g) / den) ** 2)


def hac_bandwidth(alpha: float, n: int) -> float:
    """Andrews' (1991) Bartlett bandwidth ``1.1447 (alpha n)^(1/3)`` (samples), clipped to
    ``[1, n / 4]``.

    Parameters
    ----------
    alpha : float
        ``(sum |j| gamma_j / sum gamma_j)^2`` of the residual's autocovariance (samples^2).
    n : int
        Number of time samples.

    Returns
    -------
    float
    """
    b = 1.1447 * (max(alpha, 0.0) * n) ** (1.0 / 3.0) if np.isfinite(alpha) else n / 4.0
    return float(np.clip(b, 1.0, max(1.0, n / 4.0)))


def hac_fixed(rows, ls, n: int, bandwidth: float, chunk: int):
    """``ls`` (an i.i.d. least-squares result of the blocks ``rows``) with its HAC covariance:
    Bartlett at ``bandwidth`` samples (the filter chain's, :func:`hac_bandwidth`), leverage
    adjusted (:func:`cdprid.core.hac_covariance_blocks`)."""
    S, ZtZ = [], 0.0
    for i0 in range(0, n, chunk):
        M, y = rows(i0, min(n, i0 + chunk))
        S.append(sample_scores(M, y - M @ ls.x))
        ZtZ = ZtZ + np.einsum("kap,kaq->pq", M, M)
    R = np.linalg.cholesky(ZtZ).T
    cov, bw = hac_covariance_blocks(lambda a, b: rows(a, b)[0], np.concatenate(S), R,
                                    bandwidth=bandwidth, leverage=True, chunk=max(chunk, 2048))
    return dataclasses.replace(ls, cov=cov, covariance="hac", hac_bandwidth=bw)
