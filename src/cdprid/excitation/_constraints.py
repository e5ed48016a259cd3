"""Safety constraints of the excitation: smooth tension margins (nominal and robust),
exact tension certificate per sample, kinematic margins."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.core import regressors, wrench_matrices
from cdprid.model import quat_to_matrix, smooth_clearances


def _softmin(x, temperature):
    return -temperature * jax.nn.logsumexp(-x / temperature, axis=-1)


def tension_margin_smooth(W, w, tmin: float, tmax: float, temperature: float = 0.5):
    """Smooth, conservative tension margin of one sample.

    ``tau = tau_mid + W^T (W W^T)^-1 (w - W tau_mid)`` (centred least-norm distribution); the
    margin is a soft minimum of ``tau - tmin`` and ``tmax - tau`` (never above the true
    minimum). A positive value proves feasibility; the LP margin can be larger.

    Parameters
    ----------
    W : array (6, m)
        Wrench matrix.
    w : array (6,)
        Required wrench, N and N m.
    tmin, tmax : float
        Tension limits, N.
    temperature : float
        Soft-minimum temperature, N.

    Returns
    -------
    scalar array
        Margin, N.
    """
    mid = 0.5 * (tmin + tmax)
    tau0 = jnp.full(W.shape[1], mid)
    tau = tau0 + W.T @ _cholesky_solve(W @ W.T, w - W @ tau0)
    return _softmin(jnp.concatenate([tau - tmin, tmax - tau]), temperature)


def robust_tension_margin_smooth(W, A_full, x_lo, x_hi, tmin: float, tmax: float,
                                 temperature: float = 0.5):
    """Smooth, conservative tension margin of one sample over a box of parameters.

    The centred least-norm distribution ``tau(x) = base + G x`` with ``G = W^+ A_full`` is
    linear in ``x = [m, m s_G, I_P]``; over the box ``[x_lo, x_hi]`` its i-th tension ranges
    over ``base_i + G_i x_mid +- |G_i| x_half`` exactly. Soft minimum of the distances of those
    ranges to the bounds (never above the true worst case of that distribution).

    Parameters
    ----------
    W : array (6, m)
        Wrench matrix.
    A_full : array (6, 10)
        Full regressor at the sample.
    x_lo, x_hi : array (10,)
        Parameter box (kg, kg m, kg m^2).
    tmin, tmax : float
        Tension limits, N.
    temperature : float
        Soft-minimum temperature, N.

    Returns
    -------
    scalar array
        Margin, N.
    """
    mid = 0.5 * (tmin + tmax)
    tau0 = jnp.full(W.shape[1], mid)
    WWt = W @ W.T + 1e-10 * jnp.eye(6)
    rhs = jnp.concatenate([A_full, (W @ tau0)[:, None]], axis=1)
    sol = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(WWt), rhs)
    G = W.T @ sol[:, :-1]  # (m, 10)
    base = tau0 - W.T @ sol[:, -1]
    xm, xh = 0.5 * (x_lo + x_hi), 0.5 * (x_hi - x_lo)
    centre = base + G @ xm
    spread = jnp.abs(G) @ xh
    return _softmin(jnp.concatenate([centre - spread - tmin, tmax - centre - spread]), temperature)


def _cholesky_solve(A, b):
    """``A^-1 b`` for a small symmetric positive-definite ``A`` by an unrolled Cholesky.

    Written with scalar entries so that, vmapped over the samples of a trajectory, every
    operation is one fused vector operation across samples (cheaper than a batched LAPACK
    solve of 6 x 6 systems, gradients included). ``b`` may be a vector or a matrix (rows
    ``b[i]``). Same result as ``jnp.linalg.solve`` to rounding (tested).
    """
    n = A.shape[0]
    L = [[None] * n for _ in range(n)]
    for j in range(n):
        d = A[j, j] - sum((L[j][k] ** 2 for k in range(j)), 0.0)
        L[j][j] = jnp.sqrt(d)
        for i in range(j + 1, n):
            L[i][j] = (A[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), 0.0)) / L[j][j]
    y = []
    for i in range(n):
        y.append((b[i] - sum((L[i][k] * y[k] for k in range(i)), 0.0)) / L[i][i])
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), 0.0)) / L[i][i]
    return jnp.stack(x)


def _cable_speeds(Wm, states):
    """Cable speeds dl/dt (n, m) = J [v; omega] = -W^T [v; omega] (W = -J^T, see geometry)."""
    tw = jnp.concatenate([states.v, states.omega], axis=1)
    return -jnp.einsum("nim,ni->nm", Wm, tw)


def certify_tensions(W, w, tmin: float, tmax: float):
    """Per-sample largest tension margin (N) by a linear programme through CasADi (HiGHS).

    Parameters
    ----------
    W : array (n, 6, m)
        Wrench matrices (eq. 2).
    w : array (n, 6)
        Required wrenches.
    tmin, tmax : float
        Tension limits, N.

    Returns
    -------
    margin : ndarray (n,)
        ``max s`` such that some tau with ``W tau = w`` lies in ``[tmin + s, tmax - s]``;
        ``-inf`` where ``W tau = w`` has no solution.
    """
    from cdprid.model import feasibility_margin

    return np.atleast_1d(feasibility_margin(np.asarray(W, float), np.asarray(w, float), tmin, tmax))


def _norm(x):
    return jnp.sqrt(jnp.sum(x * x, axis=-1) + 1e-12)


def _kinematic_margins(prob, states):
    """Normalised margins (n, k) of acceleration, jerk and (rotating families) tilt, angular
    velocity and acceleration, at ``fractions.kinematic`` of the limits."""
    lim, f = prob.limits, prob.fractions.kinematic
    pairs = [(_norm(states.a), lim.acceleration_max), (_norm(states.j), lim.jerk_max)]
    if prob.family.rotates:
        tilt = 2.0 * jnp.arctan2(_norm(states.q[:, 1:]), jnp.abs(states.q[:, 0]))
        pairs += [(tilt, lim.tilt_max), (_norm(states.omega), lim.angular_velocity_max),
                  (_norm(states.alpha), lim.angular_acceleration_max)]
    return jnp.stack([(f * L - v) / (0.05 * L) for v, L in pairs], axis=1)


def _constraint_margins(prob, states, states_fine=None):
    """Per-sample normalised margins (>= 0 feasible): workspace, speed, tension, kinematics
    (on ``states_fine`` when given: a finer grid, cheap), clearance."""
    fr, lim = prob.fractions, prob.limits
    lo = jnp.asarray(lim.workspace_min) + fr.workspace_m
    hi = jnp.asarray(lim.workspace_max) - fr.workspace_m
    ws = jnp.minimum(states.p - lo, hi - states.p) / 0.05  # (n, 3)
    R = jax.vmap(quat_to_matrix)(states.q)
    Wm = wrench_matrices(prob.robot, states.p, R)
    sp = (fr.speed * lim.cable_speed_max - jnp.abs(_cable_speeds(Wm, states)))
    sp = sp / (0.05 * lim.cable_speed_max)
    A = regressors("full", R, states.a, states.omega, states.alpha, prob.robot.gravity)
    x_lo, x_hi = jnp.asarray(prob.box.x_lo), jnp.asarray(prob.box.x_hi)
    tm = jax.vmap(lambda W_, A_: robust_tension_margin_smooth(W_, A_, x_lo, x_hi, lim.tension_min,
                                                              lim.tension_max))(Wm, A)
    target = prob.tension_target
    tn = (tm - target) / max(1.0, abs(target))
    clr = lim.cable_clearance
    cc, cb = smooth_clearances(prob.robot, states.p, R, np.asarray(prob.pairs, int).reshape(-1, 2),
                               pulleys=prob.pulleys)
    cl = (jnp.stack([cc, cb], axis=1) - fr.clearance * clr) / clr
    kin = _kinematic_margins(prob, states if states_fine is None else states_fine)
    return ws, sp, tn, kin, cl
