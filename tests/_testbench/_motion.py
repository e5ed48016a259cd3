"""Platform motion and Newton-Euler of the test simulator (numpy, its own derivation).

The position is a sum of sines (exact derivatives); the angular velocity (base frame) is a sum
of cosines whose integral is a rotation of at most the stated angle, and the orientation is
integrated from it (RK4 on the unit quaternion, ``qdot = 1/2 [0, omega] * q``, 1 ms steps,
renormalised).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Motion:
    """Sampled motion of the platform at times ``t`` (base frame, P the reference point)."""

    t: np.ndarray  # (n,) s
    p: np.ndarray  # (n, 3) m
    v: np.ndarray  # (n, 3) m/s
    a: np.ndarray  # (n, 3) m/s^2
    q: np.ndarray  # (n, 4) unit quaternion, scalar first, platform -> base
    R: np.ndarray  # (n, 3, 3)
    w: np.ndarray  # (n, 3) angular velocity, base frame, rad/s
    al: np.ndarray  # (n, 3) angular acceleration, base frame, rad/s^2


@dataclasses.dataclass(frozen=True)
class Path:
    """A trajectory: ``p = p0 + sum_j P_j sin(f_j t + phi_j)``; ``w = sum_j Q_j g_j cos(g_j t
    + psi_j)`` (so the rotation vector stays near ``sum_j Q_j sin(...)``)."""

    p0: np.ndarray  # (3,)
    P: np.ndarray  # (J, 3) amplitudes, m
    f: np.ndarray  # (J,) rad/s
    phi: np.ndarray  # (J,)
    Q: np.ndarray  # (K, 3) rotation amplitudes, rad
    g: np.ndarray  # (K,) rad/s
    psi: np.ndarray  # (K,)


def random_path(rng, center, half_range, max_angle_rad, n_terms: int = 4,
                freq_hz=(0.12, 0.6)) -> Path:
    """A rich random trajectory within ``center +- half_range`` rotating up to ``max_angle``."""
    f = 2 * np.pi * rng.uniform(*freq_hz, size=n_terms)
    P = rng.uniform(-1, 1, size=(n_terms, 3)) * np.asarray(half_range) / n_terms
    g = 2 * np.pi * rng.uniform(0.15, 0.7, size=n_terms)
    Q = rng.uniform(-1, 1, size=(n_terms, 3))
    Q *= max_angle_rad / max(np.sum(np.linalg.norm(Q, axis=1)), 1e-12)
    return Path(np.asarray(center, float), P, f, rng.uniform(0, 2 * np.pi, n_terms), Q, g,
                rng.uniform(0, 2 * np.pi, n_terms))


def _omega(path: Path, t):
    arg = np.outer(t, path.g) + path.psi
    w = (np.cos(arg) * path.g) @ path.Q
    al = (-np.sin(arg) * path.g**2) @ path.Q
    return w, al


def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


def _Omega(w):
    """``1/2 [0, w] *`` as 4 x 4 matrices (n, 4, 4): ``qdot = Omega(w) q``."""
    x, y, z = w[:, 0], w[:, 1], w[:, 2]
    o = np.zeros_like(x)
    return 0.5 * np.stack([np.stack([o, -x, -y, -z], -1), np.stack([x, o, -z, y], -1),
                           np.stack([y, z, o, -x], -1), np.stack([z, -y, x, o], -1)], -2)


def _rk4_maps(path, t0, h):
    """One RK4 step of the linear ODE ``qdot = Omega(w(t)) q`` from ``t0`` by ``h`` (arrays),
    as the matrices M with ``q(t0 + h) ~ M q(t0)``."""
    A0 = _Omega(_omega(path, t0)[0])
    Ah = _Omega(_omega(path, t0 + h / 2)[0])
    A1 = _Omega(_omega(path, t0 + h)[0])
    H = h[:, None, None]
    eye = np.eye(4)
    K1 = A0
    K2 = Ah @ (eye + H / 2 * K1)
    K3 = Ah @ (eye + H / 2 * K2)
    K4 = A1 @ (eye + H * K3)
    return eye + H / 6 * (K1 + 2 * K2 + 2 * K3 + K4)


def integrate_orientation(path: Path, t, step: float = 1e-3) -> np.ndarray:
    """Unit quaternions (n, 4) at the times ``t >= 0`` (identity at ``t = 0``).

    RK4 on a uniform grid of ``step`` (each step a 4 x 4 map, renormalised), then one RK4
    step of the remaining fraction from the grid point below each time.
    """
    t = np.asarray(t, float)
    n_grid = int(np.floor(np.max(t) / step)) + 2 if len(t) else 1
    tg = np.arange(n_grid) * step
    M = _rk4_maps(path, tg[:-1], np.full(n_grid - 1, step))
    qg = np.empty((n_grid, 4))
    q = np.array([1.0, 0.0, 0.0, 0.0])
    qg[0] = q
    for j in range(n_grid - 1):
        q = M[j] @ q
        q /= np.sqrt(q @ q)
        qg[j + 1] = q
    g = np.clip(np.floor(t / step).astype(int), 0, n_grid - 1)
    Mq = _rk4_maps(path, tg[g], t - tg[g])
    out = np.einsum("nij,nj->ni", Mq, qg[g])
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def quat_matrix(q):
    """Rotation matrices (n, 3, 3) of unit quaternions (n, 4), scalar first."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def motion(path: Path, t) -> Motion:
    """The motion at the increasing times ``t`` (orientation integrated from t = 0)."""
    t = np.asarray(t, float)
    arg = np.outer(t, path.f) + path.phi
    p = path.p0 + np.sin(arg) @ path.P
    v = (np.cos(arg) * path.f) @ path.P
    a = (-np.sin(arg) * path.f**2) @ path.P
    w, al = _omega(path, t)
    q = integrate_orientation(path, t)
    return Motion(t, p, v, a, q, quat_matrix(q), w, al)


def newton_euler(mo: Motion, mass, com_P, inertia_G_P, gravity, drag_Ns_per_m: float = 0.0):
    """The wrench (n, 6) the cables must apply at P: force and moment about P, base frame.

    ``f = m (a + al x c + w x (w x c) - g) + drag v`` and
    ``n = I_P al + w x (I_P w) + m c x (a - g)``, with ``c = R s_G`` and
    ``I_P = R I_G R^T + m (|c|^2 1 - c c^T)`` (a viscous drag ``-drag v`` acts at P, so the
    cables supply ``+drag v`` more).
    """
    g = np.asarray(gravity, float)
    c = np.einsum("nij,j->ni", mo.R, np.asarray(com_P, float))
    IG = np.einsum("nij,jk,nlk->nil", mo.R, np.asarray(inertia_G_P, float), mo.R)
    cc = np.einsum("ni,ni->n", c, c)[:, None, None] * np.eye(3) - np.einsum("ni,nj->nij", c, c)
    IP = IG + mass * cc
    acc_G = mo.a + np.cross(mo.al, c) + np.cross(mo.w, np.cross(mo.w, c))
    f = mass * (acc_G - g) + drag_Ns_per_m * mo.v
    n = (np.einsum("nij,nj->ni", IP, mo.al)
         + np.cross(mo.w, np.einsum("nij,nj->ni", IP, mo.w))
         + mass * np.cross(c, mo.a - g))
    return np.concatenate([f, n], axis=1)
