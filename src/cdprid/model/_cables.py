"""Per-pose cable geometry: leave points, cable vectors and lengths, swivel angles, W.

Notation (paper section 3, names carry their frame):

- ``B_A`` (m, 3): exit points A_i, base frame. With a swivel pulley, A_i is the fixed
  point where the cable enters the pulley, on the swivel axis.
- ``P_b`` (m, 3): attachment points b_i on the platform, platform frame (origin P).
- ``B_p`` (3,): position of P in the base frame; ``B_R_P`` (3, 3): rotation platform -> base.
- ``u_i``: unit vector of cable i from its attachment B_i towards its leave point, base frame.
- ``W`` (6, m): wrench matrix (eq. 2), columns ``[u_i; (B_R_P b_i) x u_i]``: force and
  moment about P, base frame, of unit tensions. The paper writes ``b_i x u_i`` with b_i
  "expressed in the platform frame"; the moment needs b_i rotated into the base frame,
  which is what is implemented (identical when ``B_R_P = I``).

Swivel pulleys (spec v1): the pulley of radius r turns about the unit axis k through A so
that its plane contains the cable. The cable arrives at A travelling along +k, wraps on
the rim, and leaves at the tangent point T towards the attachment. In the pulley plane
(x along the horizontal-to-B direction e, y along k, origin at the pulley centre
C = A + r e), with (px, py) the coordinates of B - C, d = |B - C|, the leave point is at
angle phi = atan2(py, px) + acos(r / d), T = C + r (cos phi e + sin phi k), and the cable
length is r (pi - phi) + |B - T|. The length's gradient with respect to the platform
pose is the straight segment's unit vector, so ``W = -J^T`` with J the Jacobian of the
cable lengths with respect to (position, rotation vector) — tested in the suite.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from cdprid.model._geometry import CableRobot

__all__ = [
    "leave_points",
    "cable_vectors",
    "cable_lengths",
    "unit_vectors",
    "wrench_matrix",
    "swivel_angles",
    "pulley_leave_point",
]


def _safe_unit(v, fallback):
    n2 = v @ v
    ok = n2 > 1e-24
    n = jnp.sqrt(jnp.where(ok, n2, 1.0))
    return jnp.where(ok, v / n, fallback)


def _one_cable(A, b_base, p, r, k, ref):
    """Leave point T, wrap angle and straight segment for one cable (base frame)."""
    B = p + b_base
    v = B - A
    e = _safe_unit(v - (v @ k) * k, ref)
    C = A + r * e
    px = (B - C) @ e
    py = (B - C) @ k
    d = jnp.sqrt(px * px + py * py)
    phi = jnp.arctan2(py, px) + jnp.arccos(jnp.clip(r / d, 0.0, 1.0))
    T = C + r * (jnp.cos(phi) * e + jnp.sin(phi) * k)
    wrap = jnp.pi - phi
    return T, wrap, e


def leave_points(robot: CableRobot, B_p, B_R_P):
    """Points where the cables leave the frame towards the platform, base frame.

    Parameters
    ----------
    robot : CableRobot
    B_p, B_R_P : array (3,), array (3, 3)
        Position of P (m) and rotation platform -> base, base frame.

    Returns
    -------
    array (m, 3)
        Leave points, m; ``robot.B_A`` for cables without pulleys.
    """
    b = (B_R_P @ robot.P_b.T).T
    T, _, _ = _per_cable(robot, B_p, b)
    return T


def _per_cable(robot, B_p, b_base):
    return jax.vmap(_one_cable, in_axes=(0, 0, None, 0, 0, 0))(
        robot.B_A, b_base, B_p, robot.pulley_radius, robot.pulley_axis, robot.pulley_reference
    )


def cable_vectors(robot: CableRobot, B_p, B_R_P):
    """Cable vectors from each attachment B_i to its leave point, base frame.

    Parameters
    ----------
    robot : CableRobot
    B_p, B_R_P : array (3,), array (3, 3)
        Position of P (m) and rotation platform -> base, base frame.

    Returns
    -------
    array (m, 3)
        Vectors, m.
    """
    b = (B_R_P @ robot.P_b.T).T
    T, _, _ = _per_cable(robot, B_p, b)
    return T - (B_p + b)


def cable_lengths(robot: CableRobot, B_p, B_R_P):
    """Cable lengths from the pulley entry point (arc on the rim included) to B_i.

    Parameters
    ----------
    robot : CableRobot
    B_p, B_R_P : array (3,), array (3, 3)
        Position of P (m) and rotation platform -> base, base frame.

    Returns
    -------
    array (m,)
        Lengths, m.
    """
    b = (B_R_P @ robot.P_b.T).T
    T, wrap, _ = _per_cable(robot, B_p, b)
    straight = jnp.linalg.norm(T - (B_p + b), axis=1)
    return straight + robot.pulley_radius * wrap


def unit_vectors(robot: CableRobot, B_p, B_R_P):
    """Unit cable vectors u_i, from attachment towards leave point, base frame.

    Parameters
    ----------
    robot : CableRobot
    B_p, B_R_P : array (3,), array (3, 3)
        Position of P (m) and rotation platform -> base, base frame.

    Returns
    -------
    array (m, 3)
    """
    L = cable_vectors(robot, B_p, B_R_P)
    return L / jnp.linalg.norm(L, axis=1, keepdims=True)


@jax.jit
def wrench_matrix(robot: CableRobot, B_p, B_R_P):
    """Wrench matrix W (6, m) of eq. (2) at one pose: ``W tau`` = cable force and moment about P.

    Jitted: the regression, the guards and the Jacobians of the bound trace it once per
    robot and shape, not once each (start-up time).

    Parameters
    ----------
    robot : CableRobot
    B_p : array (3,)
        Position of P, base frame.
    B_R_P : array (3, 3)
        Rotation platform -> base.

    Returns
    -------
    W : array (6, m)
        Rows 0-2 force (base frame), rows 3-5 moment about P (base frame).
    """
    b = (B_R_P @ robot.P_b.T).T
    T, _, _ = _per_cable(robot, B_p, b)
    L = T - (B_p + b)
    u = L / jnp.linalg.norm(L, axis=1, keepdims=True)
    return jnp.concatenate([u.T, jnp.cross(b, u).T], axis=0)


def swivel_angles(robot: CableRobot, B_p, B_R_P):
    """Swivel angle of each pulley plane about its axis, from ``pulley_reference``.

    Parameters
    ----------
    robot : CableRobot
    B_p, B_R_P : array (3,), array (3, 3)
        Position of P (m) and rotation platform -> base, base frame.

    Returns
    -------
    array (m,)
        Angles, rad.
    """
    b = (B_R_P @ robot.P_b.T).T
    _, _, e = _per_cable(robot, B_p, b)
    k, ref = robot.pulley_axis, robot.pulley_reference
    s = jnp.sum(jnp.cross(ref, e) * k, axis=1)
    c = jnp.sum(ref * e, axis=1)
    return jnp.arctan2(s, c)


def pulley_leave_point(A, b_base, p, r, k, ref):
    """Leave point, wrap angle and in-plane unit vector of one cable over a swivel pulley.

    Parameters
    ----------
    A : (3,) exit point (pulley entry on the swivel axis), base frame
    b_base : (3,) attachment vector ``R b_i``, base frame
    p : (3,) platform position
    r : float, pulley radius
    k : (3,) unit swivel axis, the direction the cable runs into the pulley
    ref : (3,) reference direction used when the cable runs along the axis

    Returns
    -------
    T : (3,) leave point; wrap : float, wrap angle (rad); e : (3,) in-plane unit vector
    """
    return _one_cable(A, b_base, p, r, k, ref)
