# ruff: noqa: F722  (jaxtyping shape strings)
"""Rotation utilities: quaternions (scalar first), rotation matrices, skew matrices.

Conventions (spec v1): a quaternion ``q = [qw, qx, qy, qz]`` is the rotation
platform frame -> base frame, ``B_R_P = quat_to_matrix(q)`` so that a vector
``P_v`` given in the platform frame reads ``B_R_P @ P_v`` in the base frame.
Angular velocities are expressed in the base frame unless their name says ``P_``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float


def skew(v: Float[ArrayLike, " 3"]) -> Float[Array, "3 3"]:
    """Skew-symmetric matrix ``[v]x`` with ``skew(v) @ w == cross(v, w)``.

    Parameters
    ----------
    v : array (3,)

    Returns
    -------
    array (3, 3)
    """
    v = jnp.asarray(v)
    z = jnp.zeros_like(v[0])
    return jnp.array(
        [[z, -v[2], v[1]], [v[2], z, -v[0]], [-v[1], v[0], z]], dtype=v.dtype
    )


def quat_to_matrix(q: Float[ArrayLike, " 4"]) -> Float[Array, "3 3"]:
    """Rotation matrix of a unit quaternion ``[qw, qx, qy, qz]`` (scalar first).

    The quaternion is normalised first, so small norm errors do not leak
    into the rotation.

    Parameters
    ----------
    q : array (4,)

    Returns
    -------
    array (3, 3)
    """
    q = jnp.asarray(q)
    q = q / jnp.linalg.norm(q)
    w, x, y, z = q[0], q[1], q[2], q[3]
    return jnp.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_multiply(a: Float[ArrayLike, " 4"], b: Float[ArrayLike, " 4"]) -> Float[Array, " 4"]:
    """Hamilton product ``a * b`` of two quaternions (scalar first).

    Parameters
    ----------
    a, b : array (4,)

    Returns
    -------
    array (4,)
    """
    a = jnp.asarray(a)
    b = jnp.asarray(b)
    w1, v1 = a[0], a[1:]
    w2, v2 = b[0], b[1:]
    return jnp.concatenate(
        [jnp.array([w1 * w2 - v1 @ v2]), w1 * v2 + w2 * v1 + jnp.cross(v1, v2)]
    )


def quat_conjugate(q: Float[ArrayLike, " 4"]) -> Float[Array, " 4"]:
    """Conjugate ``[qw, -qx, -qy, -qz]``.

    Parameters
    ----------
    q : array (4,)

    Returns
    -------
    array (4,)
    """
    q = jnp.asarray(q)
    return q * jnp.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def rotvec_to_quat(r: Float[ArrayLike, " 3"]) -> Float[Array, " 4"]:
    """Quaternion of a rotation vector (axis * angle), safe at zero angle.

    Parameters
    ----------
    r : array (3,)
        Rotation vector, rad.

    Returns
    -------
    array (4,)
        Unit quaternion, scalar first.
    """
    r = jnp.asarray(r)
    angle2 = r @ r
    angle = jnp.sqrt(jnp.where(angle2 > 0, angle2, 1.0))
    small = angle2 < 1e-12
    half_sinc = jnp.where(small, 0.5 - angle2 / 48.0, jnp.sin(0.5 * angle) / angle)
    w = jnp.where(small, 1.0 - angle2 / 8.0, jnp.cos(0.5 * angle))
    return jnp.concatenate([jnp.array([w]), half_sinc * r])


def matrix_to_quat(R: Float[ArrayLike, "*batch 3 3"]) -> Float[np.ndarray, "*batch 4"]:
    """Unit quaternion (scalar first, qw >= 0) of a rotation matrix (numpy, any batch).

    Shepperd's method, robust for all rotations.

    Parameters
    ----------
    R : array (..., 3, 3)

    Returns
    -------
    numpy.ndarray (..., 4)
    """
    R = np.asarray(R, dtype=float)
    batch = R.shape[:-2]
    R = R.reshape(-1, 3, 3)
    out = np.empty((R.shape[0], 4))
    for k, m in enumerate(R):
        tr = np.trace(m)
        if tr > 0:
            s = 2.0 * np.sqrt(1.0 + tr)
            q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s,
                 (m[1, 0] - m[0, 1]) / s]
        elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
            s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
            q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s,
                 (m[0, 2] + m[2, 0]) / s]
        elif m[1, 1] > m[2, 2]:
            s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
            q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s,
                 (m[1, 2] + m[2, 1]) / s]
        else:
            s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
            q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s,
                 0.25 * s]
        q = np.asarray(q)
        out[k] = q if q[0] >= 0 else -q
    return out.reshape(*batch, 4)


def quat_continuity(q: Float[ArrayLike, "n 4"]) -> Float[np.ndarray, "n 4"]:
    """Flip signs of a quaternion time series so consecutive samples agree.

    ``q`` and ``-q`` are the same rotation; differentiating a series with sign
    jumps would create spikes, so this is applied before differentiation.

    Parameters
    ----------
    q : array (n, 4)

    Returns
    -------
    numpy.ndarray (n, 4)
        A copy; sample k is negated when its dot product with sample k-1 is negative.
    """
    q = np.array(q, dtype=float, copy=True)
    for k in range(1, len(q)):
        if q[k] @ q[k - 1] < 0:
            q[k] = -q[k]
    return q


def angular_rates_from_quat(
    q: Float[ArrayLike, " 4"], qd: Float[ArrayLike, " 4"], qdd: Float[ArrayLike, " 4"]
) -> tuple[Float[Array, " 3"], Float[Array, " 3"]]:
    """Angular velocity and acceleration (base frame) from q, dq/dt, d2q/dt2.

    For ``q`` the rotation platform -> base, ``omega = 2 vec(qd * conj(q))`` and
    ``alpha = d omega/dt = 2 vec(qdd * conj(q))`` (the term ``qd * conj(qd)``
    is a pure scalar and drops out of the vector part).

    Parameters
    ----------
    q, qd, qdd : arrays (4,)

    Returns
    -------
    omega, alpha : arrays (3,), base frame
    """
    qc = quat_conjugate(q) / (jnp.asarray(q) @ jnp.asarray(q))
    omega = 2.0 * quat_multiply(qd, qc)[1:]
    alpha = 2.0 * quat_multiply(qdd, qc)[1:]
    return omega, alpha
