"""The excitation for an identification from motor currents (issue 41): the joint regressor
of the platform's and the drives' parameters along a designed trajectory.

``identify --source currents`` fits ``Y theta = D d`` (``cdprid.core.drive_columns``: per
drive ``d = (k, J, f_v, f_c, c)`` of ``tau = k i + J l'' + f_v l' + f_c sign(l') - c``) with
one drive's ``k`` given (the scale reference): its design matrix is
``[Y, -W i, -W l'', -W l', -W sign(l'), W]`` without the reference's ``k`` column. What a
trajectory makes of it is predicted here before the robot moves:

* the cable length rates ``l'`` and ``l''`` are exact: the lengths (pulley arcs included,
  :func:`cdprid.model.cable_lengths`) differentiated twice in time along the trajectory's
  second-order pose path (position, velocity, acceleration; rotation vector, angular rate and
  acceleration);
* the currents are those of the nominal platform (the uncertainty box's) carried by the
  tensions closest to the middle of the tension range (``tau_mid + W^+ (w - W tau_mid)``),
  through the nominal drives (datasheet ``k = N K_t / r``, no friction, inertia or offset:
  the columns' sizes, not their exact values, set the conditioning);
* ``sign(l')`` is smoothed over :data:`SLIDE_M_S` (a cable that nearly stops gives no
  Coulomb column).

The objective is the column-scaled condition number (the columns mix N/A, kg, N s/m and N).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from cdprid.core import regressors
from cdprid.model import TrajectoryState, cable_lengths, quat_to_matrix, wrench_matrix

__all__ = ["SLIDE_M_S", "currents_regressor", "length_rates"]

#: Cable speed (m/s) over which the Coulomb column's sign is smoothed (``tanh(l' / v)``)
SLIDE_M_S = 0.01


def _skew(w):
    return jnp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def length_rates(robot, states: TrajectoryState):
    """Cable length rates ``l'`` and ``l''`` (n, m) along the trajectory (m/s, m/s^2; ``l`` is
    the length paid out, pulley arcs included).

    Parameters
    ----------
    robot : CableRobot
    states : TrajectoryState
        n samples (position, velocity, acceleration, quaternion, angular velocity and
        acceleration).

    Returns
    -------
    ldot, lddot : array (n, m)
    """

    def one(p, v, a, q, w, al):
        R = quat_to_matrix(q)

        def length(s):  # the pose path to second order in s (all that l', l'' at 0 read)
            X = _skew(w * s + 0.5 * al * s * s)
            return cable_lengths(robot, p + v * s + 0.5 * a * s * s,
                                 (jnp.eye(3) + X + 0.5 * X @ X) @ R)

        d1 = jax.jacfwd(length)
        return d1(0.0), jax.jacfwd(d1)(0.0)

    return jax.vmap(one)(states.p, states.v, states.a, states.q, states.omega, states.alpha)


def currents_regressor(robot, states: TrajectoryState, model: str, theta, k_nominal,
                       reference: int, tension_min: float, tension_max: float):
    """The joint regressor (6 n, p + 5 m - 1) of ``identify --source currents`` along the
    trajectory (see the module docstring), rows sample by sample.

    Parameters
    ----------
    robot : CableRobot
    states : TrajectoryState
    model : {"translation", "full"}
    theta : array (p,)
        The nominal platform's parameters (SI).
    k_nominal : array (m,)
        The drives' nominal current-to-force constants, N/A.
    reference : int
        The drive whose ``k`` is given (0-based): its column is left out.
    tension_min, tension_max : float
        The tension range, N (the tensions are the closest to its middle).

    Returns
    -------
    array (6 n, p + 5 m - 1)
        Columns: the platform's ``p``, then per kind (``k`` without the reference's, ``J``,
        ``f_v``, ``f_c``, ``c``) one per drive.
    """
    R = jax.vmap(quat_to_matrix)(states.q)
    Y = regressors(model, R, states.a, states.omega, states.alpha, robot.gravity)  # (n, 6, p)
    W = jax.vmap(lambda p, Rk: wrench_matrix(robot, p, Rk))(states.p, R)  # (n, 6, m)
    m = W.shape[2]
    w = jnp.einsum("nip,p->ni", Y, jnp.asarray(theta))
    mid = jnp.full((m,), 0.5 * (tension_min + tension_max))

    def spread(Wk, wk):  # tensions closest to the middle that carry wk (a tiny ridge)
        G = Wk @ Wk.T
        G = G + 1e-12 * jnp.trace(G) * jnp.eye(6)
        return mid + Wk.T @ jnp.linalg.solve(G, wk - Wk @ mid)

    tau = jax.vmap(spread)(W, w)
    ldot, lddot = length_rates(robot, states)
    current = tau / jnp.asarray(k_nominal)[None, :]
    cols = [W * x[:, None, :] for x in (current, lddot, ldot, jnp.tanh(ldot / SLIDE_M_S))]
    keep = jnp.asarray([j for j in range(m) if j != reference], int)
    D = jnp.concatenate([cols[0][:, :, keep]] + cols[1:] + [-W], axis=2)
    return jnp.concatenate([Y, -D], axis=2).reshape(-1, Y.shape[2] + D.shape[2])
