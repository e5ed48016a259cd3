"""The Cramer-Rao bound of an identification: how well its own recording could do at best.

Errors-in-variables model of one recording (poses and tensions both noisy):

* the true motion is unknown: each pose coordinate (position, and a small rotation vector
  about the measured orientation) is a uniform cubic B-spline with knots every ``h`` s, its
  coefficients ``c`` a nuisance; the measured poses are the spline plus white noise
  (``sigma_p`` per position axis, ``sigma_r`` per rotation axis);
* at each pose sample the cable side ``W(q) tau_meas`` equals the model ``Y(q, a, omega,
  alpha) theta`` up to the load-cell noise mapped by ``W``: covariance ``W S W^T`` with ``S =
  diag(s_i^2)`` (per cable, scaled by the tension samples per pose sample); the internal
  forces of a redundant robot carry no information on theta.

The Fisher information of ``(theta, c)`` is accumulated sample by sample: the per-sample
Jacobians of the residual with respect to the pose, acceleration, rotation, angular rate and
angular acceleration come from ``jax.jacfwd`` (vmapped), and are chained with the four
non-zero B-spline basis functions (value, first and second derivatives). The bound on theta
is the inverse of the Schur complement ``I_tt - I_tc I_cc^-1 I_ct``: the price of not knowing
the trajectory is included. With vanishing pose noise it becomes the GLS bound
``(sum Y^T (W S W^T)^+ Y)^-1`` (tested).
"""

from __future__ import annotations

import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.model._dynamics import regressor_full, regressor_translation
from cdprid.model._geometry import wrench_matrix

__all__ = ["CRBResult", "crb", "bspline_basis", "sample_jacobians"]

#: most spline knots per coordinate (longer recordings get a wider spacing; see ``note``)
MAX_KNOTS = 400


@dataclasses.dataclass(frozen=True)
class CRBResult:
    """The bound on theta (covariance and std) and what it assumed."""

    cov: np.ndarray
    std: np.ndarray
    knot_spacing_s: float
    noise: dict
    note: str


def bspline_basis(u: np.ndarray):
    """Uniform cubic B-spline basis at positions ``u`` (in knot units): the index of the
    first of the four non-zero functions and their values and first and second derivatives
    with respect to ``u``, each ``(n, 4)``."""
    u = np.asarray(u, float)
    i = np.floor(u).astype(int)
    f = (u - i)[:, None]
    b = np.concatenate([(1 - f) ** 3, 3 * f**3 - 6 * f**2 + 4, -3 * f**3 + 3 * f**2 + 3 * f + 1,
                        f**3], axis=1) / 6.0
    d1 = np.concatenate([-((1 - f) ** 2), 3 * f**2 - 4 * f, -3 * f**2 + 2 * f + 1, f**2],
                        axis=1) / 2.0
    d2 = np.concatenate([1 - f, 3 * f - 2, 1 - 3 * f, f], axis=1)
    return i, b, d1, d2


def _residual(robot, model: str, theta, tau, p, R, a, w, al, xi):
    """Cable side minus model at one sample with the motion perturbed by ``xi`` (15,):
    position, acceleration, rotation vector (base frame), angular rate, angular accel."""
    dp, da, dphi, dw, dal = (xi[3 * k:3 * k + 3] for k in range(5))
    # first order in the rotation vector is all the Jacobian at xi = 0 needs
    Rk = (jnp.eye(3) + jnp.array([[0.0, -dphi[2], dphi[1]], [dphi[2], 0.0, -dphi[0]],
                                  [-dphi[1], dphi[0], 0.0]])) @ R
    W = wrench_matrix(robot, p + dp, Rk)
    g = robot.gravity
    if model == "full":
        Y = regressor_full(Rk, a + da, w + dw, al + dal, g)
    else:
        Y = regressor_translation(Rk, a + da, g)
    return W @ tau - Y @ theta


@functools.partial(jax.jit, static_argnums=(1,))
def sample_jacobians(robot, model, theta, tau, p, R, a, w, al):
    """Per-sample ``(G, Y, W)``: d residual / d xi (n, 6, 15), regressor, wrench matrix.

    ``xi`` perturbs position, acceleration, rotation vector (base frame), angular rate and
    angular acceleration (3 each); shared by the bound and the errors-in-variables weighting
    of identify (one trace for both when they ask for the same samples)."""

    def one(tk, pk, Rk, ak, wk, alk):
        f = functools.partial(_residual, robot, model, theta, tk, pk, Rk, ak, wk, alk)
        G = jax.jacfwd(f)(jnp.zeros(15))
        W = wrench_matrix(robot, pk, Rk)
        Y = (regressor_full(Rk, ak, wk, alk, robot.gravity) if model == "full"
             else regressor_translation(Rk, ak, robot.gravity))
        return G, Y, W

    return jax.vmap(one)(tau, p, R, a, w, al)


def _pinv_sym(S: np.ndarray, rel: float = 1e-10) -> np.ndarray:
    """Pseudo-inverses of symmetric PSD matrices ``(n, k, k)`` (rank-deficient for 4 cables or
    a point-mass platform: no information in the null directions)."""
    w, V = np.linalg.eigh(S)
    cut = rel * np.max(w, axis=1, keepdims=True)
    inv = np.where(w > cut, 1.0 / np.where(w > cut, w, 1.0), 0.0)
    return np.einsum("nij,nj,nkj->nik", V, inv, V)


DENSE_KNOTS = 1500
"""Up to this many nuisance knots (150 s at 0.1 s spacing) the Schur complement is solved
densely; above, by scipy's banded Cholesky (the dense matrix would grow as the square)."""


def _schur_banded(Itt, Itc_loc, Icc_loc, cols, nc: int, bw: int):
    """The Schur complement ``I_tt - I_tc I_cc^-1 I_ct`` of the nuisance coefficients,
    the per-sample blocks scatter-added into ``I_tc`` and the banded ``I_cc`` (bandwidth
    ``bw``: a sample touches 4 consecutive knots), solved by banded Cholesky."""
    p = Itt.shape[0]
    # scatter-add of the local blocks (bincount: one pass over the samples)
    Itc = np.stack([np.bincount(cols.ravel(), weights=Itc_loc[:, j, :].ravel(), minlength=nc)
                    for j in range(p)])
    flat = (cols[:, :, None] * nc + cols[:, None, :]).ravel()
    Icc = np.bincount(flat, weights=Icc_loc.ravel(), minlength=nc * nc).reshape(nc, nc)
    ridge = 1e-12 * float(np.max(np.diag(Icc)))
    Icc[np.diag_indices(nc)] += ridge
    if nc <= DENSE_KNOTS:  # a dense solve is instant here, and keeps scipy off identify's path
        return Itt - Itc @ np.linalg.solve(Icc, Itc.T)
    from scipy.linalg import solveh_banded

    # I_cc is banded (a sample touches 4 consecutive knots): banded Cholesky solve
    ab = np.zeros((bw + 1, nc))
    for d in range(bw + 1):
        ab[d, :nc - d] = np.diagonal(Icc, -d)
    return Itt - Itc @ solveh_banded(ab, Itc.T, lower=True)


def crb(robot, model: str, theta, t, position, R, acceleration, omega, alpha, tension,
        tension_std, position_std: float, rotation_std: float | None,
        knot_spacing_s: float = 0.1) -> CRBResult:
    """The errors-in-variables Cramer-Rao bound on ``theta`` for one recording.

    Parameters
    ----------
    robot : CableRobot
    model : {"translation", "full"}
    theta : (p,) the parameters at which the bound is evaluated (the estimate)
    t : (n,) pose sample times, s (the samples the identification used)
    position, R, acceleration, omega, alpha : the estimated motion at ``t`` (base frame)
    tension : (n, m) tensions at ``t``
    tension_std : (m,) load-cell noise std per pose sample, N
    position_std : float
        Position noise std per axis, m.
    rotation_std : float or None
        Orientation noise std per axis, rad; None when the dataset has no orientations
        (the orientation is then known: not a nuisance).
    knot_spacing_s : float
        Spline knot spacing, s (widened so that no coordinate has more than
        :data:`MAX_KNOTS` knots).

    Returns
    -------
    CRBResult
    """
    t = np.asarray(t, float)
    n = len(t)
    span = float(t[-1] - t[0])
    h = max(float(knot_spacing_s), span / (MAX_KNOTS - 3))
    K = int(np.floor(span / h)) + 4  # coefficients per coordinate
    rot = rotation_std is not None
    ndof = 6 if rot else 3
    G, Y, W = (np.asarray(z) for z in sample_jacobians(
        robot, model, jnp.asarray(theta, float), jnp.asarray(tension, float),
        jnp.asarray(position, float), jnp.asarray(R, float), jnp.asarray(acceleration, float),
        jnp.asarray(omega, float), jnp.asarray(alpha, float)))
    s2 = np.square(np.broadcast_to(np.asarray(tension_std, float), (W.shape[2],)))
    Sig = np.einsum("nim,m,njm->nij", W, s2, W)
    P = _pinv_sym(Sig)
    i0, b, d1, d2 = bspline_basis((t - t[0]) / h)
    i0 = np.clip(i0, 0, K - 4)
    # local Jacobian (n, 6, 4 knots, ndof) of the residual w.r.t. the spline coefficients
    Gp, Ga, Gr, Gw, Gal = (G[:, :, 3 * k:3 * k + 3] for k in range(5))
    Lp = Gp[:, :, None, :] * b[:, None, :, None] + Ga[:, :, None, :] * (d2 / h**2)[:, None, :,
                                                                                 None]
    blocks = [Lp]
    if rot:
        Lr = (Gr[:, :, None, :] * b[:, None, :, None]
              + Gw[:, :, None, :] * (d1 / h)[:, None, :, None]
              + Gal[:, :, None, :] * (d2 / h**2)[:, None, :, None])
        blocks.append(Lr)
    L = np.concatenate(blocks, axis=3).reshape(n, 6, 4 * ndof)  # knot-major, dof inside
    cols = ((i0[:, None] + np.arange(4)[None, :])[:, :, None] * ndof
            + np.arange(ndof)[None, None, :]).reshape(n, 4 * ndof)
    nc = K * ndof
    PL = np.einsum("nij,njk->nik", P, L)
    Itt = np.einsum("nip,nij,njq->pq", Y, P, Y)
    Itc_loc = -np.einsum("nip,nik->npk", Y, PL)  # (n, p, 24)
    Icc_loc = np.einsum("nik,nil->nkl", L, PL)  # (n, 24, 24)
    # pose observations: the spline values seen with noise
    obs = np.zeros((n, 4 * ndof, 4 * ndof))
    sd = np.array([position_std] * 3 + ([rotation_std] * 3 if rot else []), float)
    inv_var = 1.0 / np.maximum(sd, 1e-9) ** 2
    for d in range(ndof):
        idx = np.arange(4) * ndof + d
        obs[:, idx[:, None], idx[None, :]] += inv_var[d] * b[:, :, None] * b[:, None, :]
    Icc_loc = Icc_loc + obs
    S = _schur_banded(Itt, Itc_loc, Icc_loc, cols, nc, 4 * ndof - 1)
    cov = np.linalg.pinv(0.5 * (S + S.T))
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    noise = {"tension_N": [float(v) for v in np.sqrt(s2)], "position_m": float(position_std),
             "orientation_rad": None if not rot else float(rotation_std)}
    note = ("Cramer-Rao bound with poses and tensions noisy (trajectory a cubic B-spline "
            f"nuisance, knots every {h:.3g} s)")
    return CRBResult(cov, std, h, noise, note)
