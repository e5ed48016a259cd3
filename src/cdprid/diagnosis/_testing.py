"""Stage 2 of the diagnosis: statistics (HAC Wald tests, blocked held-out error, noise).

The HAC covariance is :func:`cdprid.core.hac_covariance` with a fixed Bartlett window of
``lags + 1`` samples (the correlation length of the matched-filtered residual).
"""

from __future__ import annotations

import numpy as np

from cdprid.core import (
    estimate_noise,  # noqa: F401  (re-exported)
    hac_covariance,
)


def hac_cov(Z, e, lags: int):
    """Sandwich covariance of LS coefficients, Newey-West (Bartlett) HAC over time samples.

    Z : (n, 6, p) design rows grouped by sample; e : (n, 6) residuals; lags up to ``lags``
    get the Bartlett weights ``1 - j / (lags + 1)``. This is
    :func:`cdprid.core.hac_covariance` with the window ``lags + 1``.
    """
    return hac_covariance(Z, e, bandwidth=int(lags) + 1)[0]


def wald(Z, y, idx_extra, lags):
    """LS of y on Z, Wald statistic of the coefficients idx_extra with HAC covariance."""
    n, _, p = Z.shape
    Zf = Z.reshape(-1, p)
    beta, *_ = np.linalg.lstsq(Zf, y.reshape(-1), rcond=None)
    e = y - np.einsum("nip,p->ni", Z, beta)
    V = hac_cov(Z, e, lags)
    b = beta[idx_extra]
    Vb = V[np.ix_(idx_extra, idx_extra)]
    try:
        stat = float(b @ np.linalg.solve(Vb, b))
    except np.linalg.LinAlgError:
        stat = 0.0
    return stat, beta, V, e


def blocks(n: int, k: int):
    """``k`` contiguous (lo, hi) index blocks covering ``range(n)``."""
    edges = np.linspace(0, n, k + 1).astype(int)
    return [(edges[i], edges[i + 1]) for i in range(k)]


def cv_sse(Z, y, folds, guard):
    """Blocked held-out sum of squared residuals of the LS of y on Z.

    Each fold ``(lo, hi)`` is predicted from the LS fit on the samples outside
    ``[lo - guard, hi + guard)``. The fits use normal equations from prefix sums of the
    per-sample Gram matrices (one pass over the data for every fold; the same solution as
    the least squares on the training rows whenever they have full column rank).
    """
    n, _, p = Z.shape
    G = np.zeros((n + 1, p, p))
    np.cumsum(np.einsum("nip,niq->npq", Z, Z), axis=0, out=G[1:])
    g = np.zeros((n + 1, p))
    np.cumsum(np.einsum("nip,ni->np", Z, y), axis=0, out=g[1:])
    s = np.concatenate([[0.0], np.cumsum(np.einsum("ni,ni->n", y, y))])
    sse = 0.0
    count = 0
    for lo, hi in folds:
        a, b = max(0, lo - guard), min(n, hi + guard)
        sse += fold_sse(G[n] - (G[b] - G[a]), g[n] - (g[b] - g[a]), G[hi] - G[lo],
                        g[hi] - g[lo], s[hi] - s[lo])
        count += int(hi - lo) * y.shape[1]
    return sse, count


def fold_sse(Gt, gt, Gb, gb, yy) -> float:
    """Held-out sum of squared residuals of one fold from Gram matrices: the LS fit on the
    training rows (``Gt = Z^T Z``, ``gt = Z^T y``; columns scaled to unit norm, ``lstsq``)
    applied to the held-out rows (``Gb``, ``gb``, ``yy = y^T y``)."""
    scale = np.sqrt(np.clip(np.diag(Gt), 1e-300, None))
    beta = np.linalg.lstsq(Gt / np.outer(scale, scale), gt / scale, rcond=None)[0] / scale
    return float(max(0.0, yy - 2.0 * beta @ gb + beta @ Gb @ beta))


def partial_wald(Ct, yt, lags):
    """Wald statistic (HAC) of the LS of yt on Ct, both already partialled on the base model."""
    q = Ct.shape[2]
    Cf = Ct.reshape(-1, q)
    G = Cf.T @ Cf
    try:
        beta = np.linalg.solve(G, Cf.T @ yt.reshape(-1))
    except np.linalg.LinAlgError:
        return 0.0, np.zeros(q), np.eye(q)
    e = yt - np.einsum("niq,q->ni", Ct, beta)
    V = hac_cov(Ct, e, lags)
    try:
        stat = float(beta @ np.linalg.solve(V, beta))
    except np.linalg.LinAlgError:
        stat = 0.0
    return stat, beta, V


def partial_wald_many(Ct, Y, lags):
    """:func:`partial_wald` statistics for many right-hand sides Y (n, 6, R) at once.

    Matrix products throughout (BLAS): residuals, per-sample scores ``C_t^T e_t``, Bartlett
    window sums from a cumulative sum, and the meat of every right-hand side at once.
    """
    n, _, q = Ct.shape
    R = Y.shape[-1]
    Cf = Ct.reshape(-1, q)
    Yf = Y.reshape(-1, R)
    Ginv = np.linalg.pinv(Cf.T @ Cf)
    B = Ginv @ (Cf.T @ Yf)  # (q, R)
    E = (Yf - Cf @ B).reshape(n, 6, R)
    S = np.matmul(Ct.transpose(0, 2, 1), E)  # (n, q, R)
    L = int(lags) + 1
    c = np.zeros((n + 1, q, R))
    np.cumsum(S, axis=0, out=c[1:])
    hi = np.minimum(np.arange(n + L - 1) + 1, n)
    lo = np.maximum(np.arange(n + L - 1) - L + 1, 0)
    M = (c[hi] - c[lo]).transpose(2, 1, 0)  # (R, q, n+L-1)
    meat = np.matmul(M, M.transpose(0, 2, 1)) / L
    V = Ginv[None] @ meat @ Ginv[None]  # (R, q, q)
    try:
        return np.einsum("rq,rq->r", B.T, np.linalg.solve(V, B.T[:, :, None])[:, :, 0])
    except np.linalg.LinAlgError:
        out = np.zeros(R)
        for r in range(R):
            try:
                out[r] = B[:, r] @ np.linalg.solve(V[r], B[:, r])
            except np.linalg.LinAlgError:
                out[r] = 0.0
        return out


def aliases_of(c_best, scored, pcols, corr: float = 0.8) -> list[str]:
    """Candidates the data cannot tell apart from the winner.

    An alternative is an alias when its HAC Wald statistic is within
    ``max(25, 5 %)`` of the winner's (it explains the residual nearly as well, the difference
    being of the order of the noise) and the largest canonical correlation between the two
    column spaces, with the base model partialled out, is at least ``corr``. ``scored`` holds
    ``(p, candidate, statistic)`` best first; ``pcols`` the partialled columns by candidate.
    """
    stat_best = next(st for _, c, st in scored if c == c_best)
    margin = max(25.0, 0.05 * stat_best)
    Qb, _ = np.linalg.qr(pcols[c_best].reshape(-1, pcols[c_best].shape[2]))
    out = []
    for _, c, st in scored[:25]:
        if c == c_best or st < stat_best - margin:
            continue
        Qc, _ = np.linalg.qr(pcols[c].reshape(-1, pcols[c].shape[2]))
        s = np.linalg.svd(Qb.T @ Qc, compute_uv=False)
        if s.max() >= corr:
            out.append(c.effect if c.cable is None else f"{c.effect}:cable={c.cable}")
    return out
