"""The currents' noise inside the regressor of ``identify --source currents``: its expected
contribution ``Q`` to the normal equations and the corrected least squares ``(N - Q) theta =
0`` with the std its own randomness adds (:mod:`cdprid.identify._currents`)."""

from __future__ import annotations

import numpy as np

__all__ = ["corrected", "normal_and_noise"]


def normal_and_noise(full, U, n: int, m: int, p: int, noise: dict, chunk: int):
    """The whitened normal matrix ``N`` of the full theta (reference included) and ``Q``, the
    expected contribution of the current and encoder noise inside the regressor:
    ``E[dM^T Omega dM]`` on the columns of k (``g_i sigma_i^2 W_j^T Omega W_j``), J and f_v
    (``C22``, ``C11``, ``C12`` times the encoder variance) of each cable."""
    q = p + 5 * m
    N, G = np.zeros((q, q)), np.zeros(m)
    C = noise["C"]
    for i0 in range(0, n, chunk):
        i1 = min(n, i0 + chunk)
        M = np.matmul(U[i0:i1], full(i0, i1))
        N += np.einsum("kap,kaq->pq", M, M)
        Wu = -M[:, :, p + 4 * m:]  # U W_j: the offset columns are -F[W_j] (filtered W)
        G += np.einsum("kaj,kaj->j", Wu, Wu)
    Q = np.zeros((q, q))
    sl2 = noise["length_m"] ** 2
    kk, JJ, vv = (np.arange(m) + p + j * m for j in range(3))
    Q[kk, kk] = noise["g_current"] * noise["current_A"] ** 2 * G
    Q[JJ, JJ] = C[2, 2] * sl2 * G
    Q[vv, vv] = C[1, 1] * sl2 * G
    Q[JJ, vv] = Q[vv, JJ] = C[1, 2] * sl2 * G
    return N, Q


def corrected(N, Q, o, r, n_eff: float, prior=None):
    """The corrected least squares ``(N - Q) theta = 0`` (reference ``r`` fixed at 1), with
    optional Gaussian priors, the map of the GLS covariance, and the std the correction's own
    randomness adds.

    The noise part of ``N`` equals ``Q`` only on average: over ``n_eff`` independent samples
    (samples / HAC bandwidth) it fluctuates by about ``delta = sqrt(2 / n_eff)`` of itself.
    Where the estimate is sensitive to it (a direction in which the currents' noise is a large
    share of the regressor: weak identification), the estimates at ``N - (1 +- delta) Q``
    differ; half their difference is added as a std (negligible when the identification is
    strong). When ``N - lam Q + P`` is singular for some ``lam`` within ``1 +- 3 delta`` the
    estimate is not determined: every std is infinite (the report says it cannot tell).

    Parameters
    ----------
    N, Q : (q, q) whitened normal matrix and the noise's expected part
    o : (q - 1,) indices of the free parameters; r : the reference's index
    n_eff : float
    prior : (precision (q,), mean (q,)) or None
        Independent Gaussian priors on the fit's scale (precision 0: none).

    Returns
    -------
    phi (q - 1,), Ainv (q - 1, q - 1), Pdiag (q - 1,), extra (q - 1,), mu
        ``Cov(phi) = Ainv (N_oo C N_oo + diag(Pdiag)) Ainv + extra extra^T`` for the GLS
        covariance ``C``; ``mu`` the largest share of the regressor's energy that is noise.
    """
    import scipy.linalg as sl

    oo = np.ix_(o, o)
    P, pm = (np.zeros(N.shape[0]), np.zeros(N.shape[0])) if prior is None else prior
    Po = P[o]

    def solve(lam):
        Nc = N - lam * Q
        return np.linalg.solve(Nc[oo] + np.diag(Po), -Nc[o, r] + Po * pm[o])

    phi = solve(1.0)
    Ainv = np.linalg.inv((N - Q)[oo] + np.diag(Po))
    delta = float(np.sqrt(2.0 / max(n_eff, 2.0)))
    mu = float(sl.eigh(Q[oo], N[oo] + np.diag(Po), eigvals_only=True)[-1])
    if mu * (1.0 + 3.0 * delta) >= 1.0:  # singular within the noise: cannot tell
        return phi, Ainv, Po, np.full(len(phi), np.inf), mu
    extra = 0.5 * (solve(1.0 + delta) - solve(1.0 - delta))
    return phi, Ainv, Po, extra, mu
