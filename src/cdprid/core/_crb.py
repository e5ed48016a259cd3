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

from cdprid.base import cached_executable
from cdprid.core._regression import CHUNK
from cdprid.model import regressor_full, regressor_translation, wrench_matrix

__all__ = ["CRBResult", "crb", "bspline_basis", "block_banded_solve", "sample_jacobians",
           "regressor_jacobians"]

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


def _small_rotation(dphi, R):
    """``(I + [dphi]x) R``: first order in the rotation vector is all a Jacobian at 0 needs."""
    return (jnp.eye(3) + jnp.array([[0.0, -dphi[2], dphi[1]], [dphi[2], 0.0, -dphi[0]],
                                    [-dphi[1], dphi[0], 0.0]])) @ R


def _regressor(robot, model: str, R, a, w, al):
    return (regressor_full(R, a, w, al, robot.gravity) if model == "full"
            else regressor_translation(R, a, robot.gravity))


def sample_jacobians(robot, model, theta, tau, p, R, a, w, al):
    """Per-sample ``(G, Y, W)``: d residual / d xi, regressor, wrench matrix.

    The residual is the cable side minus the model, ``W(p, R) tau - Y(R, a, omega, alpha)
    theta``; ``xi`` perturbs position, acceleration, rotation vector (base frame), angular rate
    and angular acceleration (3 each). The cable side is differentiated in the 6 pose
    directions only (the pulley geometry is the costly part; the 9 rate directions do not
    reach it), the model side in its 12. Shared by the bound and the errors-in-variables
    weighting of identify (one trace for both when they ask for the same samples).

    Parameters
    ----------
    robot : CableRobot
    model : {"translation", "full"}
        Static.
    theta : jax.Array (p,)
        Parameters (SI units).
    tau : jax.Array (n, m)
        Tensions, N.
    p : jax.Array (n, 3)
        Positions, base frame, m.
    R : jax.Array (n, 3, 3)
        Orientations (platform to base).
    a, w, al : jax.Array (n, 3)
        Acceleration (m/s^2), angular rate (rad/s), angular acceleration (rad/s^2), base frame.

    Returns
    -------
    G : array (n, 6, 15)
        d residual / d xi (N per unit of each input).
    Y : array (n, 6, p)
        Regressors.
    W : array (n, 6, m)
        Wrench matrices.

    Notes
    -----
    The cable side does not depend on ``theta`` and is most of the cost (77 of 85 ms for
    5000 samples of an 8-cable robot): the last one computed is kept (keyed by the robot and
    the contents of ``tau``, ``p`` and ``R``), so the errors-in-variables weighting, its bias
    correction and the bound, which ask for the same samples at three ``theta``, compute it
    once. Called with concrete arrays the results are NumPy arrays; inside a JAX trace, JAX
    arrays (nothing kept).
    """
    leaves = jax.tree_util.tree_leaves((robot, theta, tau, p, R, a, w, al))
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        Gc, W = _cable_jacobians(robot, tau, p, R)
        Gm, Y = _body_jacobians(robot, model, theta, R, a, w, al)
        return _assemble(jnp, Gc, Gm), Y, W
    Gc, W = _cable_kept(robot, tau, p, R)
    Gm, Y = (np.asarray(z) for z in _body_jacobians(robot, model, theta, R, a, w, al))
    return _assemble(np, Gc, Gm), Y, W


def _assemble(xp, Gc, Gm):
    """``G`` from the cable side's (n, 6, 6: position, rotation vector) and the model side's
    (n, 6, 12: rotation vector, acceleration, angular rate, angular acceleration) Jacobians."""
    return xp.concatenate([Gc[:, :, :3], -Gm[:, :, 3:6], Gc[:, :, 3:] - Gm[:, :, :3],
                           -Gm[:, :, 6:]], axis=2)


@jax.jit
def _cable_jacobians(robot, tau, p, R):
    """Per sample: d (W tau) / d (dp, dphi) (6, 6) and W (6, m) (see :func:`sample_jacobians`:
    the pulley geometry is the costly part, only the 6 pose directions reach it)."""

    def one(tk, pk, Rk):
        def cable(x):  # (dp, dphi)
            return wrench_matrix(robot, pk + x[:3], _small_rotation(x[3:], Rk)) @ tk

        return jax.jacfwd(cable)(jnp.zeros(6)), wrench_matrix(robot, pk, Rk)

    return jax.vmap(one)(tau, p, R)


@functools.partial(jax.jit, static_argnums=(1,))
def _body_jacobians(robot, model, theta, R, a, w, al):
    """Per sample: d (Y theta) / d (dphi, da, domega, dalpha) (6, 12) and Y (6, p)."""

    def one(Rk, ak, wk, alk):
        def body(x):  # (dphi, da, domega, dalpha)
            return _regressor(robot, model, _small_rotation(x[:3], Rk), ak + x[3:6],
                              wk + x[6:9], alk + x[9:]) @ theta

        return jax.jacfwd(body)(jnp.zeros(12)), _regressor(robot, model, Rk, ak, wk, alk)

    return jax.vmap(one)(R, a, w, al)


_cable_jacobians = cached_executable(_cable_jacobians, name="core.cable_jacobians")
_body_jacobians = cached_executable(_body_jacobians, name="core.body_jacobians",
                                    static_argnums=(1,))
_KEPT: list = []


def _cable_kept(robot, tau, p, R):
    """:func:`_cable_jacobians` as NumPy arrays, the last one kept by content."""
    import hashlib

    leaves, tree = jax.tree_util.tree_flatten((robot, tau, p, R))
    h = hashlib.sha256(str(tree).encode())
    for x in leaves:
        x = np.ascontiguousarray(np.asarray(x))
        h.update(repr((x.shape, str(x.dtype))).encode())
        h.update(x.tobytes())
    key = h.hexdigest()
    if _KEPT and _KEPT[0][0] == key:
        return _KEPT[0][1]
    out = tuple(np.asarray(z) for z in _cable_jacobians(robot, tau, p, R))
    _KEPT[:] = [(key, out)]
    return out


@functools.partial(jax.jit, static_argnums=(1,))
def regressor_jacobians(robot, model, R, a, w, al):
    """Per-sample ``d Y / d xi``: the regressor's columns differentiated with respect to the
    inputs of :func:`cdprid.core.sample_jacobians` (position, acceleration, rotation vector,
    angular rate, angular acceleration; the position does not enter ``Y``).

    Parameters
    ----------
    robot : CableRobot
    model : {"translation", "full"}
        Static.
    R : jax.Array (n, 3, 3)
        Orientations (platform to base).
    a, w, al : jax.Array (n, 3)
        Acceleration (m/s^2), angular rate (rad/s), angular acceleration (rad/s^2), base frame.

    Returns
    -------
    jax.Array (n, 6, p, 15)
    """
    def one(Rk, ak, wk, alk):
        def body(x):  # (dphi, da, domega, dalpha)
            return _regressor(robot, model, _small_rotation(x[:3], Rk), ak + x[3:6],
                              wk + x[6:9], alk + x[9:])

        Hm = jax.jacfwd(body)(jnp.zeros(12))  # (6, p, 12)
        return jnp.concatenate([jnp.zeros(Hm.shape[:2] + (3,)), Hm[..., 3:6], Hm[..., :3],
                                Hm[..., 6:]], axis=-1)

    return jax.vmap(one)(R, a, w, al)


regressor_jacobians = cached_executable(regressor_jacobians, name="core.regressor_jacobians",
                                        static_argnums=(1,))


def _pinv_sym(S: np.ndarray, rel: float = 1e-10) -> np.ndarray:
    """Pseudo-inverses of symmetric PSD matrices ``(n, k, k)`` (rank-deficient for 4 cables or
    a point-mass platform: no information in the null directions)."""
    w, V = np.linalg.eigh(S)
    cut = rel * np.max(w, axis=1, keepdims=True)
    inv = np.where(w > cut, 1.0 / np.where(w > cut, w, 1.0), 0.0)
    return np.matmul(V * inv[:, None, :], V.transpose(0, 2, 1))


def block_banded_solve(A: np.ndarray, B: np.ndarray, d: int, nb: int) -> np.ndarray:
    """Solve ``A X = B`` for a symmetric positive definite block-banded ``A``.

    ``A`` is ``(K d, K d)`` with blocks of size ``d`` and ``nb`` non-zero blocks on each side
    of the diagonal (the spline nuisance: a sample touches 4 consecutive knots, ``nb = 3``);
    block Cholesky, then forward and back substitution: ``O(K nb^2 d^3)``, with no scipy.
    """
    K = A.shape[0] // d

    def blk(i, j):
        return A[i * d:(i + 1) * d, j * d:(j + 1) * d]

    L = {}
    for i in range(K):
        for j in range(max(0, i - nb), i):
            acc = blk(i, j) - sum((L[i, k] @ L[j, k].T for k in range(max(0, i - nb), j)),
                                  np.zeros((d, d)))
            L[i, j] = np.linalg.solve(L[j, j], acc.T).T
        acc = blk(i, i) - sum((L[i, k] @ L[i, k].T for k in range(max(0, i - nb), i)),
                              np.zeros((d, d)))
        L[i, i] = np.linalg.cholesky(acc)
    Bb = np.asarray(B, float).reshape(K, d, -1)
    y = np.empty_like(Bb)
    for i in range(K):
        r = Bb[i] - sum((L[i, k] @ y[k] for k in range(max(0, i - nb), i)), np.zeros_like(Bb[i]))
        y[i] = np.linalg.solve(L[i, i], r)
    x = np.empty_like(Bb)
    for i in reversed(range(K)):
        r = y[i] - sum((L[k, i].T @ x[k] for k in range(i + 1, min(K, i + nb + 1))),
                       np.zeros_like(Bb[i]))
        x[i] = np.linalg.solve(L[i, i].T, r)
    return x.reshape(np.shape(B))


def _scatter(Itc_loc, Icc_loc, cols, nc: int):
    """Scatter-add per-sample blocks into ``I_tc`` (p, nc) and ``I_cc`` (nc, nc) (bincount:
    one pass over the samples)."""
    Itc = np.stack([np.bincount(cols.ravel(), weights=Itc_loc[:, j, :].ravel(), minlength=nc)
                    for j in range(Itc_loc.shape[1])])
    flat = (cols[:, :, None] * nc + cols[:, None, :]).ravel()
    Icc = np.bincount(flat, weights=Icc_loc.ravel(), minlength=nc * nc).reshape(nc, nc)
    return Itc, Icc


def _schur(Itt, Itc, Icc, ndof: int):
    """``I_tt - I_tc I_cc^-1 I_ct`` with the block-banded ``I_cc`` (blocks of ``ndof``, 3 off
    the diagonal: a sample touches 4 consecutive knots) solved by :func:`block_banded_solve`."""
    Icc = Icc.copy()
    Icc[np.diag_indices(len(Icc))] += 1e-12 * float(np.max(np.diag(Icc)))
    return Itt - Itc @ block_banded_solve(Icc, Itc.T, ndof, 3)


def _schur_banded(Itt, Itc_loc, Icc_loc, cols, nc: int, ndof: int):
    """The Schur complement of the nuisance coefficients from the per-sample blocks."""
    return _schur(Itt, *_scatter(Itc_loc, Icc_loc, cols, nc), ndof)


def _information_block(u_t, h: float, K: int, ndof: int, s2, sd, G, Y, W):
    """One block's share of the information: ``I_tt`` (p, p), ``I_tc`` (p, K ndof) and
    ``I_cc`` (K ndof, K ndof), the last two scatter-added from each sample's 4 knots;
    ``G, Y, W`` are the block's :func:`sample_jacobians`."""
    n = len(u_t)
    rot = ndof == 6
    Sig = np.matmul(W * s2, W.transpose(0, 2, 1))
    P = _pinv_sym(Sig)
    i0, b, d1, d2 = bspline_basis(u_t / h)
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
    PL = np.matmul(P, L)  # matmul: BLAS (einsum is not)
    Itt = np.einsum("nip,niq->pq", Y, np.matmul(P, Y), optimize=True)
    Itc_loc = -np.matmul(Y.transpose(0, 2, 1), PL)  # (n, p, 24)
    Icc_loc = np.matmul(L.transpose(0, 2, 1), PL)  # (n, 24, 24)
    # pose observations: the spline values seen with noise
    inv_var = 1.0 / np.maximum(sd, 1e-9) ** 2
    for d in range(ndof):
        idx = np.arange(4) * ndof + d
        Icc_loc[:, idx[:, None], idx[None, :]] += inv_var[d] * b[:, :, None] * b[:, None, :]
    return (Itt, *_scatter(Itc_loc, Icc_loc, cols, K * ndof))


def crb(robot, model: str, theta, t, position, R, acceleration, omega, alpha, tension,
        tension_std, position_std: float, rotation_std: float | None,
        knot_spacing_s: float = 0.1, chunk: int = 4096) -> CRBResult:
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
    chunk : int
        Samples whose information blocks (about 18 KB a sample) are summed at a time, so
        memory does not grow with the recording; the per-sample Jacobians (about 1.6 KB a
        sample) are evaluated :data:`cdprid.core.CHUNK` samples at a time.

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
    nc = K * ndof
    sd = np.array([position_std] * 3 + ([rotation_std] * 3 if rot else []), float)
    s2 = np.square(np.broadcast_to(np.asarray(tension_std, float), (robot.n_cables,)))
    Itt, Itc, Icc = 0.0, 0.0, np.zeros((nc, nc))
    th = jnp.asarray(theta, float)
    # the Jacobians in CHUNK blocks (those of the errors-in-variables weighting: the same
    # shapes, one trace for both), the information in ``chunk`` blocks: (chunk, 24, 24)
    # temporaries, never (n, ...) ones
    for j in range(0, n, CHUNK):
        sj = slice(j, min(n, j + CHUNK))
        GYW = [np.asarray(z) for z in sample_jacobians(robot, model, th, *(
            jnp.asarray(np.asarray(z)[sj], float)
            for z in (tension, position, R, acceleration, omega, alpha)))]
        for a in range(0, sj.stop - j, chunk):
            sl = slice(a, min(sj.stop - j, a + chunk))
            parts = _information_block(t[j:sj.stop][sl] - t[0], h, K, ndof, s2, sd,
                                       *(z[sl] for z in GYW))
            Itt, Itc = Itt + parts[0], Itc + parts[1]
            Icc += parts[2]
    S = _schur(Itt, Itc, Icc, ndof)
    cov = np.linalg.pinv(0.5 * (S + S.T))
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    noise = {"tension_N": [float(v) for v in np.sqrt(s2)], "position_m": float(position_std),
             "orientation_rad": None if not rot else float(rotation_std)}
    note = ("Cramer-Rao bound with poses and tensions noisy (trajectory a cubic B-spline "
            f"nuisance, knots every {h:.3g} s)")
    return CRBResult(cov, std, h, noise, note)
