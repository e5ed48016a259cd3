# ruff: noqa: F722  (jaxtyping shape strings)
"""Covariance of least-squares estimates: the paper's i.i.d. formula and the honest HAC one.

Two estimators, one module (every feature calls these; no copy elsewhere):

* :func:`iid_covariance` -- eq. 20 of the paper, ``sigma_rho^2 (W_ID^T W_ID)^-1``, formed from
  the ``R`` factor of the thin QR ``W_ID = Q R`` as ``sigma_rho^2 R^-1 R^-T``. It assumes the
  residuals are independent from row to row.
* :func:`hac_covariance` -- the heteroskedasticity-and-autocorrelation-consistent sandwich
  ``B M B`` with bread ``B = (W_ID^T W_ID)^-1`` and meat ``M`` the Bartlett-weighted
  (Newey-West) long-run covariance of the per-sample scores ``s_k = A_k^T e_k`` (the 6 rows of
  one time sample summed), with a data-driven bandwidth (:func:`andrews_bandwidth`).

Why HAC with Andrews' plug-in bandwidth (and not a moving-block bootstrap)
---------------------------------------------------------------------------
Residuals of the identification are filtered: the 4 Hz zero-phase low-pass (or a
differentiator's own low-pass) makes consecutive residuals strongly correlated over tens of
samples, so eq. 20 understates the spread of the estimate by a factor of roughly the square
root of the correlation length (3-7 on the simulated robots). Both HAC and a block bootstrap
correct for that; HAC is chosen because

* it is deterministic (no seed, the same number on every run, cheap: O(n p^2) by moving sums),
  and exact for the linear estimator: the bootstrap would re-solve the LS hundreds of times;
* it needs the same single tuning quantity as a block bootstrap (the correlation length,
  there the block length), and Andrews (1991) gives a data-driven rule for it: fit an AR(1)
  ``s_t = rho s_{t-1} + u`` to each score component and set the Bartlett bandwidth
  ``S = 1.1447 (alpha T)^(1/3)`` with
  ``alpha = sum_a 4 rho_a^2 s_a^4 / ((1 - rho_a)^6 (1 + rho_a)^2) / sum_a s_a^4 / (1 - rho_a)^4``;
* the bandwidth is floored at 1 and capped at ``n / 4`` samples, so a short recording cannot
  give a window longer than the data.

Leverage adjustment (the default with a data-driven bandwidth)
----------------------------------------------------------------
Scores of fitted residuals sum to zero, so when the window is a sizeable fraction of the
record the fit absorbs part of the low-frequency error and the plain Bartlett meat is biased
low (measured: worst RMS z 1.55-1.68). Each window's score ``m_w`` is therefore replaced by the
jackknife estimate of the error's window score ``Z^T Z (Z^T Z - G_w)^-1 m_w`` (``G_w`` the
window's Gram matrix), i.e. ``Z^T Z (b - b_(-w))`` with ``b_(-w)`` the leave-window-out fit.
Larger bandwidths, the Quadratic-Spectral kernel and AR(1) prewhitening were measured and not
chosen (docs/uncertainty.md); ``tests/core/test_covariance.py`` and ``benchmarks/coverage.py``
measure the coverage on simulated robots.

References
----------
D. W. K. Andrews, "Heteroskedasticity and autocorrelation consistent covariance matrix
estimation", Econometrica 59(3), 1991.
W. K. Newey and K. D. West, "A simple, positive semi-definite, heteroskedasticity and
autocorrelation consistent covariance matrix", Econometrica 55(3), 1987.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import Float

from cdprid.base import InputError

__all__ = [
    "andrews_bandwidth",
    "hac_covariance",
    "hac_covariance_blocks",
    "iid_covariance",
    "sample_scores",
    "std_from_cov",
]

_RHO_MAX = 0.995
"""AR(1) coefficients are clipped below this so a near-unit-root score cannot give inf."""


def iid_covariance(R: Float[np.ndarray, "p p"], sigma2: float) -> Float[np.ndarray, "p p"]:
    """Eq. 20: ``sigma_rho^2 (W^T W)^-1`` from the R factor of the thin QR ``W = Q R``.

    Parameters
    ----------
    R : ndarray (p, p)
        Upper-triangular factor of the (weighted) stacked regressor.
    sigma2 : float
        Residual variance ``sigma_rho^2`` (eq. 19).

    Returns
    -------
    ndarray (p, p)
        ``sigma2 R^-1 R^-T``; valid when the residuals are independent from row to row.
    """
    R = np.asarray(R, float)
    Rinv = np.linalg.solve(R, np.eye(R.shape[0]))
    return float(sigma2) * (Rinv @ Rinv.T)


def _grouped(Z, e):
    Z = np.asarray(Z, float)
    e = np.asarray(e, float)
    if Z.ndim == 2:
        Z = Z[:, None, :]
    if e.ndim == 1:
        e = e.reshape(Z.shape[0], -1)
    if Z.ndim != 3 or e.shape != Z.shape[:2]:
        raise InputError(f"design {Z.shape} and residual {e.shape} do not match: expected "
                         "(n, k, p) and (n, k), or (N, p) and (N,).")
    return Z, e


def sample_scores(Z: Float[np.ndarray, "n k p"], e: Float[np.ndarray, "n k"]
                  ) -> Float[np.ndarray, "n p"]:
    """Per-sample scores ``s_t = Z_t^T e_t`` (the k rows of one time sample summed).

    Parameters
    ----------
    Z : ndarray (n, k, p) or (N, p)
        Design rows grouped by time sample (k = 6 wrench rows), or one row per sample.
    e : ndarray (n, k) or (N,)
        Residuals in the same grouping (weighted rows and residuals for weighted LS).

    Returns
    -------
    ndarray (n, p)
        Scores, in the units of ``Z`` times ``e``.
    """
    Z, e = _grouped(Z, e)
    return np.einsum("nkp,nk->np", Z, e)


def andrews_bandwidth(S: Float[np.ndarray, "n p"]) -> float:
    """Andrews (1991) AR(1) plug-in bandwidth of the Bartlett kernel, in samples.

    Parameters
    ----------
    S : ndarray (n, p)
        Per-sample scores (:func:`sample_scores`).

    Returns
    -------
    float
        ``1.1447 (alpha n)^(1/3)`` clipped to ``[1, n / 4]``; the columns are weighted equally
        after scaling each by its innovation variance (Andrews' unit weights).
    """
    S = np.asarray(S, float)
    n = S.shape[0]
    if n < 8:
        return 1.0
    num = dnm = 0.0
    for j in range(S.shape[1]):  # one column at a time: O(n) memory on long recordings
        x = S[:, j] - S[:, j].mean()
        x0, x1 = x[:-1], x[1:]
        den = float(x0 @ x0)
        if not den > 0:
            continue
        rho = float(np.clip((x0 @ x1) / den, -_RHO_MAX, _RHO_MAX))
        u = x1 - rho * x0
        s2 = float(np.mean(u**2))
        num += 4.0 * rho**2 * s2**2 / ((1 - rho) ** 6 * (1 + rho) ** 2)
        dnm += s2**2 / (1 - rho) ** 4
    if dnm == 0.0 and num == 0.0:
        return 1.0
    alpha = num / dnm if dnm > 0 else 0.0
    b = 1.1447 * (alpha * n) ** (1.0 / 3.0)
    return float(np.clip(b, 1.0, max(1.0, n / 4.0)))


def bartlett_meat(S, bandwidth: float):
    """``sum_{|j| < L} (1 - |j| / L) Gamma_j`` with ``L = ceil(bandwidth)`` by moving sums.

    The Bartlett-weighted sum of the score autocovariances equals the mean outer product of the
    moving sums of L consecutive scores (partial windows at both ends), O(n p^2).

    Parameters
    ----------
    S : ndarray (n, p)
        Per-sample scores.
    bandwidth : float
        Bartlett window L (samples; rounded up, at least 1).

    Returns
    -------
    ndarray (p, p)
    """
    n, p = S.shape
    L = max(1, int(np.ceil(bandwidth)))
    c = np.concatenate([np.zeros((1, p)), np.cumsum(S, axis=0)])
    k = np.arange(n + L - 1)
    M = c[np.minimum(k + 1, n)] - c[np.maximum(k - L + 1, 0)]
    return (M.T @ M) / L


def _window_chunk(design, c, XtX, k0: int, k1: int, n: int, L: int):
    """Adjusted summed scores of the Bartlett windows ``k0 <= k < k1`` (ends ``hi = k + 1``).

    Only the samples those windows cover, ``[max(k0 - L + 1, 0), min(k1, n))``, are asked from
    ``design``; their Gram matrices are summed by a local running sum.
    """
    k = np.arange(k0, k1)
    hi, lo = np.minimum(k + 1, n), np.maximum(k - L + 1, 0)
    base, top = int(lo[0]), int(hi[-1])
    Zb = np.asarray(design(base, top), float)
    Zb = Zb[:, None, :] if Zb.ndim == 2 else Zb
    G = np.einsum("nkp,nkq->npq", Zb, Zb)
    p = G.shape[-1]
    cg = np.concatenate([np.zeros((1, p, p)), np.cumsum(G, axis=0)])
    m = c[hi] - c[lo]
    try:
        return np.linalg.solve(XtX[None] - (cg[hi - base] - cg[lo - base]),
                               m[..., None])[..., 0] @ XtX.T
    except np.linalg.LinAlgError:
        return m


def _leverage_adjusted_windows(design, S, XtX, bandwidth: float, chunk: int = 2048):
    """Bartlett meat from jackknife (leave-one-window-out) adjusted window scores.

    A fitted residual under-represents the error it estimates: removing the window ``w`` from
    the fit would move the estimate by ``(Z^T Z - G_w)^-1 m_w`` (``m_w`` the window's summed
    score, ``G_w`` its Gram matrix), so the error's window score is estimated by
    ``Z^T Z (Z^T Z - G_w)^-1 m_w`` (the HC3 / jackknife correction applied to each Bartlett
    window instead of each row). Windows whose complement is singular keep the raw score.

    Streamed: windows are taken a chunk at a time and each chunk asks ``design`` only for the
    samples it covers, about ``chunk`` (``chunk - L + 1`` windows, at least 256), so no
    (n, p, p) array is ever held.
    """
    n, p = S.shape
    L = max(1, int(np.ceil(bandwidth)))
    step = max(int(chunk) - L + 1, min(int(chunk), 256))
    c = np.empty((n + 1, p))
    c[0] = 0.0
    np.cumsum(S, axis=0, out=c[1:])
    meat = np.zeros((p, p))
    for k0 in range(0, n + L - 1, step):
        adj = _window_chunk(design, c, XtX, k0, min(k0 + step, n + L - 1), n, L)
        meat += adj.T @ adj
    return meat / L


def hac_covariance(
    Z: Float[np.ndarray, "n k p"],
    e: Float[np.ndarray, "n k"],
    bandwidth: float | None = None,
    R: Float[np.ndarray, "p p"] | None = None,
    leverage: bool | None = None,
    min_bandwidth: float = 1.0,
) -> tuple[Float[np.ndarray, "p p"], float]:
    """HAC (Newey-West / Bartlett) sandwich covariance of LS coefficients.

    Parameters
    ----------
    Z : ndarray (n, k, p) or (N, p)
        Design rows (already multiplied by the row weights for weighted LS), grouped by time
        sample: the k rows of one sample are summed into one score before the time weighting.
    e : ndarray (n, k) or (N,)
        Residuals of the (weighted) fit in the same grouping.
    bandwidth : float, optional
        Bartlett bandwidth in samples (the window L: lags up to L - 1 get weights 1 - j / L).
        Default: data-driven, :func:`andrews_bandwidth` of the scores.
    R : ndarray (p, p), optional
        R factor of the thin QR of the stacked design, reused for the bread
        ``(Z^T Z)^-1 = R^-1 R^-T``; computed when not given.
    leverage : bool, optional
        Jackknife-adjust each Bartlett window's score for the fit's leverage
        (``Z^T Z (Z^T Z - G_w)^-1 m_w``, see the module notes). Default: True when the bandwidth
        is data-driven (the std ``identify`` reports), False when a bandwidth is given (the
        textbook Newey-West sum, as ``diagnose``'s fixed-lag tests use it).
    min_bandwidth : float
        Floor of the data-driven bandwidth (:func:`hac_covariance_blocks`).

    Returns
    -------
    cov : ndarray (p, p)
        ``B M B`` with ``B = (Z^T Z)^-1`` and ``M`` the Bartlett long-run covariance of the scores
        (leverage-adjusted or not, see ``leverage``).
    bandwidth : float
        The bandwidth used (samples).
    """
    Z, e = _grouped(Z, e)
    p = Z.shape[-1]
    S = np.einsum("nkp,nk->np", Z, e)
    if R is None:
        R = np.linalg.qr(Z.reshape(-1, p), mode="r")
    return hac_covariance_blocks(lambda i0, i1: Z[i0:i1], S, R, bandwidth, leverage,
                                 min_bandwidth=min_bandwidth)


def hac_covariance_blocks(
    design,
    S: Float[np.ndarray, "n p"],
    R: Float[np.ndarray, "p p"],
    bandwidth: float | None = None,
    leverage: bool | None = None,
    chunk: int = 2048,
    min_bandwidth: float = 1.0,
) -> tuple[Float[np.ndarray, "p p"], float]:
    """:func:`hac_covariance` in bounded memory: the design is asked for block by block.

    Parameters
    ----------
    design : callable
        ``design(i0, i1)`` returns the (weighted) design rows of samples ``i0:i1`` as an array
        (i1 - i0, k, p); called only for the leverage adjustment, one window chunk at a time.
    S : ndarray (n, p)
        Per-sample scores ``Z_t^T e_t`` (:func:`sample_scores`).
    R : ndarray (p, p)
        R factor of the thin QR of the stacked design (``Z^T Z = R^T R``).
    bandwidth, leverage :
        As in :func:`hac_covariance`.
    chunk : int
        Samples asked from ``design`` per call (``chunk - L + 1`` Bartlett windows, at least
        256, per block; memory about ``chunk p^2`` floats).
    min_bandwidth : float
        Floor of the data-driven bandwidth, samples: the memory of a filter every row passed
        (its residuals are correlated over it, which an AR(1) plug-in underestimates).

    Returns
    -------
    cov : ndarray (p, p)
    bandwidth : float
    """
    S = np.asarray(S, float)
    p = S.shape[-1]
    if leverage is None:
        leverage = bandwidth is None
    if bandwidth is None:
        bandwidth = min(max(andrews_bandwidth(S), float(min_bandwidth)), max(1.0, len(S) / 4))
    R = np.asarray(R, float)
    Rinv = np.linalg.solve(R, np.eye(p))
    bread = Rinv @ Rinv.T
    if leverage:
        meat = _leverage_adjusted_windows(design, S, R.T @ R, float(bandwidth), int(chunk))
    else:
        meat = bartlett_meat(S, float(bandwidth))
    cov = bread @ meat @ bread
    return 0.5 * (cov + cov.T), float(bandwidth)


def std_from_cov(cov: Float[np.ndarray, "p p"]) -> Float[np.ndarray, " p"]:
    """Standard deviations: square roots of the covariance diagonal (negatives clipped to 0).

    Parameters
    ----------
    cov : array_like (p, p)

    Returns
    -------
    ndarray (p,)
        In the parameters' units.
    """
    return np.sqrt(np.clip(np.diag(np.asarray(cov, float)), 0.0, None))
