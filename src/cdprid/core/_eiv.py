"""Errors-in-variables weighting of the batch regression (``identify --weighting eiv``).

Each sample's residual ``r = F[W tau] - Y theta`` (``F`` the matched wrench filter) is noisy
through the tensions *and* through the pose: the pose enters ``W``, the rotation enters ``Y``,
and the differentiated pose gives the accelerations, angular rates and angular accelerations
of ``Y``. To first order its covariance is

    Sigma_n = g_F W diag(s_tau^2) W^T + sum_d sigma_d^2 sum_(a, b) C_ab J_a J_b^T,

with ``d`` the position and the orientation, ``J_0, J_1, J_2`` the Jacobians of ``r`` with
respect to that coordinate, its rate and its second derivative (at the estimate), and ``C``
the 3 x 3 covariance of ``(F x, D1 x, D2 x)`` for unit white noise ``x`` through the wrench
filter and the differentiator (measured by passing white noise through them, so every method
of :data:`cdprid.signal.METHODS` gets its own gains). Ordinary least squares weighs every
sample alike although ``Sigma_n`` changes by orders of magnitude along a trajectory (tensions
that change the cable directions' weight, accelerations that scale the pose noise); the
generalised least squares estimate whitens each sample by ``Sigma_n^-1/2`` (two steps: OLS
for the Jacobians' theta, then GLS). The time correlation left by the filters is handled by
the HAC covariance as before.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from cdprid.core._crb import regressor_jacobians, sample_jacobians
from cdprid.core._noise import estimate_noise
from cdprid.signal import differentiate

__all__ = ["noise_gains", "noise_levels", "whitening", "input_covariance", "eiv_fit", "EIV_NOTE",
           "bias_correction"]

EIV_NOTE = ("errors-in-variables weighting: each sample whitened by its residual covariance "
            "(tension noise through W, pose noise through W and the differentiated motion), "
            "noise levels estimated from the data")


def noise_gains(differentiator: str, params: dict, dt: float, wf=None, n: int = 3000,
                seed: int = 0) -> np.ndarray:
    """``C``: the covariance of ``(F x, D1 x, D2 x)`` for unit white noise ``x``.

    ``F`` is the wrench filter ``wf`` (identity when None), ``D1``, ``D2`` the
    differentiator's first and second derivative; 10 % of each end is dropped (transients).

    Parameters
    ----------
    differentiator : str
        A method of :data:`cdprid.signal.METHODS`.
    params : dict
        Its parameters.
    dt : float
        Sampling period, s.
    wf : callable or LinearMatch, optional
        The wrench filter (a per-segment filter is applied to one ``n``-sample segment).
    n : int
        Samples of the simulated noise.
    seed : int
        Seed of the noise (the result is deterministic).

    Returns
    -------
    ndarray (3, 3)
        Units 1, 1/s^2 and 1/s^4 on the diagonal.
    """
    x = np.random.default_rng(seed).normal(size=(n, 3))
    if hasattr(wf, "whole"):  # a per-segment filter of the recording: here one n-sample segment
        wf = wf.whole(n)
    v, a = (np.asarray(z) for z in differentiate(x, dt, method=differentiator, **params))
    f = x if wf is None else np.asarray(wf(x, np.ones(3)))
    if hasattr(wf, "position"):  # the linear match: accelerations are its FIR of the poses
        a = np.asarray(wf.position(x))
    k = slice(n // 10, n - n // 10)
    C = np.zeros((3, 3))
    for j in range(3):
        C += np.cov(np.stack([f[k, j], v[k, j], a[k, j]]))
    return C / 3.0


def whitening(robot, model: str, motion, tension, theta, s_tau, s_pos: float,
              s_rot: float | None, C: np.ndarray, chunk: int = 16384) -> np.ndarray:
    """Per-sample whitening matrices ``U_n``, ``U_n^T U_n = Sigma_n^-1``.

    The Jacobians are those of the Cramer-Rao bound (:func:`cdprid.core.sample_jacobians`:
    the residual with respect to position, acceleration, rotation vector, angular rate and
    angular acceleration), evaluated ``chunk`` samples at a time.

    Parameters
    ----------
    robot : CableRobot
    model : {"translation", "full"}
    motion : Motion
        The estimated motion (position, B_R_P, acceleration, omega, alpha), n samples.
    tension : ndarray (n, m)
        Tensions at the pose times, N.
    theta : ndarray (p,)
        The parameters at which the Jacobians are taken (the OLS estimate).
    s_tau : ndarray (m,)
        Tension noise std per pose sample, N.
    s_pos : float
        Position noise std per axis, m.
    s_rot : float or None
        Orientation noise std per axis, rad (None: no orientation stream).
    C : ndarray (3, 3)
        :func:`noise_gains`.
    chunk : int
        Samples per evaluation block (bounded memory).

    Returns
    -------
    ndarray (n, 6, 6)
        ``U_n`` in 1/N (force rows) and 1/(N m) (moment rows).
    """
    n = len(motion.t)
    U = np.empty((n, 6, 6))
    s2 = np.square(np.broadcast_to(np.asarray(s_tau, float), (np.shape(tension)[1],)))
    Su = input_covariance(s_pos, s_rot, C)
    th = jnp.asarray(theta, float)
    for i0 in range(0, n, chunk):
        i1 = min(n, i0 + chunk)
        G, _, W = (np.asarray(z) for z in sample_jacobians(robot, model, th, *(
            jnp.asarray(np.asarray(x)[i0:i1], float) for x in (
                tension, motion.position, motion.B_R_P, motion.acceleration, motion.omega,
                motion.alpha))))
        S = (np.matmul(G @ Su, G.transpose(0, 2, 1))
             + C[0, 0] * np.matmul(W * s2, W.transpose(0, 2, 1)))
        U[i0:i1] = _inverse_sqrt(S)
    return U


def input_covariance(s_pos: float, s_rot: float | None, C: np.ndarray) -> np.ndarray:
    """Covariance of the noisy inputs of :func:`cdprid.core.sample_jacobians` (position,
    acceleration, rotation vector, angular rate, angular acceleration): ``sigma^2 C (x) I3``
    over (pose, rate, second derivative) of each coordinate.

    Parameters
    ----------
    s_pos : float
        Position noise std per axis, m.
    s_rot : float or None
        Orientation noise std per axis, rad; None: no orientation noise.
    C : ndarray (3, 3)
        :func:`noise_gains`.

    Returns
    -------
    ndarray (15, 15)
        In m^2, m^2/s^4, rad^2, rad^2/s^2, rad^2/s^4 on the diagonal blocks.
    """
    S = np.zeros((15, 15))
    for sig, blocks in ((s_pos, {0: 0, 2: 1}), (0.0 if s_rot is None else s_rot,
                                                   {0: 2, 1: 3, 2: 4})):
        for a, ba in blocks.items():
            for b, bb in blocks.items():
                S[3 * ba:3 * ba + 3, 3 * bb:3 * bb + 3] = sig ** 2 * C[a, b] * np.eye(3)
    return S


def bias_correction(reg, robot, model: str, motion, tension, theta, U, Su,
                    chunk: int) -> np.ndarray:
    """The errors-in-variables estimate's second-order bias from the pose noise (p,).

    The regressor ``Y`` is built from the noisy differentiated pose, and so is the residual
    ``r = F[W tau] - Y theta``: their noise is correlated, and least squares (weighted by
    ``Omega = U^T U``) keeps ``E[dY^T Omega dr] != 0``, a bias of
    ``(Z^T Omega Z)^-1 sum_n E[dY_n^T Omega_n dr_n]`` with, to first order,
    ``dY_n[:, j] = H_nj xi``, ``dr_n = G_n xi`` and ``xi`` the inputs' noise of covariance
    ``Su`` (:func:`input_covariance`): ``b_j = sum_n tr(H_nj^T Omega_n G_n Su)``. With
    0.3 mrad of orientation noise it was +2.5 % of an 8-cable robot's Ixx (0.03 of its bound,
    measured by antithetic Monte Carlo, ``benchmarks/efficiency.py --antithetic``).

    Parameters
    ----------
    reg : StreamedRegression
        The kept samples' regression (n samples).
    robot : CableRobot
    model : {"translation", "full"}
    motion : namespace
        The kept samples' motion (``position`` m, ``B_R_P``, ``acceleration`` m/s^2, ``omega``
        rad/s, ``alpha`` rad/s^2), each with n rows.
    tension : ndarray (n, m)
        The kept samples' tensions, N.
    theta : ndarray (p,)
        The estimate (SI units).
    U : ndarray (n, 6, 6)
        Whitening matrices (:func:`whitening`).
    Su : ndarray (15, 15)
        Covariance of the Jacobians' inputs (:func:`input_covariance`).
    chunk : int
        Samples per evaluation block.

    Returns
    -------
    ndarray (p,)
        The bias, in the parameters' units: subtract it from ``theta``.
    """
    n, p = len(reg.t), len(theta)
    b, N = np.zeros(p), np.zeros((p, p))
    th = jnp.asarray(theta, float)
    for i0 in range(0, n, chunk):
        i1 = min(n, i0 + chunk)
        args = [jnp.asarray(np.asarray(x)[i0:i1], float) for x in (
            tension, motion.position, motion.B_R_P, motion.acceleration, motion.omega,
            motion.alpha)]
        G = np.asarray(sample_jacobians(robot, model, th, *args)[0])
        H = np.asarray(regressor_jacobians(robot, model, *args[2:]))
        u = U[i0:i1]
        M = np.matmul(np.matmul(u, G), Su)  # (k, 6, 15)
        b += np.einsum("krs,kspi,kri->p", u, H, M, optimize=True)
        Zu = np.matmul(u, reg.wrench_block(i0, i1)[0])
        N += np.einsum("krp,krq->pq", Zu, Zu)
    return np.linalg.solve(N, b)


def _inverse_sqrt(S):
    """``U`` with ``U^T U = S^-1`` (k, 6, 6), from the Cholesky factor of ``S`` + a ridge."""
    # a ridge of 1e-6 of each sample's largest variance: rows a point-mass robot cannot load
    # and directions no noise reaches get a large but finite weight
    ridge = 1e-6 * np.max(np.diagonal(S, axis1=1, axis2=2), axis=1) + 1e-300
    L = np.linalg.cholesky(S + ridge[:, None, None] * np.eye(6))
    return np.linalg.inv(L)


def eiv_fit(reg, robot, model: str, motion, tension, idx, noise: tuple, C: np.ndarray,
            names, covariance: str, chunk: int, min_bandwidth: float = 1.0,
            bias_correct: bool = True):
    """Two-step errors-in-variables GLS of a streamed regression.

    Step 1: ordinary least squares (the Jacobians' theta); step 2: every sample whitened by
    :func:`whitening`; step 3: the pose noise's second-order bias removed
    (:func:`bias_correction`). The returned :class:`cdprid.core.LSResult` has the GLS estimate
    and its (HAC or i.i.d.) covariance, and the residuals and ``sigma_rho`` in newtons
    (unwhitened).

    Parameters
    ----------
    reg : StreamedRegression
        The kept samples' regression (``reg.t`` = ``motion.t[idx]``).
    robot : CableRobot
    model : {"translation", "full"}
    motion : Motion
        The differentiated motion (all samples).
    tension : ndarray (n, m)
        Tensions at the pose times (all samples), N.
    idx : ndarray (k,) of int
        The kept samples' indices.
    noise : tuple (s_tau, s_pos, s_rot)
        Noise std per pose sample: tensions (m,) in N, position in m, orientation in rad or
        None (see :func:`whitening`).
    C : ndarray (3, 3)
        :func:`noise_gains`.
    names : sequence of str
        Parameter names (p,).
    covariance : {"hac", "iid"}
        Covariance of the GLS estimate.
    chunk : int
        Samples per evaluation block (bounded memory).
    min_bandwidth : float
        Floor of the HAC bandwidth (the memory of the rows' filter, samples).
    bias_correct : bool
        Step 3 (identify applies it with a cutoff chosen from the data only).

    Returns
    -------
    LSResult
        GLS estimate (bias-corrected with ``bias_correct``), its covariance, the unweighted
        design's condition numbers, the unwhitened residuals (6 k,) and ``sigma_rho`` (N).
    """
    import dataclasses
    from types import SimpleNamespace

    from cdprid.core._identification import least_squares_blocks

    n = len(reg.t)
    first = least_squares_blocks(reg.wrench_block, n, names, covariance="iid", chunk=chunk)
    sub = SimpleNamespace(**{k: np.asarray(getattr(motion, k))[idx] for k in (
        "t", "position", "B_R_P", "velocity", "acceleration", "omega", "alpha")})
    U = whitening(robot, model, sub, np.asarray(tension)[idx], first.x, *noise, C,
                  chunk=chunk)

    def block(i0, i1):
        Z, y = reg.wrench_block(i0, i1)
        u = U[i0:i1]
        return np.matmul(u, Z), np.matmul(u, y[:, :, None])[:, :, 0]

    res = least_squares_blocks(block, n, names, covariance=covariance, chunk=chunk,
                               min_bandwidth=min_bandwidth)
    if bias_correct:
        dx = bias_correction(reg, robot, model, sub, np.asarray(tension)[idx], res.x, U,
                             input_covariance(noise[1], noise[2], C), chunk)
        res = dataclasses.replace(res, x=np.asarray(res.x) - dx)
    # the design's condition (the paper's cond(W_ID)) is the unweighted regressor's
    res = dataclasses.replace(res, cond=first.cond, cond_scaled=first.cond_scaled,
                              column_norms=first.column_norms)
    resid = np.empty((n, 6))
    for i0 in range(0, n, chunk):
        i1 = min(n, i0 + chunk)
        Z, y = reg.wrench_block(i0, i1)
        resid[i0:i1] = y - Z @ res.x
    sigma = float(np.sqrt(np.sum(resid ** 2) / max(res.n_rows - len(res.x), 1)))
    return dataclasses.replace(res, residual=resid.reshape(-1), sigma_rho=sigma)


def noise_levels(ds, sig) -> tuple:
    """Noise levels estimated from the data (4th differences, :func:`estimate_noise`).

    Tension noise per cable from the raw stream, scaled to a pose sample by the tension
    samples per pose sample; position and orientation noise from the pose stream.

    Parameters
    ----------
    ds : Dataset
        The recording (raw tension stream, quaternions or None).
    sig : AlignedSignals
        Its aligned streams (pose times, positions, quaternions).

    Returns
    -------
    s_tau : ndarray (m,)
        Tension noise std per pose sample, N.
    per_pose : float
        Tension samples per pose sample (>= 1).
    s_pos : float
        Position noise std per axis, m.
    s_rot : float or None
        Orientation noise std per axis, rad; None without a quaternion stream.
    """
    tt = np.asarray(ds.tension_t, float)
    per_pose = max(1.0, sig.dt / float(np.median(np.diff(tt)))) if len(tt) > 1 else 1.0
    s_tau = estimate_noise(np.asarray(ds.tension, float)) / np.sqrt(per_pose)
    s_pos = float(np.median(estimate_noise(sig.position)))
    s_rot = None
    if ds.quaternion is not None:
        q = np.asarray(sig.quaternion, float)
        q = q * np.where(q @ q[0] < 0, -1.0, 1.0)[:, None]
        s_rot = float(np.median(estimate_noise(2.0 * q[:, 1:])))  # small angles: 2 q_xyz
    return s_tau, per_pose, s_pos, s_rot
