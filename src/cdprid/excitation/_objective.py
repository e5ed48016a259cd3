"""Identifiability objectives of the excitation: stacked regressor, condition numbers
(exact and smooth), D-optimality, predicted sigma."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from cdprid.core import regressors
from cdprid.model import TrajectoryState, quat_to_matrix

OBJECTIVES = ("cond", "cond_scaled", "dopt", "sigma")


def stacked_regressor(states: TrajectoryState, gravity, model: str = "translation"):
    """W_ID of eq. (11) from analytic motion states (:func:`cdprid.core.regressors`).

    Parameters
    ----------
    states : TrajectoryState
        n samples of acceleration (m/s^2), quaternion, angular velocity (rad/s) and
        acceleration (rad/s^2).
    gravity : array (3,)
        Gravity, base frame, m/s^2.
    model : {"translation", "full"}

    Returns
    -------
    array (6 n, p)
        p = 4 or 10.
    """
    R = jax.vmap(quat_to_matrix)(states.q)
    A = regressors(model, R, states.a, states.omega, states.alpha, gravity)
    return A.reshape(-1, A.shape[-1])


def _scale_columns(M):
    d = jnp.sqrt(jnp.diag(M))
    return M / (d[:, None] * d[None, :])


def information_cond(W_ID, scaled: bool = False):
    """Exact cond(W_ID) from the eigenvalues of ``M = W_ID^T W_ID``.

    Differentiable when the extreme eigenvalues are simple.

    Parameters
    ----------
    W_ID : array (r, p)
    scaled : bool
        Scale the columns to unit norm first.

    Returns
    -------
    scalar array
        ``sqrt(lambda_max / lambda_min)`` (dimensionless).
    """
    M = W_ID.T @ W_ID
    if scaled:
        M = _scale_columns(M)
    lam = jnp.linalg.eigvalsh(M)
    return jnp.sqrt(lam[-1] / lam[0])


def _log_trace_power(M, n_squarings: int):
    """log tr(M^(2^n)) by normalised repeated squaring (M symmetric positive definite)."""
    s0 = jnp.trace(M)
    X = M / s0
    L = jnp.log(s0)
    for _ in range(n_squarings):
        X = X @ X
        s = jnp.trace(X)
        X = X / s
        L = 2.0 * L + jnp.log(s)
    return L


def soft_log_cond(M, n_squarings: int = 5):
    """Smooth upper bound of ``log cond(W_ID)`` from the information matrix M.

    ``0.5 (log tr(M^k) - log tr(M^-k)) / k`` with ``k = 2^n_squarings``; exceeds the exact
    value by at most ``log(p) / k``.

    Parameters
    ----------
    M : array (p, p)
        ``W_ID^T W_ID``, symmetric positive definite.
    n_squarings : int

    Returns
    -------
    scalar array
    """
    k = 2.0**n_squarings
    p = M.shape[0]
    Minv = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(M), jnp.eye(p))
    Minv = 0.5 * (Minv + Minv.T)
    return 0.5 * (_log_trace_power(M, n_squarings) + _log_trace_power(Minv, n_squarings)) / k


def d_optimality(W_ID, delta: float = 1e-9):
    """D-optimality criterion ``-log det(W_ID^T W_ID / n_rows + delta I)`` (smaller is better).

    Parameters
    ----------
    W_ID : array (r, p)
    delta : float
        Regularisation added to the diagonal.

    Returns
    -------
    scalar array
    """
    p = W_ID.shape[1]
    M = W_ID.T @ W_ID / W_ID.shape[0] + delta * jnp.eye(p)
    return -2.0 * jnp.sum(jnp.log(jnp.diag(jnp.linalg.cholesky(M))))


def predicted_sigma(W_ID, sigma_rho: float = 1.0):
    """Predicted standard deviations ``sigma_rho sqrt(diag((W^T W)^-1))`` (eq. 20), via QR.

    Parameters
    ----------
    W_ID : array (r, p)
    sigma_rho : float
        Residual standard deviation, N (or N m).

    Returns
    -------
    array (p,)
        In the parameters' units (kg, kg m, kg m^2) for ``sigma_rho`` in N.
    """
    R = jnp.linalg.qr(W_ID, mode="r")
    Rinv = jax.scipy.linalg.solve_triangular(R, jnp.eye(R.shape[0]), lower=False)
    return sigma_rho * jnp.sqrt(jnp.sum(Rinv**2, axis=1))
