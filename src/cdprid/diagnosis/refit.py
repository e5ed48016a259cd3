"""Stage 4 of the diagnosis: nonlinear refit of the accepted effects (Gauss-Newton)."""

from __future__ import annotations

import numpy as np

from cdprid.diagnosis.testing import hac_cov


def refit_gauss_newton(design, theta, x0, active_idx, rotational, wrow, train, lags,
                       max_iter: int = 10, tol_std: float = 1e-3):
    """Nonlinear least squares on (x, active theta): Gauss-Newton with the exact Jacobian.

    Every iteration re-linearises the full nonlinear model (``design``: the per-cable JAX
    Jacobian of the cable side, compiled once, filtered by the matched filter) and solves the
    weighted linear LS for (x, theta_active) in closed form (x enters linearly: variable
    projection). No recompilation per active set, which keeps the diagnosis within its time
    budget. Iterations stop when no active parameter moves by more than ``tol_std`` of its
    standard deviation.

    Returns
    -------
    theta, x, th_cov, lin
        theta, x (10,), the HAC covariance of theta, and the last linearisation
        ``(y, A, C)`` shifted to the returned theta (``y - C dtheta``) when the iterations
        converged with active parameters (None otherwise): the linear model at the returned
        theta to first order in a step below ``tol_std`` standard deviations.
    """
    theta = np.array(theta, float)
    px = 10 if rotational else 4
    x = np.array(x0, float)
    ai = np.asarray(active_idx, int)
    V = np.zeros((px + len(ai), px + len(ai)))
    lin = None
    for _ in range(max_iter):
        y, A, C = design(theta, x, rotational)
        Ca = C[:, :, ai]
        Z = np.concatenate([A, Ca], axis=2) * wrow[None, :, None]
        tgt = (y + np.einsum("nij,j->ni", Ca, theta[ai])) * wrow
        p = Z.shape[2]
        beta, *_ = np.linalg.lstsq(Z[train].reshape(-1, p), tgt[train].reshape(-1), rcond=None)
        step = beta[px:] - theta[ai]
        theta[ai] = beta[px:]
        x[:px] = beta[:px]
        e = tgt[train] - np.einsum("nip,p->ni", Z[train], beta)
        V = hac_cov(Z[train], e, lags)
        scale = np.sqrt(np.clip(np.diag(V)[px:], 1e-30, None))
        if len(ai) == 0:
            break
        if np.max(np.abs(step) / scale) < tol_std:
            lin = (y - np.einsum("nij,j->ni", Ca, step), A, C)
            break
    th_cov = np.zeros((len(theta), len(theta)))
    if len(ai):
        th_cov[np.ix_(ai, ai)] = V[px:, px:]
    return theta, x, th_cov, lin
