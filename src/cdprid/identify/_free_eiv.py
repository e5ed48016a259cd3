"""The pose noise inside the free motion's regressor (errors in variables): its bias removed
by a corrected normal matrix from re-noised poses (``identify --source free-motion``).

Every entry of the free-motion rows ``F[N^T S Z]`` comes from the measured poses: the
accelerations, angular rates and angular accelerations are their differences, and the free
directions ``N`` and the gravity terms of ``Z`` follow their rotation. The homogeneous fit
``P x = 0`` (``x[ref] = 1``) minimises ``x^T M x`` with ``M = sum_n P_n^T P_n``, and to second
order in the pose noise ``E[M] = M_0 + D``: the noise's own power ``E[dP^T dP]`` and the rows'
curvature ``P^T E[d2P]``. ``D x != 0`` is a bias that grows as ``sigma^2`` and that least
squares does not see (its HAC covariance holds the residual's first-order noise only). On a
push-free simulated swing (tests/identify/free_sim.py, 6 s, 0.2 mm and 0.5 mrad, 16 noise
draws) z_G sat 1.4 of its spread off, 2.3 at twice the noise, 3.4 at four times.

The correction is the tension path's idea (:func:`cdprid.core.bias_correction`: remove the
second-order term) by simulation instead of Jacobians, so that the rows' whole chain (stencils,
projection, filter, the samples kept) is followed exactly. The measured poses get fresh white
noise of the levels estimated from them (:func:`cdprid.core.noise_levels`, 4th differences) in
antithetic pairs ``y + e``, ``y - e``; a pair's mean normal matrix
``(M(y + e) + M(y - e)) / 2`` has no first-order term and exceeds ``M(y)`` by ``D`` in
expectation (the noise variance doubled). The estimate minimises ``x^T (M - D_hat) x``:
consistent as ``M`` is linear in the noise variance to second order, however large ``D`` is
against ``M_0`` (a linear extrapolation of the estimates themselves, SIMEX, left 20 % of z_G's
bias at the simulated noise and 64 % at four times it). Its covariance is the least-squares
HAC through the corrected bread ``(M - D)^-1 M``, inflated per parameter when the corrected
scores ``(P_n^T P_n - D_n) x`` (``D_n`` per sample from the pairs) vary more than the plain
ones, plus the pairs' Monte-Carlo spread. The pairs' half differences are draws of the pose
noise's first-order error: their covariance, the parametric bootstrap's, is reported next to
the HAC's (on the UACDPR recording it is 1-2 % of it: the residual there is not pose noise).

Assumed: white pose noise (a coloured one is under- or over-corrected) and noise levels that
the 4th differences measure (a motion with power near the Nyquist frequency inflates them).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.core import bartlett_meat, noise_levels, rotation_matrices

__all__ = ["PAIRS", "PoseNoiseBias", "pose_noise_bias"]

#: antithetic pairs of the bootstrap
PAIRS = 8


@dataclasses.dataclass(frozen=True)
class PoseNoiseBias:
    """What :func:`pose_noise_bias` found (parameters without the reference's).

    Attributes
    ----------
    bias : ndarray (p - 1,)
        The estimated second-order bias, the parameters' units over the reference's.
    share : float
        The pose noise's largest share of the rows' power over the parameters' directions
        (the largest eigenvalue of ``D`` in the metric of ``M``, reference left out): the
        corrected estimate is ``1 / (1 - share)`` times noisier than least squares there.
    inflation : ndarray (p - 1,)
        How much more the corrected scores ``(P_n^T P_n - D_n) x`` vary than the plain ones
        ``P_n^T P_n x`` (``D_n`` the noise's share of sample n, from the pairs): the ratio of
        the HAC variances they give through the same corrected bread (no leverage
        adjustment).
    cov_mc : ndarray (p - 1, p - 1)
        Monte-Carlo covariance of ``bias`` (its pairs' spread over their number).
    cov_boot : ndarray (p - 1, p - 1)
        The pose noise's first-order covariance of the estimate (the pairs' half differences).
    bread : ndarray (p - 1, p - 1)
        ``Bc^-1 B``: the least-squares covariance ``C`` becomes ``bread C bread^T`` for the
        corrected estimate (``B`` the normal matrix, ``Bc`` with the noise's share removed).
    s_pos : float
        Position noise used, m.
    s_rot : float or None
        Orientation noise used, rad (None: none perturbed).
    pairs : int
    """

    bias: np.ndarray
    share: float
    inflation: np.ndarray
    cov_mc: np.ndarray
    cov_boot: np.ndarray
    bread: np.ndarray
    s_pos: float
    s_rot: float | None
    pairs: int


def _per_sample(P, idx) -> np.ndarray:
    """``P_n^T P_n`` (k_idx, p, p) of the samples ``idx``."""
    Z = P[idx]
    return np.einsum("nkp,nkq->npq", Z, Z)


def _solve(M, ref_i: int) -> np.ndarray:
    """The minimiser of ``x^T M x`` with ``x[ref_i] = 1``: the other parameters (p - 1,)."""
    o = np.delete(np.arange(M.shape[0]), ref_i)
    return np.linalg.solve(M[np.ix_(o, o)], -M[o, ref_i])


def _perturbed(sig, motion, e_pos, e_rot):
    """The aligned signals and motion with the poses moved by ``e_pos`` (m) and rotated by the
    small rotation vectors ``e_rot`` (rad, platform side; None: not rotated)."""
    pos = np.asarray(sig.position, float) + e_pos
    q = np.asarray(sig.quaternion, float)
    if e_rot is not None:
        w, v = q[:, :1], q[:, 1:]
        d = 0.5 * e_rot
        q = np.concatenate([w - np.sum(v * d, 1, keepdims=True),
                            w * d + v + np.cross(v, d)], axis=1)
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
    sig2 = dataclasses.replace(sig, position=pos, quaternion=q)
    R = motion.B_R_P if e_rot is None else np.asarray(rotation_matrices(q))
    return sig2, dataclasses.replace(motion, position=pos, B_R_P=R)


def pose_noise_bias(ds, sig, motion, rows, idx, ref_i: int, P, bandwidth: float,
                    pairs: int = PAIRS, seed: int = 0) -> PoseNoiseBias:
    """The second-order bias of the free-motion fit from the pose noise (module docstring).

    Parameters
    ----------
    ds : Dataset
        The recording (with tensions or a placeholder: :func:`cdprid.core.noise_levels`).
    sig : AlignedSignals
        Its aligned poses.
    motion : Motion
        The differentiated motion (segments, rotation matrices).
    rows : callable
        ``rows(sig, motion) -> P`` (n, k, p): the free-motion rows of poses
        (:func:`cdprid.identify._free_rows.projected_filtered_rows` with the fit's settings).
    idx : ndarray of int
        The samples fitted.
    ref_i : int
        The reference parameter's index.
    P : ndarray (n, k, p)
        The rows at the measured poses.
    bandwidth : float
        Bartlett bandwidth of the HAC covariance, samples (the least-squares fit's).
    pairs : int
        Antithetic pairs.
    seed : int
        Seed of the added noise (the result is deterministic).

    Returns
    -------
    PoseNoiseBias
    """
    _, _, s_pos, s_rot = noise_levels(ds, sig)
    if not getattr(sig, "has_rotation", True) or (s_rot is not None and s_rot <= 0):
        s_rot = None
    rng = np.random.default_rng(seed)
    n, Mn = len(sig.t), _per_sample(P, idx)
    M0, Dn, extra, halves = Mn.sum(0), np.zeros_like(Mn), [], []
    for _ in range(int(pairs)):
        e_pos = s_pos * rng.standard_normal((n, 3))
        e_rot = None if s_rot is None else s_rot * rng.standard_normal((n, 3))
        Ms = [_per_sample(rows(*_perturbed(sig, motion, sgn * e_pos,
                                           None if e_rot is None else sgn * e_rot)), idx)
              for sgn in (1.0, -1.0)]
        dn = 0.5 * (Ms[0] + Ms[1]) - Mn
        Dn += dn / int(pairs)
        extra.append(dn.sum(0))
        halves.append(0.5 * (_solve(Ms[0].sum(0), ref_i) - _solve(Ms[1].sum(0), ref_i)))
    D = Dn.sum(0)
    x0, xc = _solve(M0, ref_i), _solve(M0 - D, ref_i)
    xs = np.array([_solve(M0 - d, ref_i) for d in extra])  # each pair's corrected estimate
    d = xs - xs.mean(0)
    o = np.delete(np.arange(M0.shape[0]), ref_i)
    B, Bi = M0[np.ix_(o, o)], np.linalg.inv((M0 - D)[np.ix_(o, o)])
    g = np.einsum("npq,q->np", (Mn - Dn)[:, o, :], np.insert(xc, ref_i, 1.0))
    g0 = np.einsum("npq,q->np", Mn[:, o, :], np.insert(x0, ref_i, 1.0))
    cov = Bi @ bartlett_meat(g, bandwidth) @ Bi.T  # the meats compared through one bread
    cov0 = Bi @ bartlett_meat(g0, bandwidth) @ Bi.T
    halves = np.array(halves)
    Li = np.linalg.inv(np.linalg.cholesky(B))  # the noise's share in the rows' own metric
    lam = float(np.max(np.linalg.eigvalsh(Li @ D[np.ix_(o, o)] @ Li.T)))
    return PoseNoiseBias(x0 - xc, lam, np.diag(cov) / np.diag(cov0),
                         d.T @ d / max(1, len(d) - 1) / len(d),
                         halves.T @ halves / len(halves), Bi @ B, float(s_pos),
                         None if s_rot is None else float(s_rot), int(pairs))
