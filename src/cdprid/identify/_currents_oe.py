"""Output-error estimator of ``identify --source currents --estimator oe``: the motor currents
as the response, not the regressor.

Per cable and pose sample the drive model solved for the current,

    i_j = a_j (tau_j(x) - J_j l''_j - f_v,j l'_j - f_c,j sign(l'_j) + c_j),   a_j = 1 / k_j,

with ``tau(x) = W^+ Z x`` the tensions the platform's dynamics need (``Z x = W tau``, the
Newton-Euler regressor of the filtered motion). On a redundant robot the internal forces
(``tau + N lam``, ``N`` the null space of ``W``) are free per sample: the residual is
projected on the complement of ``diag(a) N`` in the whitened current space (the Cramer-Rao
bound's model in ``benchmarks/currents.py``). Both sides pass the accelerations' filter
(``F[i]``, ``F[sign]``, the differentiated lengths), so the measured current's noise sits in
the response alone: no errors in variables from the currents (the pose noise's, inside ``Z``
and ``W``, is removed by re-noising: :mod:`cdprid.identify._currents_pose`).

Gauss-Newton (Levenberg-Marquardt damped) in ``(x, a, J, f_v, f_c, c)`` from the corrected
least squares, the reference parameter held at its value, each cable weighted by its current
noise's long-run variance per pose sample (``sigma_i^2 dt_i / dt_pose``), the datasheet
constants as Gaussian priors on ``a_j``; the covariance is the HAC sandwich
``H^-1 (S + P) H^-1`` (``S`` the Bartlett long-run covariance of the per-sample scores, ``P``
the priors' precision), mapped to ``k = 1 / a`` and with the reference's uncertainty added.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.core import andrews_bandwidth, bartlett_meat, wrench_matrices
from cdprid.signal import zero_phase_filter

__all__ = ["OEFit", "commutator", "fit_output_error", "oe_inputs", "raw_rates",
           "refit_output_error"]

OE_NOTE = ("output-error estimator: the currents are the response (per cable i = (tau(x) - J "
           "l'' - f_v l' - f_c sign + c) / k, the internal forces projected out on a redundant "
           "robot), Gauss-Newton from the corrected least squares, weighted by the currents' "
           "noise, HAC sandwich covariance")


BANDWIDTH_PERIODS = 4.0
"""Bartlett bandwidth of the sandwich: this many periods of the accelerations' cutoff (the
residual is the currents' noise through that filter: its autocovariance dies within about a
period; Andrews' AR(1) plug-in reads the smooth filtered noise as a near-unit root and takes
~500 samples, leaving ~6 windows to estimate the long-run covariance)."""


@dataclasses.dataclass(frozen=True)
class OEFit:
    """The output-error fit in ``(x, a, J, f_v, f_c, c)``.

    Attributes
    ----------
    phi : ndarray (p + 5m,)
        Estimate (``a = 1 / k`` in 1/(N/A); the reference at its given value).
    cov : ndarray (p + 5m, p + 5m)
        HAC sandwich covariance (zero row and column at the reference).
    cov_iid : ndarray
        ``H^-1`` (the i.i.d. covariance at the assumed weights).
    bandwidth : float
        Bartlett bandwidth (pose samples) of ``cov``.
    cov_andrews : ndarray
        The sandwich with Andrews' AR(1) plug-in bandwidth instead (for comparison).
    bandwidth_andrews : float
    iterations : int
    converged : bool
    resid : ndarray (n, m)
        Whitened (projected) residuals.
    """

    phi: np.ndarray
    cov: np.ndarray
    cov_iid: np.ndarray
    bandwidth: float
    iterations: int
    converged: bool
    resid: np.ndarray
    cov_andrews: np.ndarray | None = None
    bandwidth_andrews: float = float("nan")


def _resid(phi, G, I, L2, L1, S, C1, sw, Nn, Dc):
    """Whitened current residuals (n, m) at ``phi``, projected when ``Nn`` is given (``Dc``
    the filter's commutator, subtracted from ``G x``)."""
    p, m = G.shape[2], G.shape[1]
    x, a = phi[:p], phi[p:p + m]
    J, fv, fc, c = (phi[p + k * m:p + (k + 1) * m] for k in range(1, 5))
    tau = jnp.einsum("njp,p->nj", G, x) - Dc
    e = sw * (I - a * (tau - J * L2 - fv * L1 - fc * S + c * C1))
    if Nn is None:
        return e
    B = (sw * a)[..., None] * Nn  # (n, m, r): the internal forces in whitened currents
    BtB = jnp.einsum("njr,njs->nrs", B, B)
    lam = jnp.linalg.solve(BtB, jnp.einsum("njr,nj->nr", B, e)[..., None])[..., 0]
    return e - jnp.einsum("njr,nr->nj", B, lam)


_resid_jit = jax.jit(_resid)
_jac_jit = jax.jit(jax.jacfwd(_resid))
_grad_jit = jax.jit(jax.grad(lambda phi, *data: 0.5 * jnp.sum(_resid(phi, *data) ** 2)))


def gradient_fn(G, I, L2, L1, S, C1, sw, Nn, Dc=None):
    """``phi -> J^T r``: the gradient of half the residuals' sum of squares (reverse mode, one
    pass: far cheaper than the Jacobian), compiled once per shape.

    Parameters
    ----------
    G, I, L2, L1, S, C1, sw, Nn, Dc
        As in :func:`fit_output_error` (``sw`` the whitening, ``(1, m)``).

    Returns
    -------
    callable
    """
    data = _model_data(G, I, L2, L1, S, C1, sw, Nn, Dc)
    return lambda phi: np.asarray(_grad_jit(jnp.asarray(phi, float), *data))


def _model_data(G, I, L2, L1, S, C1, sw, Nn, Dc):
    """The residual's data as device arrays in :func:`_resid`'s order (``Dc`` None: zeros)."""
    data = tuple(jnp.asarray(v, float) for v in (G, I, L2, L1, S, C1, sw))
    return data + (None if Nn is None else jnp.asarray(Nn, float),
                   jnp.zeros_like(data[1]) if Dc is None else jnp.asarray(Dc, float))


def _residual_fn(G, I, L2, L1, S, C1, sw, Nn, Dc=None):
    """``(r(phi), dr/dphi(phi))``: the residual (n, m) and its Jacobian (n, m, q), compiled
    once per shape."""
    data = _model_data(G, I, L2, L1, S, C1, sw, Nn, Dc)
    return (lambda phi: _resid_jit(jnp.asarray(phi, float), *data),
            lambda phi: _jac_jit(jnp.asarray(phi, float), *data))


def raw_rates(lengths, segments, dt: float):
    """Central first and second differences of the lengths (n, m), segment by segment.

    Parameters
    ----------
    lengths : (n, m) paid-out lengths, m
    segments : list of (i0, i1) sample ranges without gaps
    dt : float
        Period, s.

    Returns
    -------
    d1 (n, m) m/s, d2 (n, m) m/s^2
    """
    d1, d2 = np.zeros_like(lengths), np.zeros_like(lengths)
    for i0, i1 in segments:
        x = lengths[i0:i1]
        d1[i0:i1] = np.gradient(x, dt, axis=0, edge_order=2)
        d2[i0 + 1:i1 - 1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt ** 2
        d2[i0], d2[i1 - 1] = d2[i0 + 1], d2[i1 - 2]
    return d1, d2


def fit_output_error(G, I, L2, L1, S, C1, phi0, fixed: int, weights, Nn=None, prior=None,
                     bandwidth: float | None = None, max_iter: int = 30,
                     tol: float = 1e-10, Dc=None) -> OEFit:
    """Gauss-Newton fit of the output-error current model with the HAC sandwich covariance.

    Parameters
    ----------
    G : (n, m, p)
        ``W^+ Z`` per sample: the tensions' sensitivity to the platform parameters (N per
        parameter unit).
    I, L2, L1, S, C1 : (n, m)
        Currents (A), length accelerations (m/s^2), rates (m/s), Coulomb signs and the offset
        column (1), all through the same filter.
    phi0 : (p + 5m,)
        Start ``(x, a, J, f_v, f_c, c)``; ``phi0[fixed]`` is held (the scale reference).
    fixed : int
        Index of the reference parameter.
    weights : (m,)
        Per-cable weight, 1 / A^2 (the inverse of the current noise's long-run variance per
        sample).
    Nn : (n, m, m - 6), optional
        Orthonormal null spaces of ``W`` (redundant robots): projected out.
    prior : (precision (q,), mean (q,)), optional
        Independent Gaussian priors (precision 0: none).
    bandwidth : float, optional
        Bartlett bandwidth of the sandwich, pose samples (default: Andrews' AR(1) plug-in).
    max_iter : int
    tol : float
        Relative step size at which the iteration stops.
    Dc : (n, m), optional
        Known offset of the tensions (N), subtracted from ``G x`` (the filter's commutator,
        :func:`commutator`).

    Returns
    -------
    OEFit
    """
    sw = np.sqrt(np.asarray(weights, float))[None, :]
    r, jac = _residual_fn(G, I, L2, L1, S, C1, sw, Nn, Dc)
    q = len(phi0)
    P, pm = (np.zeros(q), np.zeros(q)) if prior is None else (np.asarray(prior[0], float),
                                                              np.asarray(prior[1], float))
    o = np.delete(np.arange(q), fixed)
    phi = np.asarray(phi0, float).copy()

    def cost(ph):
        return float(np.sum(np.asarray(r(ph)) ** 2) + np.sum(P * (ph - pm) ** 2))

    lam, c0, it, converged = 1e-6, cost(phi), 0, False
    while it < max_iter:
        it += 1
        e, Jm = np.asarray(r(phi)).reshape(-1), np.asarray(jac(phi)).reshape(-1, q)[:, o]
        H = Jm.T @ Jm + np.diag(P[o])
        g = Jm.T @ e + P[o] * (phi[o] - pm[o])
        D = np.diag(np.diag(H))
        while True:
            step = np.linalg.solve(H + lam * D, -g)
            trial = phi.copy()
            trial[o] += step
            c1 = cost(trial)
            if c1 <= c0 or lam > 1e8:
                break
            lam *= 10.0
        if c1 <= c0:
            phi, c0, lam = trial, c1, max(lam / 10.0, 1e-9)
        if np.all(np.abs(step) <= tol * (np.abs(phi[o]) + 1e-6)):
            converged = True
            break
    return _sandwich(r, jac, phi, o, P, it, converged, bandwidth)


def _sandwich(r, jac, phi, o, P, it: int, converged: bool, bandwidth) -> OEFit:
    """The HAC sandwich ``H^-1 (S + P) H^-1`` at ``phi`` (Bartlett, ``bandwidth`` samples or
    Andrews' plug-in)."""
    q = len(phi)
    e = np.asarray(r(phi))
    Jm = np.asarray(jac(phi))[:, :, o]  # (n, m, q - 1)
    scores = np.einsum("njq,nj->nq", Jm, e)
    bw_a = andrews_bandwidth(scores)
    H = np.einsum("njq,njr->qr", Jm, Jm) + np.diag(P[o])
    Hi = np.linalg.inv(H)
    cov, cov_a, cov_iid = np.zeros((q, q)), np.zeros((q, q)), np.zeros((q, q))
    cov_a[np.ix_(o, o)] = Hi @ (bartlett_meat(scores, bw_a) + np.diag(P[o])) @ Hi
    bw = bw_a if bandwidth is None else float(bandwidth)
    cov[np.ix_(o, o)] = Hi @ (bartlett_meat(scores, bw) + np.diag(P[o])) @ Hi
    cov_iid[np.ix_(o, o)] = Hi
    return OEFit(phi, cov, cov_iid, float(bw), it, converged, e, cov_a, float(bw_a))


def oe_inputs(ds, motion, idx, reg, current, lengths, sign, wf, dt: float, params: dict):
    """The output-error model's inputs at the kept samples ``idx``.

    Parameters
    ----------
    ds : Dataset
    motion : Motion
        The filtered motion (pose clock).
    idx : (n,) int
        Kept samples.
    reg : regression restricted to ``idx`` (``wrench_block`` gives ``Z``, (n, 6, p)).
    current, lengths, sign : (N, m)
        Currents (A, prefiltered, on the pose clock), paid-out lengths (m), Coulomb signs, all
        samples.
    wf : callable
        The accelerations' matched filter of (N, k) channels.
    dt : float
        Pose period, s.
    params : dict
        The differentiator's parameters (``cutoff_hz``, ``order``).

    Returns
    -------
    G (n, m, p), I, L2, L1, S, C1 (n, m), Nn (n, m, m - 6) or None
    """
    m = ds.robot.n_cables
    d1, d2 = raw_rates(lengths, motion.segments, dt)
    ones = np.ones(m)
    I, L1, S, C1 = (np.asarray(wf(np.asarray(v, float), ones))[idx] for v in (
        current, d1, sign, np.ones_like(d1)))
    L2 = zero_phase_filter(d2, dt, params["cutoff_hz"], params.get("order", 2))[idx]
    W = np.asarray(wrench_matrices(ds.robot, motion.position, motion.B_R_P))[idx]
    Z = np.concatenate([reg.wrench_block(i0, min(len(idx), i0 + 2048))[0]
                        for i0 in range(0, len(idx), 2048)])
    G = _right_inverse(W, Z)
    Nn = None
    if m > 6:
        # an orthonormal basis of W's null space (the residual's projection does not depend on
        # which): the last m - 6 columns of the complete QR of W^T
        Nn = np.linalg.qr(np.swapaxes(W, 1, 2), mode="complete")[0][:, :, 6:]
    return G, I, L2, L1, S, C1, Nn


def _right_inverse(W, B):
    """``W^+ B`` per sample for full-row-rank wrench matrices ``W`` (n, 6, m): ``W^T (W
    W^T)^-1 B`` (the pseudo-inverse's least-norm solution, a 6 x 6 solve instead of an SVD;
    ``B`` (n, 6, k) or (n, 6))."""
    vec = B.ndim == 2
    B = B[..., None] if vec else B
    X = np.swapaxes(W, 1, 2) @ np.linalg.solve(W @ np.swapaxes(W, 1, 2), B)
    return X[..., 0] if vec else X


def commutator(ds, motion, idx, current, lengths, sign, wf, dt: float, theta, p: int):
    """``W^+ F[W tau] - F[tau]`` (n, m) at the kept samples, ``tau`` the drive model's
    tensions at ``theta`` (the corrected least squares) on every sample: what ``G x = W^+ Z
    x`` (``Z x = F[W tau]``, the matched filter) has besides ``F[tau]``, the filter not
    commuting with the slowly varying ``W^+``. Its error through ``theta``'s is second order.

    Parameters
    ----------
    ds, motion, idx, current, lengths, sign, wf, dt
        As in :func:`oe_inputs`.
    theta : (p + 5m,)
        Platform and drive parameters.
    p : int
        Number of platform parameters.

    Returns
    -------
    ndarray (n, m), N
    """
    from cdprid.core import DriveParameters, drive_tension

    d1, d2 = raw_rates(lengths, motion.segments, dt)
    tau = drive_tension(DriveParameters.from_vector(theta[p:]), np.asarray(current, float),
                        d1, d2, np.asarray(sign, float))
    W = np.asarray(wrench_matrices(ds.robot, motion.position, motion.B_R_P))
    Fu = np.asarray(wf(np.einsum("nam,nm->na", W, tau)))[idx]
    Ft = np.asarray(wf(tau, np.ones(tau.shape[1])))[idx]
    return _right_inverse(W[idx], Fu) - Ft


def datasheet_drives(drives, ref, m: int):
    """``(j, k0, tol)`` for every drive but the reference that states a datasheet tolerance:
    index, nominal torque constant and relative tolerance (the priors of both estimators)."""
    for j in range(m):
        tol = float(drives.tolerance[j])
        if np.isnan(tol) or (ref.kind == "drive" and ref.cable == j + 1):
            continue
        yield j, float(drives.k_nominal[j]), tol


def _a_prior(drives, ref, p: int, m: int):
    """Gaussian priors on ``a_j = 1 / k_j`` from the datasheets (std ``tol / (sqrt(3) k0)``),
    the reference drive excluded; None without any."""
    if drives is None:
        return None
    q = p + 5 * m
    P, mean = np.zeros(q), np.zeros(q)
    for j, k0, tol in datasheet_drives(drives, ref, m):
        P[p + j] = (np.sqrt(3.0) * k0 / max(tol, 1e-6)) ** 2
        mean[p + j] = 1.0 / k0
    return (P, mean) if P.any() else None


def current_weights(noise: dict, t_cur, dt: float) -> np.ndarray:
    """Per-cable weights (1 / A^2): the inverse of the current noise's long-run variance per
    pose sample (``sigma_i^2 dt_i / dt_pose``, at most ``sigma_i^2``)."""
    s_i = np.maximum(np.asarray(noise["current_A"], float), 1e-6)
    ratio = min(1.0, float(np.median(np.diff(t_cur))) / dt)
    return 1.0 / (s_i ** 2 * ratio)


def refit_output_error(ds, model_p: int, motion, idx, reg, fit: dict, ref, drives, current,
                       lengths, sign, wf, dt: float, params: dict, noise: dict, t_cur,
                       notes: list, warns: list) -> dict:
    """The output-error estimate started from the corrected least squares ``fit``.

    Returns a dict with the keys of ``_currents._fit`` (``theta``, ``cov``, ``cov_iid``,
    ``resid``, ...), the reference's uncertainty propagated (``Cov += (s_v / v)^2 theta
    theta^T``); ``fit`` unchanged (and a warning) when the refit fails or does not converge.
    """
    p, m = model_p, ds.robot.n_cables
    if m < 6:
        warns.append("--estimator oe needs at least six cables; the corrected least squares "
                     "is reported.")
        return fit
    G, I, L2, L1, S, C1, Nn = oe_inputs(ds, motion, idx, reg, current, lengths, sign, wf, dt,
                                        params)
    th0 = np.asarray(fit["theta"], float)
    k0 = th0[p:p + m]
    if drives is not None and (not np.all(np.isfinite(th0)) or np.any(k0 <= 0)):
        th0 = th0.copy()
        th0[p:p + m] = drives.k_nominal
    phi0 = th0.copy()
    phi0[p:p + m] = 1.0 / th0[p:p + m]
    fixed = ref.index(p)
    phi0[fixed] = 1.0 / ref.value if ref.kind == "drive" else ref.value
    w = current_weights(noise, t_cur, dt)
    try:
        Dc = commutator(ds, motion, idx, current, lengths, sign, wf, dt, th0, p)
        oe = fit_output_error(G, I, L2, L1, S, C1, phi0, fixed, w, Nn,
                              _a_prior(drives, ref, p, m),
                              bandwidth=np.ceil(BANDWIDTH_PERIODS / (params["cutoff_hz"] * dt)),
                              Dc=Dc)
    except np.linalg.LinAlgError as e:
        warns.append(f"the output-error refit failed ({e}); the corrected least squares is "
                     "reported.")
        return fit
    if not oe.converged:
        warns.append(f"the output-error refit stopped after {oe.iterations} iterations without "
                     "converging: its estimate and std may not hold (compare --estimator cls).")
    T = np.eye(len(oe.phi))
    a = oe.phi[p:p + m]
    T[p:p + m, p:p + m] = np.diag(-1.0 / a ** 2)
    theta = oe.phi.copy()
    theta[p:p + m] = 1.0 / a
    rel = ref.std / ref.value
    cov = T @ oe.cov @ T.T + rel ** 2 * np.outer(theta, theta)
    cov_iid = T @ oe.cov_iid @ T.T + rel ** 2 * np.outer(theta, theta)
    cov_andrews = T @ oe.cov_andrews @ T.T + rel ** 2 * np.outer(theta, theta)
    cov_sandwich = cov
    cov = _floored(cov, cov_iid)
    notes.append(OE_NOTE + f" ({oe.iterations} iterations, Bartlett bandwidth "
                 f"{oe.bandwidth:.0f} samples)")
    noise["eiv_share"] = 0.0
    compared = {"cls_theta": fit["theta"], "cls_cov": fit["cov"], "cov_sandwich": cov_sandwich,
                "cov_andrews": cov_andrews, "cov_model": cov_iid}
    return dict(fit, theta=theta, cov=cov, cov_iid=cov_iid, oe=oe, compared=compared)


def _floored(cov, cov_model):
    """The sandwich with every std raised to at least the current noise's own (``H^-1`` at
    the measured noise level), correlations kept. The Bartlett sandwich reads the filtered
    current noise ~10-20 % low in variance (its window's bias, the fit's leverage)."""
    s, s0 = np.sqrt(np.clip(np.diag(cov), 0, None)), np.sqrt(np.clip(np.diag(cov_model), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(s > 0, np.maximum(1.0, s0 / s), 1.0)
    return cov * np.outer(f, f)
