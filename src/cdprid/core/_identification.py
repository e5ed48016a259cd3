"""Least-squares identification (paper eqs. 11-21).

``Y_ID = W_ID x + rho`` is solved by a thin QR of the (optionally weighted) stacked regressor
— never through the normal-equation inverse. The covariance ``sigma_rho^2 (W^T W)^-1`` (eq. 20)
is formed from R as ``sigma_rho^2 R^-1 R^-T`` (:func:`cdprid.core.iid_covariance`); the
default reported covariance is the HAC sandwich of :func:`cdprid.core.hac_covariance`,
because filtered residuals are correlated over many samples and eq. 20 then understates the
spread of the estimate several times.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import InputError
from cdprid.core._covariance import hac_covariance_blocks, iid_covariance, std_from_cov

__all__ = ["LSResult", "condition_number", "group_weights", "least_squares",
           "least_squares_blocks"]


@dataclasses.dataclass(frozen=True)
class LSResult:
    """Result of a least-squares identification.

    Attributes
    ----------
    names : tuple of str
        Parameter names, e.g. ``("m", "mxG", "myG", "mzG")``.
    x : ndarray (p,)
        Estimates (eq. 15).
    cov : ndarray (p, p)
        Covariance of the estimate used for ``std``: HAC (default) or eq. 20 (``covariance``).
    sigma_rho : float
        Residual standard deviation (eq. 19), in the units of the (weighted) rows.
    cond : float
        Condition number of W_ID (ratio of extreme singular values).
    cond_scaled : float
        Condition number after scaling every column to unit norm.
    n_rows : int
        Number of equations 6 n_e (rows used).
    residual : ndarray
        Unweighted residual ``Y_ID - W_ID x``.
    weights : ndarray or None
        Row weights used (None for ordinary LS).
    cov_iid : ndarray (p, p) or None
        Eq. 20's covariance ``sigma_rho^2 (W^T W)^-1`` (i.i.d. residuals), always kept.
    covariance : str
        Which covariance ``cov`` is: ``"hac"`` or ``"iid"``.
    hac_bandwidth : float
        Bartlett bandwidth (time samples) of the HAC covariance.
    column_norms : ndarray (p,) or None
        Euclidean norms of the (unweighted) columns of W_ID.
    """

    names: tuple
    x: np.ndarray
    cov: np.ndarray
    sigma_rho: float
    cond: float
    cond_scaled: float
    n_rows: int
    residual: np.ndarray
    weights: np.ndarray | None = None
    cov_iid: np.ndarray | None = None
    covariance: str = "hac"
    hac_bandwidth: float = float("nan")
    column_norms: np.ndarray | None = None

    @property
    def std(self) -> np.ndarray:
        """Standard deviation of each parameter (square root of the covariance diagonal)."""
        return std_from_cov(self.cov)

    @property
    def std_iid(self) -> np.ndarray:
        """Eq. 20's standard deviations (i.i.d. residuals); understated on filtered data."""
        return std_from_cov(self.cov if self.cov_iid is None else self.cov_iid)

    @property
    def rel_std_percent(self) -> np.ndarray:
        """Relative standard deviation in percent (eq. 21); inf for a zero estimate."""
        with np.errstate(divide="ignore"):
            return 100.0 * self.std / np.abs(self.x)

    def as_dict(self) -> dict:
        """The estimates by name (the CLI's JSON contract).

        Returns
        -------
        dict
            ``{name: {"value", "std", "rel_std_percent", "std_iid"}}``, floats in the parameter's
            SI unit (``rel_std_percent`` in percent).
        """
        return {
            n: {"value": float(v), "std": float(s), "rel_std_percent": float(r),
                "std_iid": float(si)}
            for n, v, s, r, si in zip(self.names, self.x, self.std, self.rel_std_percent,
                                      self.std_iid, strict=True)
        }


def condition_number(W_ID, scaled: bool = False) -> float:
    """Condition number of W_ID by SVD.

    Parameters
    ----------
    W_ID : array_like (N, p)
        Stacked regressor.
    scaled : bool
        Scale the columns to unit norm first (removes the parameters' units).

    Returns
    -------
    float
        Largest over smallest singular value (``inf`` when the smallest is 0).
    """
    A = np.asarray(W_ID, float)
    if scaled:
        norms = np.linalg.norm(A, axis=0)
        A = A / np.where(norms > 0, norms, 1.0)
    s = np.linalg.svd(A, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")


def group_weights(residual, groups) -> np.ndarray:
    """Row weights 1/sigma_g for each row group from a first-pass residual.

    Parameters
    ----------
    residual : ndarray (N,)
        First-pass residual (N for force rows, N m for moment rows).
    groups : ndarray of int (N,)
        Group label of each row (e.g. 0 for force rows, 1 for moment rows).

    Returns
    -------
    ndarray (N,)
        ``1 / rms(residual of the row's group)`` (1 where that rms is 0), inverse residual units.
    """
    residual = np.asarray(residual, float)
    groups = np.asarray(groups)
    w = np.ones_like(residual)
    for g in np.unique(groups):
        sel = groups == g
        s = np.sqrt(np.mean(residual[sel] ** 2))
        w[sel] = 1.0 / s if s > 0 else 1.0
    return w


def _check_rank(R, names, tol: float = 1e-10) -> None:
    """Raise a clear ValueError when W_ID = Q R is (numerically) rank deficient.

    The singular values and right singular vectors of W_ID are those of its R factor, and its
    column norms are R's.
    """
    norms = np.linalg.norm(R, axis=0)
    zero = [n for n, v in zip(names, norms, strict=False) if v == 0]
    _, s, Vt = np.linalg.svd(R / np.where(norms > 0, norms, 1.0), full_matrices=False)
    if zero or s[-1] < tol * s[0]:
        v = np.abs(Vt[-1])
        culprits = zero or [n for n, c in zip(names, v, strict=False) if c > 0.3 * v.max()]
        raise InputError(
            f"the regressor W_ID is rank deficient: {', '.join(culprits)} not identifiable from "
            "this motion (excite it, or use a smaller model)."
        )


def _update_r(Rt, M):
    """R factor of ``[Rt; M]`` (the tall-skinny QR step: W = Q R accumulated block by block)."""
    return np.linalg.qr(M if Rt is None else np.vstack([Rt, M]), mode="r")


def _chunks(n: int, chunk: int):
    return ((i, min(i + chunk, n)) for i in range(0, n, chunk))


def _block_rows(block, i0, i1, p_check=None):
    Z, y = block(i0, i1)
    Z = np.asarray(Z, float)
    y = np.asarray(y, float)
    if Z.ndim != 3 or y.shape != Z.shape[:2] or (p_check is not None and Z.shape[2] != p_check):
        raise InputError(f"block({i0}, {i1}) gave a design {Z.shape} and wrenches {y.shape}; "
                         "expected (c, k, p) and (c, k).")
    return Z, y


def _factor_blocks(block, n, w, chunk):
    """R of the weighted ``[Z | y]`` (with ``Q^T y``) and R of the unweighted Z, block by block."""
    Ra = Ru = None
    for i0, i1 in _chunks(n, chunk):
        Z, y = _block_rows(block, i0, i1)
        k, p = Z.shape[1:]
        A = Z.reshape(-1, p)
        Ru = _update_r(Ru, A)
        if w is not None:
            ww = w[i0 * k:i1 * k]
            Ra = _update_r(Ra, np.column_stack([A * ww[:, None], y.reshape(-1) * ww]))
        else:
            Ra = _update_r(Ra, np.column_stack([A, y.reshape(-1)]))
    return Ra, Ru, k, p


def _residuals_and_scores(block, n: int, chunk: int, x, w, k: int, p: int):
    """Second pass of :func:`least_squares_blocks` at the solution ``x``: the unweighted
    residuals (n, k), the weighted scores ``Z^T e`` per sample (n, p) and the weighted RSS."""
    resid = np.empty((n, k))
    S = np.empty((n, p))
    rss = 0.0
    for i0, i1 in _chunks(n, chunk):
        Z, y = _block_rows(block, i0, i1, p)
        e = y - Z @ x
        resid[i0:i1] = e
        if w is not None:
            ww = w[i0 * k:i1 * k].reshape(-1, k)
            Z, e = Z * ww[..., None], e * ww
        S[i0:i1] = np.einsum("nkp,nk->np", Z, e)
        rss += float(np.sum(e * e))
    return resid, S, rss


def least_squares_blocks(block, n: int, names=None, weights=None, groups=None,
                         covariance: str = "hac", bandwidth: float | None = None,
                         chunk: int = 16384, min_bandwidth: float = 1.0) -> LSResult:
    """:func:`least_squares` in bounded memory: the regression is asked for block by block.

    The stacked regressor is never formed: its R factor (with ``Q^T Y``) is accumulated by a
    tall-skinny QR over blocks of samples, the residuals and HAC scores by a second pass, and the
    HAC leverage adjustment asks for the design window chunk by window chunk
    (:func:`cdprid.core.hac_covariance_blocks`). The result equals :func:`least_squares`
    on the stacked arrays to rounding.

    Parameters
    ----------
    block : callable
        ``block(i0, i1) -> (Z, y)``: the design rows (i1 - i0, k, p) and measured wrenches
        (i1 - i0, k) of time samples ``i0:i1`` (k = 6 rows per sample for wrenches). Called
        several times per block (deterministic results expected).
    n : int
        Number of time samples.
    names, weights, groups, covariance, bandwidth :
        As in :func:`least_squares` (``weights`` and ``groups`` per stacked row, length n k).
    chunk : int
        Time samples per block.
    min_bandwidth : float
        Floor of the data-driven HAC bandwidth (:func:`cdprid.core.hac_covariance_blocks`).

    Returns
    -------
    LSResult
    """
    if covariance not in ("hac", "iid"):
        raise InputError(f"unknown covariance {covariance!r}; use 'hac' or 'iid'.")
    n, chunk = int(n), max(1, int(chunk))
    w = None if weights is None else np.asarray(weights, float).reshape(-1)
    if w is None and groups is not None:
        first = least_squares_blocks(block, n, names, covariance="iid", chunk=chunk)
        w = group_weights(first.residual, groups)
    Ra, Ru, k, p = _factor_blocks(block, n, w, chunk)
    N = n * k
    if N <= p:
        raise InputError(f"need more equations than parameters, got {N} rows for {p} parameters.")
    if names is None:
        names = tuple(f"x{i}" for i in range(p))
    R = Ra[:p, :p]
    _check_rank(R, names)
    x = np.linalg.solve(R, Ra[:p, p])
    resid, S, rss = _residuals_and_scores(block, n, chunk, x, w, k, p)
    sigma2 = rss / (N - p)
    cov_iid = iid_covariance(R, sigma2)
    cov, bw = cov_iid, float("nan")
    if covariance == "hac":
        def design(i0, i1):
            Z = _block_rows(block, i0, i1, p)[0]
            return Z if w is None else Z * w[i0 * k:i1 * k].reshape(-1, k)[..., None]

        cov, bw = hac_covariance_blocks(design, S, R, bandwidth=bandwidth,
                                        chunk=max(chunk, 2048), min_bandwidth=min_bandwidth)
    return LSResult(
        names=tuple(names),
        x=x,
        cov=cov,
        sigma_rho=float(np.sqrt(sigma2)),
        cond=condition_number(Ru),
        cond_scaled=condition_number(Ru, scaled=True),
        n_rows=N,
        residual=resid.reshape(-1),
        weights=w,
        cov_iid=cov_iid,
        covariance=covariance,
        hac_bandwidth=bw,
        column_norms=np.linalg.norm(Ru, axis=0),
    )


def least_squares(W_ID, Y_ID, names=None, weights=None, groups=None, rows_per_sample: int = 1,
                  covariance: str = "hac", bandwidth: float | None = None,
                  min_bandwidth: float = 1.0) -> LSResult:
    """Ordinary or weighted least squares with the paper's statistics.

    Parameters
    ----------
    W_ID : array (N, p)
        Stacked regressor (eq. 11).
    Y_ID : array (N,)
        Stacked measured wrenches ``W tau``.
    names : sequence of str, optional
    weights : array (N,), optional
        Row weights (rows are multiplied by them before solving).
    groups : array (N,) of int, optional
        If given and ``weights`` is None: two-step weighted LS, each group's weight the
        inverse of its first-pass residual RMS (force and moment rows differ in units).
    rows_per_sample : int
        Consecutive rows that belong to one time sample (6 for stacked wrenches); the HAC
        covariance sums their scores before weighting lags in time.
    covariance : {"hac", "iid"}
        Which covariance is reported as ``cov`` / ``std``. ``"hac"`` (default): the
        autocorrelation-consistent sandwich with a data-driven bandwidth
        (:func:`cdprid.core.hac_covariance`); ``"iid"``: the paper's eq. 20. Both are
        kept (``cov_iid``).
    bandwidth : float, optional
        HAC bandwidth in time samples; default data-driven (Andrews 1991).
    min_bandwidth : float
        Floor of the data-driven bandwidth (the memory of a filter every row passed).

    Returns
    -------
    LSResult

    Notes
    -----
    sigma_rho^2 = ||W (Y - A x)||^2 / (N - p) (eq. 19) and ``cov = sigma_rho^2 (A_w^T A_w)^-1``
    (eq. 20) are computed from the thin QR ``A_w = Q R``: ``cov = sigma_rho^2 R^-1 R^-T``.
    With weights, the HAC sandwich uses the weighted rows and residuals (the weighted LS
    score ``A^T w^2 e``). The QR is accumulated block by block
    (:func:`least_squares_blocks`), so no copy of W_ID is made.
    """
    if covariance not in ("hac", "iid"):
        raise InputError(f"unknown covariance {covariance!r}; use 'hac' or 'iid'.")
    A = np.asarray(W_ID, float)
    y = np.asarray(Y_ID, float).reshape(-1)
    if A.ndim != 2 or A.shape[0] != y.shape[0]:
        raise InputError(f"W_ID {A.shape} and Y_ID {y.shape} do not have the same number of rows.")
    N, p = A.shape
    if N <= p:
        raise InputError(f"need more equations than parameters, got {N} rows for {p} parameters.")
    k = int(rows_per_sample)
    if k < 1 or N % k:
        raise InputError(f"rows_per_sample={k} does not divide the {N} rows.")
    A3, y2 = A.reshape(N // k, k, p), y.reshape(N // k, k)
    return least_squares_blocks(lambda i0, i1: (A3[i0:i1], y2[i0:i1]), N // k, names,
                                weights=weights, groups=groups, covariance=covariance,
                                bandwidth=bandwidth, chunk=max(1, 65536 // k),
                                min_bandwidth=min_bandwidth)
