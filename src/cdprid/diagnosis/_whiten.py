"""The clock offset estimated in the metric of the tension noise (issue 37).

The diagnosis weights the six wrench rows by two constants (force and moment rows, from the
base model's residual). The load cells' noise, however, reaches the wrench through the wrench
matrix: its covariance at each sample is ``W(t) S W(t)^T`` (``S`` the cells' in-band noise
variances), with force and moment rows strongly correlated (a cable's moment is ``b x`` its
force) and a shape that follows the pose. The clock offset is read from the timing of the
tensions, so its estimate is dominated by that noise; with the diagonal row weights the
AR(1) noise of the floor-winch benchmark moved it by 0.80 ms (std over 30 simulated noise
draws on the noise-free model; +1.56 ms for the benchmark's own draw of seed 3), in the metric
of :func:`noise_metric` by 0.16 ms (-0.11 ms for that draw). A generalised least squares in
that metric is the efficient estimate; any metric gives a consistent one, and its interval
comes from the HAC covariance in the same metric, so a metric that fits the noise badly costs
precision, never coverage.

:func:`noise_metric` fits the residual's row covariance as ``sum_j a_j w_j w_j^T + diag(d)``
(``w_j`` cable j's column of W, ``a_j, d >= 0``: each cell's noise through its cable and what
the cells do not explain, pose noise and model misfit) by non-negative least squares on the
residual's outer products, and returns the per-sample whitening. :func:`whitened_delay`
profiles the delay exactly (shifts of the tension stream, every other parameter of the model
re-solved at its linearisation) in that metric and gives its HAC variance there.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import nnls

from cdprid.diagnosis._problem import Problem, design
from cdprid.diagnosis._profile import GRID_S, profile_interval, shift_wrenches
from cdprid.diagnosis._testing import hac_cov

#: the unique entries of a symmetric 6 x 6 matrix (upper triangle)
_IU = np.triu_indices(6)


def noise_metric(prob: Problem, resid: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Per-sample whitening ``L(t)^-1`` of the residual's modelled row covariance.

    Parameters
    ----------
    prob : Problem
        Its nominal wrench matrices ``W_all`` and row weights ``wrow`` (which balance the
        fit of the covariance between force and moment rows).
    resid : numpy.ndarray (n, 6)
        The model's filtered residual, unweighted (N and N m).
    rows : numpy.ndarray (n,) bool
        The samples the covariance is fitted on (the training samples).

    Returns
    -------
    numpy.ndarray (k, 6, 6)
        For each of the ``rows`` samples the inverse Cholesky factor of ``M(t) = sum_j a_j
        w_j w_j^T + diag(d)``: ``Linv @ r`` has unit covariance when the model holds.
    """
    W = prob.W_all[rows]  # (k, 6, m)
    r = resid[rows]
    k, _, m = W.shape
    scale = np.outer(prob.wrow, prob.wrow)[_IU]  # balance N^2, N^2 m, N^2 m^2 entries
    basis = [np.einsum("ti,tj->tij", W[:, :, j], W[:, :, j])[:, _IU[0], _IU[1]] * scale
             for j in range(m)]
    for i in range(6):
        e = np.zeros(len(_IU[0]))
        e[[n for n, (a, b) in enumerate(zip(*_IU, strict=True)) if a == b == i]] = 1.0
        basis.append(np.broadcast_to(e * scale, (k, len(e))))
    A = np.stack([b.reshape(-1) for b in basis], axis=1)
    target = (np.einsum("ti,tj->tij", r, r)[:, _IU[0], _IU[1]] * scale).reshape(-1)
    coef, _ = nnls(A, target, maxiter=50 * A.shape[1])
    a, d = coef[:m], coef[m:]
    # a floor on the diagonal part (a robot with fewer than 6 cables has a singular W S W^T)
    d = np.maximum(d, 1e-6 * np.mean(np.diag(np.mean(np.einsum("ti,tj->tij", r, r), axis=0))))
    M = np.einsum("tij,j,tkj->tik", W, a, W) + np.diag(d)[None]
    L = np.linalg.cholesky(M)
    return np.linalg.inv(L)


def _golden(cost_at, lo: float, hi: float, tol_s: float = 1e-4) -> tuple[float, float]:
    """Minimum of a unimodal ``cost_at(d)`` on ``[lo, hi]`` by golden section."""
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo + (1 - g) * (hi - lo), lo + g * (hi - lo)
    fa, fb = cost_at(a), cost_at(b)
    while hi - lo > tol_s:
        if fa < fb:
            hi, b, fb = b, a, fa
            a = lo + (1 - g) * (hi - lo)
            fa = cost_at(a)
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = cost_at(b)
    return (a, fa) if fa < fb else (b, fb)


def _low_pass(prob: Problem, cutoff_hz: float | None):
    """``(low, lags)``: a further zero-phase low-pass along time of ``(n, ...)`` arrays and
    of ``(k, n, 6)`` stacks (the identity when ``cutoff_hz`` is None), and the HAC lags."""
    if cutoff_hz is None:
        return (lambda a: a), prob.lags
    from cdprid.signal import zero_phase_filter

    def low(a):
        a = np.asarray(a)
        if a.ndim == 3 and a.shape[1] != 6:  # (k, n, 6) stacks of shifts
            return np.stack([low(x) for x in a])
        return zero_phase_filter(a.reshape(a.shape[0], -1), prob.dt, cutoff_hz,
                                 2).reshape(a.shape)

    return low, int(math.ceil(3.0 / (cutoff_hz * prob.dt)))


def whitened_delay(prob: Problem, s, di: int, cutoff_hz: float | None = None) -> dict:
    """The clock offset of the model ``s`` (delay active at theta index ``di``) estimated in
    the tension noise's metric (:func:`noise_metric`).

    Every other parameter of ``s`` is re-solved at ``s``'s linearisation for each exact
    shift of the tension stream (the joint profile of :mod:`cdprid.diagnosis._profile`, in
    the whitened metric); the minimum is refined by golden section; the variance is the HAC
    variance of the whitened linear model re-linearised at that delay.

    Parameters
    ----------
    prob : Problem
    s : Selection
        A model with the clock offset among its active parameters.
    di : int
        The clock offset's theta index.
    cutoff_hz : float (Hz), optional
        A further zero-phase low-pass (order 2) applied to both sides of the linear model
        before the metric (the HAC lags scaled to it). None (the diagnosis' choice): the
        matched filter alone. On floor8 seed 3 a 2 Hz one moved the named delay's error from
        +1.58 to +0.56 ms (one noise draw, +0.28 to +0.11 ms on another); not yet measured on
        other robots or on real recordings, so not used.

    Returns
    -------
    dict
        ``delay_s`` (s), ``var`` (s^2), ``interval`` ``(lo, hi, open_ends)`` (s), ``grid``
        and ``cost`` (the whitened profile over :data:`GRID_S`).
    """
    tr = prob.train
    active = list(s.active_idx)
    others = [i for i in active if i != di]
    low, lags = _low_pass(prob, cutoff_hz)
    y_now, Am, C = (low(a) for a in design(prob, s.theta, s.x, s.rotational))
    Linv = noise_metric(prob, y_now - np.einsum("nij,j->ni", Am, s.x[:Am.shape[2]]), tr)
    Co = C[tr][:, :, others]
    Z = np.einsum("tij,tjp->tip", Linv, np.concatenate([Am[tr], Co], axis=2))
    Q = np.linalg.qr(Z.reshape(-1, Z.shape[2]))[0]
    d_cur = float(s.theta[di])
    base = y_now[tr] + np.einsum("nij,j->ni", Co, s.theta[others])
    now = low(shift_wrenches(prob, [d_cur])[0])[tr]

    def costs(delays):
        S = low(shift_wrenches(prob, list(delays)))[:, tr]
        T = np.einsum("tij,ktj->kti", Linv, base[None] + S - now[None]).reshape(len(delays), -1).T
        R = T - Q @ (Q.T @ T)
        return np.einsum("ik,ik->k", R, R)

    cost = costs(GRID_S)
    k = int(np.argmin(cost))
    d_w, c_w = _golden(lambda d: float(costs([d])[0]), GRID_S[max(k - 1, 0)],
                       GRID_S[min(k + 1, len(GRID_S) - 1)])
    d_w = d_w if c_w <= cost[k] else float(GRID_S[k])
    theta = np.array(s.theta, float)
    theta[di] = d_w
    y2, A2, C2 = (low(a) for a in design(prob, theta, s.x, s.rotational))
    Z2 = np.einsum("tij,tjp->tip", Linv, np.concatenate([A2[tr], C2[tr][:, :, active]], axis=2))
    t2 = np.einsum("tij,tj->ti", Linv, y2[tr] + np.einsum("nij,j->ni", C2[tr][:, :, active],
                                                           theta[active]))
    p = Z2.shape[2]
    beta, *_ = np.linalg.lstsq(Z2.reshape(-1, p), t2.reshape(-1), rcond=None)
    e = t2 - np.einsum("tip,p->ti", Z2, beta)
    col = A2.shape[2] + active.index(di)
    var = float(hac_cov(Z2, e, lags)[col, col])
    return {"delay_s": float(d_w), "var": var,
            "interval": profile_interval(GRID_S, cost, float(d_w), var),
            "grid": GRID_S, "cost": cost}
