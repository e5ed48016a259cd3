# ruff: noqa: F722  (jaxtyping shape strings)
"""Physical consistency of inertial parameters.

A rigid body has ``m > 0`` and an inertia about its centre of mass ``I_G`` that is positive
definite with principal moments obeying the triangle inequalities
(``I_1 <= I_2 + I_3`` and permutations). Least squares does not know that: on poorly excited
data it can return a negative mass or an impossible inertia. This module

* converts the full model's inertia about P to the inertia about G with its Jacobian
  (:func:`inertia_about_com`), for the output and its covariance,
* states which physical conditions an estimate violates (:func:`physical_warnings`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float

__all__ = [
    "SIGNIFICANCE_Z", "inertia_about_com", "inertia_com_matrix", "margin_z", "physical_fit",
    "physical_warnings", "pseudo_inertia_to_vector",
    "realisability_margin", "violations",
]


def inertia_com_matrix(x: Float[np.ndarray, " 10"]) -> Float[np.ndarray, "3 3"]:
    """Inertia about the centre of mass (platform frame) from the full parameter vector.

    ``I_G = I_P - m (|s|^2 1 - s s^T)`` with ``s = (m s_G) / m`` (parallel-axis theorem).
    Traceable JAX.

    Parameters
    ----------
    x : array (10,)
        ``(m, m xG, m yG, m zG, Ixx, Ixy, Ixz, Iyy, Iyz, Izz)`` in kg, kg m and kg m^2
        (inertia about the platform's reference point P, platform frame).

    Returns
    -------
    jax.Array (3, 3)
        ``I_G``, kg m^2.
    """
    x = jnp.asarray(x)
    m = x[0]
    s = x[1:4] / m
    Ixx, Ixy, Ixz, Iyy, Iyz, Izz = x[4:10]
    I_P = jnp.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
    return I_P - m * ((s @ s) * jnp.eye(3) - jnp.outer(s, s))


def _to_g(x):
    I = inertia_com_matrix(x)
    return jnp.concatenate([x[:4], jnp.array([I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2],
                                               I[2, 2]])])


def inertia_about_com(x: Float[np.ndarray, " 10"]
                      ) -> tuple[Float[np.ndarray, " 10"], Float[np.ndarray, "10 10"]]:
    """The full parameter vector with the inertia about G instead of P, and its Jacobian.

    Parameters
    ----------
    x : ndarray (10,)
        ``[m, mxG, myG, mzG, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` with the inertia about P.

    Returns
    -------
    x_G : ndarray (10,)
        Same order, inertia about the centre of mass (platform frame).
    J : ndarray (10, 10)
        ``d x_G / d x`` (propagate a covariance as ``J C J^T``).
    """
    xj = jnp.asarray(np.asarray(x, float))
    return np.asarray(_to_g(xj)), np.asarray(jax.jacfwd(_to_g)(xj))


def realisability_margin(x):
    """``min(smallest principal moment, I_1 + I_2 - I_3)`` of the inertia about G.

    Negative when the body is not realisable; traceable JAX (for its gradient).

    Parameters
    ----------
    x : array (10,)
        ``(m, m xG, m yG, m zG, Ixx, Ixy, Ixz, Iyy, Iyz, Izz)`` (SI units, about P).

    Returns
    -------
    jax.Array ()
        The margin, kg m^2.
    """
    ev = jnp.linalg.eigvalsh(inertia_com_matrix(x))
    return jnp.minimum(ev[0], ev[0] + ev[1] - ev[2])


def margin_z(x: Float[np.ndarray, " 10"], cov: Float[np.ndarray, "10 10"]) -> float:
    """The realisability margin divided by its standard deviation (delta method).

    Parameters
    ----------
    x : array (10,)
        The full parameter vector (SI units, about P).
    cov : array (10, 10)
        Its covariance.

    Returns
    -------
    float
        :func:`realisability_margin` over its std (dimensionless); +-inf when the std is 0.
    """
    xj = jnp.asarray(np.asarray(x, float))
    g = float(realisability_margin(xj))
    grad = np.asarray(jax.grad(realisability_margin)(xj))
    sd = float(np.sqrt(max(grad @ np.asarray(cov) @ grad, 0.0)))
    return g / sd if sd > 0 else (np.inf if g >= 0 else -np.inf)


def violations(x: Float[np.ndarray, " p"], model: str) -> list[str]:
    """The physical conditions that the estimate ``x`` violates.

    Parameters
    ----------
    x : array (p,)
        Estimate (SI units): the 4 translation parameters or the full 10.
    model : {"translation", "full"}
        ``"translation"`` checks the mass only.

    Returns
    -------
    list of str
        One phrase per violated condition (mass <= 0, inertia about G not positive definite,
        triangle inequality); empty when realisable.
    """
    x = np.asarray(x, float)
    out = []
    if x[0] <= 0:
        out.append(f"m = {x[0]:.4g} kg <= 0")
        return out
    if model != "full":
        return out
    I = np.asarray(inertia_com_matrix(x))
    ev = np.linalg.eigvalsh(0.5 * (I + I.T))
    tol = 1e-9 * max(abs(ev[2]), 1e-300)  # round-off on the boundary (a degenerate body)
    if ev[0] < -tol:
        out.append(f"the inertia about the centre of mass is not positive definite "
                   f"(smallest principal moment {ev[0]:.3g} kg m^2)")
    elif ev[2] > ev[0] + ev[1] + tol:
        out.append(f"the principal moments {ev[0]:.3g}, {ev[1]:.3g}, {ev[2]:.3g} kg m^2 violate "
                   "the triangle inequality")
    return out


SIGNIFICANCE_Z = 2.0
"""An inertia violation smaller than this many standard deviations of the margin is noise."""


def physical_warnings(x: Float[np.ndarray, " p"], model: str, cov=None
                      ) -> tuple[list[str], list[str]]:
    """Warnings and notes about the physical realisability of ``x``.

    Parameters
    ----------
    x : ndarray (p,)
    model : {"translation", "full"}
    cov : ndarray (p, p), optional
        Covariance of ``x``. An inertia violation within :data:`SIGNIFICANCE_Z` standard
        deviations of the margin (:func:`realisability_margin`) is a note, not a warning: the
        data cannot tell it from a realisable body. ``m <= 0`` is always a warning.

    Returns
    -------
    warnings, notes : list of str
    """
    v = violations(x, model)
    if not v:
        return [], []
    if x[0] > 0 and cov is not None and margin_z(x, cov) > -SIGNIFICANCE_Z:
        return [], [f"the inertia estimate is not physically realisable ({'; '.join(v)}) but "
                    f"within {SIGNIFICANCE_Z:g} std of a realisable body: its std is large "
                    "(little rotation); --physical gives the constrained estimate."]
    return [f"physically impossible estimate: {'; '.join(v)} (too little excitation or a "
            "model mismatch; try --physical, more rotation, or the translation model)."], []


# ----------------------------------------------------------------------------- --physical


def pseudo_inertia_to_vector(L):
    """Full parameter vector from the lower-triangular 4x4 factor of the pseudo-inertia.

    ``J = L L^T = [[Sigma, m s_G], [m s_G^T, m]]`` with ``Sigma = tr(I_P)/2 1 - I_P`` (about P).
    J positive definite <=> a physically realisable body (m > 0, I_G positive definite and
    triangle inequalities; Wensing, Kim and Slotine 2017). Traceable JAX.

    Parameters
    ----------
    L : jax.Array (4, 4)
        Lower-triangular factor of the pseudo-inertia (entries in sqrt(kg) m and sqrt(kg)).

    Returns
    -------
    jax.Array (10,)
        ``(m, m xG, m yG, m zG, Ixx, Ixy, Ixz, Iyy, Iyz, Izz)``, kg, kg m, kg m^2.
    """
    J = L @ L.T
    S = J[:3, :3]
    I = jnp.trace(S) * jnp.eye(3) - S
    return jnp.concatenate([J[3, 3][None], J[:3, 3],
                            jnp.array([I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]])])


_TRIL = np.tril_indices(4)


def _theta_to_x(theta):
    """Cholesky-factor parameters (10,) -> full parameter vector.

    ``L L^T`` is positive semi-definite for every real ``L``, so ``theta`` is unconstrained. The
    log-Cholesky variant (log of the diagonal) is not used: when the constraint is active the
    optimum lies on the boundary, where the log would run to -inf and the solver never stops.
    """
    L = jnp.zeros((4, 4), theta.dtype).at[_TRIL].set(theta)
    return pseudo_inertia_to_vector(L)


def _x_to_theta(x, floor: float = 1e-9):
    """A Cholesky-factor start from ``x``, its pseudo-inertia's eigenvalues floored (projection)."""
    x = np.asarray(x, float)
    m = max(x[0], floor)
    I_P = np.array([[x[4], x[5], x[6]], [x[5], x[7], x[8]], [x[6], x[8], x[9]]])
    S = 0.5 * np.trace(I_P) * np.eye(3) - I_P
    J = np.block([[S, x[1:4, None]], [x[None, 1:4], np.array([[m]])]])
    w, V = np.linalg.eigh(0.5 * (J + J.T))
    J = (V * np.maximum(w, floor * max(1.0, w.max()))) @ V.T
    return np.linalg.cholesky(J)[_TRIL].copy()


def physical_fit(x_ls: Float[np.ndarray, " 10"], R: Float[np.ndarray, "10 10"],
                 cov: Float[np.ndarray, "10 10"], max_steps: int = 5000
                 ) -> tuple[Float[np.ndarray, " 10"], Float[np.ndarray, "10 10"]]:
    """The least-squares estimate constrained to a physically realisable body.

    Minimises ``||R (x(theta) - x_ls)||^2`` (the LS cost up to a constant, ``R`` the QR factor
    of the weighted regressor) over the Cholesky-factor parameters ``theta`` of the pseudo-inertia
    (:func:`pseudo_inertia_to_vector`), with optimistix' BFGS; ``sol.result`` is
    checked. The covariance is propagated by the delta method through the constrained solution
    (``cov`` the covariance of ``x_ls``; on the boundary of the realisable set this is the
    linearisation of the active constraint). A realisable ``x_ls`` is returned unchanged.

    Parameters
    ----------
    x_ls : ndarray (10,)
        The least-squares estimate (SI units, about P).
    R : ndarray (10, 10)
        Upper-triangular QR factor of the (weighted) regressor.
    cov : ndarray (10, 10)
        Covariance of ``x_ls``.
    max_steps : int
        Most BFGS iterations.

    Returns
    -------
    x_phys : ndarray (10,)
        The constrained estimate (SI units).
    cov_phys : ndarray (10, 10)
        Its covariance.

    Raises
    ------
    cdprid.base.ConvergenceError
        When the solver does not converge.
    """
    import optimistix as optx

    from cdprid.base import ConvergenceError

    xl = jnp.asarray(np.asarray(x_ls, float))
    Rj = jnp.asarray(np.asarray(R, float))

    def resid(theta, _):
        return Rj @ (_theta_to_x(theta) - xl)

    if not violations(x_ls, "full"):
        return np.asarray(x_ls, float), np.asarray(cov, float)
    # BFGS on the quadratic cost: Levenberg-Marquardt stalls on the boundary of the PSD cone,
    # where the Cholesky parametrisation's Jacobian is singular
    sol = optx.minimise(lambda th, a: jnp.sum(resid(th, a) ** 2), optx.BFGS(rtol=1e-8, atol=1e-10),
                        jnp.asarray(_x_to_theta(x_ls)), max_steps=max_steps, throw=False)
    if sol.result != optx.RESULTS.successful:
        raise ConvergenceError("the physically constrained fit (--physical) did not converge "
                               f"({sol.result}).")
    theta = sol.value
    x = np.asarray(_theta_to_x(theta))
    Jx = np.asarray(jax.jacfwd(_theta_to_x)(theta))
    M = np.asarray(R).T @ np.asarray(R)
    H = np.linalg.pinv(Jx.T @ M @ Jx)
    G = Jx @ H @ Jx.T @ M  # d x_phys / d x_ls (linearised)
    return x, G @ np.asarray(cov) @ G.T
