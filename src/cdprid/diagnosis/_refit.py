"""Stage 4 of the diagnosis: nonlinear refit of the accepted effects (damped Gauss-Newton)."""

from __future__ import annotations

import numpy as np

from cdprid.base import Status
from cdprid.diagnosis._testing import hac_cov

#: step fractions tried when a full Gauss-Newton step raises the training cost
STEP_FRACTIONS = (1.0, 0.25, 0.0625, 0.015625, 0.00390625, 0.0009765625)


def _cost(y, A, wrow, train) -> float:
    """Training cost at one linearisation with the platform parameters x re-solved
    (variable projection): ``min_x || w (y - A x) ||^2`` over the training samples."""
    Z = (A[train] * wrow[None, :, None]).reshape(-1, A.shape[2])
    t = (y[train] * wrow).reshape(-1)
    beta, *_ = np.linalg.lstsq(Z, t, rcond=None)
    r = t - Z @ beta
    return float(r @ r)


def _gn_step(y, A, C, theta, ai, wrow, train, lags, px):
    """One Gauss-Newton solve at a linearisation: ``(x, step of theta[ai], HAC cov)``."""
    Ca = C[:, :, ai]
    Z = np.concatenate([A, Ca], axis=2) * wrow[None, :, None]
    tgt = (y + np.einsum("nij,j->ni", Ca, theta[ai])) * wrow
    p = Z.shape[2]
    beta, *_ = np.linalg.lstsq(Z[train].reshape(-1, p), tgt[train].reshape(-1), rcond=None)
    e = tgt[train] - np.einsum("nip,p->ni", Z[train], beta)
    return beta[:px], beta[px:] - theta[ai], hac_cov(Z[train], e, lags)


def refit_gauss_newton(design, theta, x0, active_idx, rotational, wrow, train, lags,
                       max_iter: int = 10, tol_std: float = 1e-3):
    """Nonlinear least squares on (x, active theta): damped Gauss-Newton, exact Jacobian.

    Every iteration re-linearises the full nonlinear model (``design``: the per-cable JAX
    Jacobian of the cable side, compiled once, filtered by the matched filter) and solves the
    weighted linear LS for (x, theta_active) in closed form (x enters linearly: variable
    projection). A step that raises the training cost (the geometry effects are strongly
    nonlinear on real data: an undamped step once put an exit point 10^8 m away) is shortened
    by the fractions :data:`STEP_FRACTIONS`; when none lowers the cost the refit stops where
    it is, not converged. Iterations stop when no active parameter moves by more than
    ``tol_std`` of its standard deviation.

    Returns
    -------
    theta, x, th_cov, lin, status
        theta, x (10,), the HAC covariance of theta, the last linearisation ``(y, A, C)``
        shifted to the returned theta (``y - C dtheta``) when the iterations converged with
        active parameters (None otherwise), and how the refit ended
        (:class:`cdprid.base.Status`: converged, max steps, or failed when no step lowers
        the cost).
    """
    theta = np.array(theta, float)
    px = 10 if rotational else 4
    x = np.array(x0, float)
    ai = np.asarray(active_idx, int)
    V = np.zeros((px + len(ai), px + len(ai)))
    lin, status = None, Status.MAX_STEPS
    y, A, C = design(theta, x, rotational)
    if not all(np.all(np.isfinite(v)) for v in (y, A, C)):
        # e.g. a start whose clock offset reaches past the tension stream (never extrapolated)
        return theta, x, np.zeros((len(theta), len(theta))), None, Status.FAILED
    for _ in range(max_iter):
        try:
            xs, step, V = _gn_step(y, A, C, theta, ai, wrow, train, lags, px)
        except np.linalg.LinAlgError:  # a singular or non-finite solve: no model here
            status = Status.FAILED
            break
        x[:px] = xs
        if len(ai) == 0:
            status = Status.CONVERGED
            break
        scale = np.sqrt(np.clip(np.diag(V)[px:], 1e-30, None))
        if np.max(np.abs(step) / scale) < tol_std:
            theta[ai] += step
            lin = (y - np.einsum("nij,j->ni", C[:, :, ai], step), A, C)
            status = Status.CONVERGED
            break
        cost = _cost(y, A, wrow, train)
        for frac in STEP_FRACTIONS:
            trial = theta.copy()
            trial[ai] += frac * step
            yt, At, Ct = design(trial, x, rotational)
            if _cost(yt, At, wrow, train) <= cost:
                break
        else:  # no step lowers the cost: stop here (not converged)
            status = Status.FAILED
            break
        theta, (y, A, C) = trial, (yt, At, Ct)
    th_cov = np.zeros((len(theta), len(theta)))
    if len(ai):
        th_cov[np.ix_(ai, ai)] = V[px:, px:]
    return theta, x, th_cov, lin, status
