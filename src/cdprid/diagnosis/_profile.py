"""The tension clock offset profiled jointly with every other effect of a model (issue 37).

A clock offset between the tension and pose streams enters the model nonlinearly (the tension
stream is read at ``t + delay``), and velocity-like effects (friction on every pulley, drag)
alias part of it: a profile against the base model alone put its minimum at +38 ms on a
recording with a 22 ms offset and friction on every pulley. Here the delay is a nonlinear
parameter of every model the search compares: :func:`joint_delay` minimises the training cost
concentrated over everything else of the model (the platform parameters and every other
active effect, linear at the model's linearisation) over a grid of exact shifts of the tension
stream, refined by golden section; the Gauss-Newton refit then starts from there
(:func:`cdprid.diagnosis._selection.refit`). The shifted wrenches of the grid are computed
once per recording and reused (Gram products only per model).

:func:`profile_interval` turns the concentrated cost into a 95 % interval calibrated on the
HAC variance at the optimum (a flat or asymmetric profile widens it; the Wald interval is
its quadratic limit).
"""

from __future__ import annotations

import math

import jax
import numpy as np

from cdprid.base import chi2_sf
from cdprid.core import CATMULL_ROM, tension_at
from cdprid.diagnosis._problem import Problem, design
from cdprid.effects import DIAGNOSIS

#: delays profiled, s (every 2 ms within +-0.1 s)
GRID_S = np.round(np.arange(-0.1, 0.1 + 1e-9, 0.002), 6)
#: chi-square(1) 95 % quantile
CHI2_95 = 3.841458820694124


def clock_index(prob: Problem) -> int | None:
    """Theta index of the clock offset (the form declared ``clock=True``), if any."""
    for name, form in DIAGNOSIS.items():
        if form.clock:
            return prob.layout.candidate_indices(name)[0]
    return None


@jax.jit
def _shifted(d, s):
    """The tension stream read at the pose times shifted by ``s`` (n, m); the data are an
    argument (compiled once per shape, not once per problem with the data as constants)."""
    return tension_at(d.stream, d.t + s, CATMULL_ROM)


def _shift_fn(prob: Problem):
    store = prob.cache.setdefault("clock_shift", {})
    if "fn" not in store:
        store["fn"] = lambda s: _shifted(prob.d, s)
    return store


def shift_wrenches(prob: Problem, delays) -> np.ndarray:
    """Matched-filtered nominal cable wrenches ``W tau(t + d)`` (n, 6) for each delay, stacked
    ``(k, n, 6)`` (unweighted); the grid's are kept in ``prob.cache``."""
    store = _shift_fn(prob)
    out, todo = {}, []
    for d in delays:
        key = round(float(d), 9)
        if key in store:
            out[key] = store[key]
        elif key not in todo:
            todo.append(key)
    if todo:
        w = np.stack([np.einsum("nij,nj->ni", prob.W_all, np.asarray(store["fn"](d)))
                      for d in todo], axis=1)  # (n, k, 6)
        w = prob.filt(w)
        for j, key in enumerate(todo):
            out[key] = np.ascontiguousarray(w[:, j])
            if np.any(np.isclose(key, GRID_S, atol=1e-9)):
                store[key] = out[key]
    return np.stack([out[round(float(d), 9)] for d in delays])


def _projector(Z_train):
    Q = np.linalg.qr(Z_train.reshape(-1, Z_train.shape[2]))[0]
    return Q


def _costs(prob: Problem, Q, target_tr, d_cur: float, delays) -> np.ndarray:
    """Training cost (weighted units) of the model with the tension stream at each delay."""
    tr = prob.train
    if len(delays) == len(GRID_S) and np.array_equal(delays, GRID_S):
        # the grid's shifts at the training rows are kept (stacked once per problem)
        store = _shift_fn(prob)
        if "grid_train" not in store:
            store["grid_train"] = shift_wrenches(prob, GRID_S)[:, tr]
        now = shift_wrenches(prob, [d_cur])[0][tr]
        dY = (store["grid_train"] - now[None]) * prob.wrow[None, None, :]
    else:
        S = shift_wrenches(prob, list(delays) + [d_cur])
        dY = (S[:-1] - S[-1][None])[:, tr] * prob.wrow[None, None, :]  # (k, ntr, 6)
    T = (target_tr[None] + dY).reshape(len(delays), -1).T  # (ntr*6, k)
    R = T - Q @ (Q.T @ T)
    return np.einsum("ik,ik->k", R, R)


def _parts(prob: Problem, theta, x, rotational: bool, active_idx, di: int):
    """The model's columns without the delay (weighted), its target at the current delay."""
    y_now, Am, C = design(prob, theta, x, rotational)
    others = [i for i in active_idx if i != di]
    Co = C[:, :, others]
    tr = prob.train
    Z = np.concatenate([Am[tr], Co[tr]], axis=2) * prob.wrow[None, :, None]
    target = (y_now[tr] + np.einsum("nij,j->ni", Co[tr], np.asarray(theta)[others])) * prob.wrow
    return _projector(Z), target


def joint_profile(prob: Problem, theta, x, rotational: bool, active_idx, grid=GRID_S):
    """Training cost of the model over ``grid`` of delays, every other parameter re-solved.

    Returns ``(grid, cost, (Q, target, d_cur))``; the last item evaluates further delays
    (:func:`joint_delay`).
    """
    di = clock_index(prob)
    Q, target = _parts(prob, theta, x, rotational, active_idx, di)
    d_cur = float(np.asarray(theta)[di])
    return np.asarray(grid), _costs(prob, Q, target, d_cur, grid), (Q, target, d_cur)


def joint_delay(prob: Problem, theta, x, rotational: bool, active_idx, grid=GRID_S,
                tol_s: float = 1e-4) -> float:
    """The delay minimising the training cost jointly with the model's other parameters.

    The grid's minimum, refined by golden section within its neighbours (exact shifts).
    """
    grid, cost, (Q, target, d_cur) = joint_profile(prob, theta, x, rotational, active_idx, grid)
    k = int(np.argmin(cost))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo + (1 - g) * (hi - lo), lo + g * (hi - lo)
    fa, fb = _costs(prob, Q, target, d_cur, [a, b])
    while hi - lo > tol_s:
        if fa < fb:
            hi, b, fb = b, a, fa
            a = lo + (1 - g) * (hi - lo)
            fa = _costs(prob, Q, target, d_cur, [a])[0]
        else:
            lo, a, fa = a, b, fb
            b = lo + g * (hi - lo)
            fb = _costs(prob, Q, target, d_cur, [b])[0]
    best = 0.5 * (lo + hi)
    return float(best if min(fa, fb) <= cost[k] else grid[k])


def _parabola(c_minus: float, c_0: float, c_plus: float, h: float) -> tuple[float, float]:
    """The profile's curvature and the vertex of the parabola through three costs ``h`` apart
    (the vertex meaningful only for a positive curvature)."""
    curv = (c_minus - 2.0 * c_0 + c_plus) / h**2
    with np.errstate(divide="ignore", invalid="ignore"):
        return float(curv), float(c_0 - (c_plus - c_minus) ** 2 / (8.0 * curv * h**2))


def profile_interval(grid, cost, d_star: float, var: float, level: float = CHI2_95):
    """95 % interval of the delay from its concentrated training cost, HAC-calibrated.

    Near the optimum the cost is ``c* + h/2 (d - d*)^2``; the likelihood-ratio statistic is
    scaled so that its quadratic part equals the Wald statistic with the HAC variance
    ``var``: ``LR(d) = 2 (c(d) - c*) / (h var)``. The interval is where ``LR <= level``
    (linear interpolation between grid points), united with the Wald interval; an end that
    reaches the grid's edge is the edge (the offset may lie beyond it).

    Returns ``(lo, hi, open_ends)``.
    """
    grid, cost = np.asarray(grid, float), np.asarray(cost, float)
    z = math.sqrt(level)
    sd = math.sqrt(max(var, 0.0))
    wald = (d_star - z * sd, d_star + z * sd)
    h = grid[1] - grid[0]
    k = int(np.argmin(cost))
    if not 0 < k < len(grid) - 1:
        return (min(wald[0], grid[0]) if k == 0 else wald[0],
                max(wald[1], grid[-1]) if k == len(grid) - 1 else wald[1], True)
    curv, c_vertex = _parabola(cost[k - 1], cost[k], cost[k + 1], h)
    if not (curv > 0 and var > 0):
        return float(grid[0]), float(grid[-1]), True
    c_star = min(float(cost.min()), c_vertex)
    lr = 2.0 * (cost - c_star) / (curv * var)
    ends, open_ends = [], False
    for step in (-1, 1):
        j = k
        while 0 <= j + step < len(grid) and lr[j + step] <= level:
            j += step
        if 0 <= j + step < len(grid):
            f = (level - lr[j]) / max(lr[j + step] - lr[j], 1e-300)
            ends.append(grid[j] + step * h * min(max(f, 0.0), 1.0))
        else:
            ends.append(grid[j])
            open_ends = True
    return float(min(ends[0], wald[0])), float(max(ends[1], wald[1])), open_ends


def clock_removal_test(prob: Problem, Z, y, col: int, d_star: float, var: float,
                       heldout) -> tuple[float, float]:
    """Held-out gain and p-value of the clock offset in a linear model, by exact shifts.

    The linearised clock column (the derivative of the tension stream read at ``t + d``)
    carries the stream's noise and the delay-dependence of the other columns: on a 100 Hz
    4-cable recording with a 2 N hysteretic cell and no offset its one-step estimate was
    -2.4 ms (Wald p 7.5e-6) where the joint profile's minimum was -1.0 ms and its interval
    [-2.0, 0.1] ms held the truth. Here the model without the offset is the model with the
    tension stream read at the pose times (``d = 0``), every other column as linearised, and
    the test is the profile's: the training cost at ``d = 0`` against its minimum at
    ``d_star``, scaled by the curvature and the HAC variance ``var`` as in
    :func:`profile_interval`, so that a finding is kept only where the interval reported
    for it excludes zero at the test's level.

    Parameters
    ----------
    prob : Problem
    Z, y : ndarray
        Weighted columns ``(n, 6, p)`` and target ``(n, 6)`` of
        :func:`cdprid.diagnosis._selection.linear_model`.
    col : int
        The clock offset's column in ``Z``.
    d_star : float
        The model's clock offset, s.
    var : float
        Its HAC variance, s^2.
    heldout : callable
        ``heldout(Z, y)``: the held-out RMS of a linear model.

    Returns
    -------
    (gain, p)
        ``1 - rms(with) / rms(without)`` and the chi-square(1) p-value of ``d = 0``
        (1 where the profile is flat or not convex at ``d_star``).
    """
    rest = [j for j in range(Z.shape[2]) if j != col]
    Zr = Z[:, :, rest]
    y_fix = y - Z[:, :, col] * d_star  # the target with the offset held at d_star
    tr = prob.train
    h = float(GRID_S[1] - GRID_S[0])
    Q = _projector(Zr[tr])
    cm, c0, cp, cz = _costs(prob, Q, y_fix[tr], d_star, [d_star - h, d_star, d_star + h, 0.0])
    curv, c_vertex = _parabola(cm, c0, cp, h)
    p = 1.0
    if curv > 0 and var > 0:
        c_star = min(c0, c_vertex)
        p = float(chi2_sf(max(2.0 * (cz - c_star) / (curv * var), 0.0), 1))
    S = shift_wrenches(prob, [0.0, d_star])
    y0 = y_fix + (S[0] - S[1]) * prob.wrow[None, :]
    return 1.0 - heldout(Zr, y_fix) / heldout(Zr, y0), p
