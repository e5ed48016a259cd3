"""Square-root recursive least squares (QR updates, no inverse) as one lax.scan."""

from __future__ import annotations

import contextlib
import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.identify._online_types import RLSResult


def _x64_scope():
    if jax.config.read("jax_enable_x64"):
        return contextlib.nullcontext()
    return jax.enable_x64(True)  # pragma: no cover - callers normally enable x64


def _check_forgetting(f):
    if not (isinstance(f, (int, float)) and math.isfinite(f) and 0.0 < f <= 1.0):
        raise InputError(f"the forgetting factor must be a number in (0, 1], got {f!r}.")


def _rls_init(x0, prior_weight):
    p = x0.shape[0]
    r = jnp.sqrt(prior_weight)
    S = jnp.zeros((p + 1, p + 1), x0.dtype)
    S = S.at[:p, :p].set(r * jnp.eye(p, dtype=x0.dtype)).at[:p, p].set(r * x0)
    return S


def _rls_update(S, n_rows, A, y, lam, use):
    """Square-root information update with the rows ``[A y]`` (weight ``use`` in {0, 1})."""
    lam = jnp.where(use, lam, 1.0)
    w = jnp.where(use, 1.0, 0.0)
    Z = jnp.concatenate([jnp.sqrt(lam) * S, w * jnp.concatenate([A, y[:, None]], axis=1)], axis=0)
    S = jnp.linalg.qr(Z, mode="r")
    n_rows = lam * n_rows + w * A.shape[0]
    return S, n_rows


def _rls_solution(S, n_rows):
    """Estimate, standard deviations and sigma_rho from the factor (eqs. 15, 19, 20)."""
    p = S.shape[0] - 1
    R = S[:p, :p]
    Rinv = jax.scipy.linalg.solve_triangular(R, jnp.eye(p, dtype=S.dtype), lower=False)
    x = Rinv @ S[:p, p]
    diagP = jnp.sum(Rinv**2, axis=1)
    dof = n_rows - p
    s2 = jnp.where(dof > 0, S[p, p] ** 2 / jnp.where(dof > 0, dof, 1.0), jnp.nan)
    return x, jnp.sqrt(s2 * diagP), jnp.sqrt(s2)


@jax.jit
def _rls_scan(A, y, lam, x0, prior_weight):
    def body(carry, inp):
        S, n = carry
        Ak, yk = inp
        S, n = _rls_update(S, n, Ak, yk, lam, True)
        x, sig, srho = _rls_solution(S, n)
        return (S, n), (x, sig, srho)

    S0 = _rls_init(x0, prior_weight)
    (S, n), out = jax.lax.scan(body, (S0, jnp.zeros((), A.dtype)), (A, y))
    return S, n, out


def recursive_least_squares(A, y, forgetting: float = 1.0, x0=None,
                            prior_weight: float = 1e-9) -> RLSResult:
    """Recursive least squares over given per-sample rows (the RLS kernel alone).

    Parameters
    ----------
    A : array (n, r, p)
        Regressor rows of each sample (r = 6 for a CDPR).
    y : array (n, r)
        Right-hand sides.
    forgetting : float
        lambda in (0, 1]; 1 = growing-memory least squares.
    x0 : array (p,), optional
        Prior mean (default zeros).
    prior_weight : float
        delta of the prior ``delta ||x - x0||^2`` (>= 0; keeps R invertible from sample 0).

    Returns
    -------
    RLSResult
    """
    A = np.asarray(A, np.float64)
    y = np.asarray(y, np.float64)
    if A.ndim != 3 or y.shape != A.shape[:2]:
        raise InputError(f"A must be (n, r, p) and y (n, r); got {A.shape} and {y.shape}.")
    _check_forgetting(forgetting)
    p = A.shape[2]
    x0 = np.zeros(p) if x0 is None else np.asarray(x0, np.float64).reshape(p)
    with _x64_scope():
        S, n, (x, sig, srho) = _rls_scan(jnp.asarray(A), jnp.asarray(y), jnp.asarray(forgetting),
                                         jnp.asarray(x0), jnp.asarray(float(prior_weight)))
        S = np.asarray(S)
    Rinv = np.linalg.solve(S[:p, :p], np.eye(p))
    srho = np.asarray(srho)
    return RLSResult(np.asarray(x), np.asarray(sig), srho, srho[-1] ** 2 * Rinv @ Rinv.T, S)
