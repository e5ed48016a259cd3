"""Cable interference: least distances between cables, and between a cable and the platform body.

A cable is the straight segment from its leave point ``T_i`` (the exit point ``A_i``, or the
tangent point on a swivel pulley; base frame) to its attachment ``B_i = p + R b_i``.

- **cable-cable**: the least distance between the segments of cables i and j (closest points of
  two segments, Ericson, *Real-Time Collision Detection*, 5.1.9). Pairs that share an end point
  (the same attachment or the same leave point, within 1 um) touch there by construction and
  are not checked (:func:`cable_pairs` lists the pairs that are).
- **cable-body**: the platform body is the box ``[body_min, body_max]`` of robot.toml
  ``[platform]`` (platform frame). "Other than at its own anchor": in the platform frame the
  cable is the segment ``b_i + s d_i``, ``0 <= s <= L_i``. If the anchor is strictly inside the
  box (as in the spec's example) the cable leaves the convex box once and never comes back:
  nothing is checked for it (``inf``). If the anchor is on the box surface, the faces that
  contain the anchor are excluded; if it is outside, no face is. The cable-body clearance is
  the least distance between the cable and the remaining faces of the box (rectangles): a
  cable that cuts through the body from a surface anchor, or passes by the body from an
  outside anchor, has a small clearance; a cable leaving its face outwards does not.

Exact values (numpy: closed form for segments; golden-section on the convex distance for the
faces) are the certificate; :func:`smooth_clearances` is the differentiable version used by the
optimiser (sampled points along the cable for the body, clipped closed form for the pairs).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from cdprid.base import InputError
from cdprid.model._cables import leave_points
from cdprid.model._geometry import CableRobot

__all__ = [
    "cable_pairs",
    "cable_segments",
    "segment_distances",
    "cable_cable_distances",
    "cable_body_distances",
    "smooth_clearances",
]

_SHARED_TOL = 1e-6


def cable_pairs(robot: CableRobot) -> np.ndarray:
    """Index pairs of cables whose interference is checked (no shared end point).

    Parameters
    ----------
    robot : CableRobot

    Returns
    -------
    numpy.ndarray (k, 2) of int
        Pairs ``(i, j)``, ``i < j``.
    """
    A = np.asarray(robot.B_A)
    b = np.asarray(robot.P_b)
    out = []
    for i in range(robot.n_cables):
        for j in range(i + 1, robot.n_cables):
            apart = np.linalg.norm(A[i] - A[j]) > _SHARED_TOL
            if apart and np.linalg.norm(b[i] - b[j]) > _SHARED_TOL:
                out.append((i, j))
    return np.asarray(out, int).reshape(-1, 2)


def cable_segments(robot: CableRobot, B_p: Float[Array, "n 3"],  # noqa: F722
                   B_R_P: Float[Array, "n 3 3"],  # noqa: F722
                   pulleys: bool | None = None) -> tuple[Array, Array]:
    """Leave points ``T`` and attachments ``B`` along a path, base frame.

    Parameters
    ----------
    robot : CableRobot
    B_p : array (n, 3)
        Positions of P, base frame, m.
    B_R_P : array (n, 3, 3)
        Rotations platform -> base.
    pulleys : bool, optional
        Static: whether any cable has a swivel pulley; None reads it from the robot (which
        must then be concrete, not traced).

    Returns
    -------
    T, B : array (n, m, 3)
        Leave points and attachment points, m.
    """
    if robot.has_pulleys if pulleys is None else pulleys:
        T = jax.vmap(lambda p, R: leave_points(robot, p, R))(B_p, B_R_P)
    else:  # the leave points are the exit points
        T = jnp.broadcast_to(robot.B_A, (B_p.shape[0],) + robot.B_A.shape)
    B = B_p[:, None, :] + jnp.einsum("nij,mj->nmi", B_R_P, robot.P_b)
    return T, B


def segment_distances(P0, P1, Q0, Q1, xp=np):
    """Least distance between segments ``[P0, P1]`` and ``[Q0, Q1]`` (broadcast over leading axes).

    Closed form of the closest points (clamped parameters).

    Parameters
    ----------
    P0, P1, Q0, Q1 : array (..., 3)
        End points, m.
    xp : module
        numpy (exact certificate) or jax.numpy (differentiable almost everywhere, used by the
        optimiser; adds 1e-12 m^2 under the square root).

    Returns
    -------
    array (...)
        Distances, m.
    """
    d1, d2, r = P1 - P0, Q1 - Q0, P0 - Q0
    a = xp.sum(d1 * d1, -1)
    e = xp.sum(d2 * d2, -1)
    b = xp.sum(d1 * d2, -1)
    c = xp.sum(d1 * r, -1)
    f = xp.sum(d2 * r, -1)
    den = a * e - b * b
    eps = 1e-300 if xp is np else 1e-30
    # parallel segments (den ~ 0): any s works, take s = 0
    s_free = xp.clip((b * f - c * e) / xp.maximum(den, eps), 0.0, 1.0)
    s = xp.where(den > 1e-12 * a * e, s_free, 0.0)
    t = (b * s + f) / e
    # clamp t and recompute s for the clamped t
    s = xp.where(t < 0.0, xp.clip(-c / a, 0.0, 1.0),
                 xp.where(t > 1.0, xp.clip((b - c) / a, 0.0, 1.0), s))
    t = xp.clip(t, 0.0, 1.0)
    diff = P0 + s[..., None] * d1 - (Q0 + t[..., None] * d2)
    return xp.sqrt(xp.sum(diff * diff, -1) + (0.0 if xp is np else 1e-12))


def cable_cable_distances(robot: CableRobot, B_p, B_R_P) -> np.ndarray:
    """Exact least distance of every checked pair (:func:`cable_pairs`) per sample.

    Parameters
    ----------
    robot : CableRobot
    B_p : array (n, 3)
        Positions of P, base frame, m.
    B_R_P : array (n, 3, 3)
        Rotations platform -> base.

    Returns
    -------
    numpy.ndarray (n, k)
        Distances, m (k = 0 columns when no pair is checked).
    """
    pairs = cable_pairs(robot)
    T, B = (np.asarray(x) for x in cable_segments(robot, jnp.asarray(B_p), jnp.asarray(B_R_P)))
    if len(pairs) == 0:
        return np.zeros((T.shape[0], 0))
    i, j = pairs[:, 0], pairs[:, 1]
    return segment_distances(B[:, i], T[:, i], B[:, j], T[:, j])


def _faces(lo, hi):
    """The 6 faces of a box as (axis, value) and their rectangle bounds (6, 3) x 2."""
    flo, fhi = [], []
    for ax in range(3):
        for val in (lo[ax], hi[ax]):
            a, b = lo.copy(), hi.copy()
            a[ax] = b[ax] = val
            flo.append(a)
            fhi.append(b)
    return np.array(flo), np.array(fhi)


def _cable_frame(robot, B_p, B_R_P, pulleys=None):
    """Per sample and cable (platform frame): unit direction d (n, m, 3) and length L (n, m)."""
    T, _ = cable_segments(robot, B_p, B_R_P, pulleys)
    P_T = jnp.einsum("nji,nmj->nmi", B_R_P, T - B_p[:, None, :])  # leave points, platform frame
    v = P_T - robot.P_b[None]
    L = jnp.linalg.norm(v, axis=-1)
    return v / L[..., None], L


def _exit_and_mask(b, d, L, lo, hi, xp):
    """Exit parameter s_out (n, m) and the mask (n, m, 6) of faces that count."""
    inside = xp.all((b > lo + _SHARED_TOL) & (b < hi - _SHARED_TOL), axis=-1)  # (m,)
    big = 1e300 if xp is np else 1e30
    dd = xp.where(xp.abs(d) < 1e-15, 1e-15, d)
    t_hi = (hi - b) / dd
    t_lo = (lo - b) / dd
    t_exit_axis = xp.where(d > 0, t_hi, xp.where(d < 0, t_lo, big))  # (n, m, 3)
    s_out = xp.where(inside, xp.minimum(xp.min(t_exit_axis, -1), L), 0.0)
    ax_exit = xp.argmin(t_exit_axis, -1)  # (n, m)
    side = xp.take_along_axis(d, ax_exit[..., None], -1)[..., 0] > 0
    exit_face = 2 * ax_exit + side.astype(int)
    on = xp.stack([xp.abs(b[..., k] - v) <= _SHARED_TOL for k in range(3) for v in (lo[k], hi[k])],
                  axis=-1)  # (1, m, 6) faces holding the anchor
    # an anchor inside the body: the cable leaves the convex box once and never comes back,
    # nothing to check; on the surface: the faces through the anchor are excluded
    mask = xp.where(inside[..., None], False, ~on) & (exit_face[..., None] >= 0)
    return s_out, mask


def _point_face_dist(q, flo, fhi, xp):
    """Distance (..., 6) from points q (..., 3) to the 6 face rectangles."""
    qq = q[..., None, :]
    c = xp.clip(qq, flo, fhi)
    diff = qq - c
    return xp.sqrt(xp.sum(diff * diff, -1) + (0.0 if xp is np else 1e-12))


def cable_body_distances(robot: CableRobot, B_p, B_R_P, n_iter: int = 80) -> np.ndarray:
    """Exact cable-body clearance (module docstring).

    Parameters
    ----------
    robot : CableRobot
    B_p : array (n, 3)
        Positions of P, base frame, m.
    B_R_P : array (n, 3, 3)
        Rotations platform -> base.
    n_iter : int
        Golden-section iterations per cable and box face.

    Returns
    -------
    numpy.ndarray (n, m)
        Clearance per sample and cable, m; ``inf`` where nothing is checked.

    Raises
    ------
    InputError
        The robot has no ``[platform]`` body box.
    """
    pl = robot.platform
    if pl.body_min is None:
        raise InputError("the robot has no [platform] body_min/body_max box.")
    lo, hi = np.asarray(pl.body_min), np.asarray(pl.body_max)
    d, L = (np.asarray(x) for x in _cable_frame(robot, jnp.asarray(B_p), jnp.asarray(B_R_P)))
    b = np.asarray(robot.P_b)[None]
    s_out, mask = _exit_and_mask(b, d, L, lo, hi, np)
    flo, fhi = _faces(lo, hi)
    # distance to a convex set along a segment is convex in s: golden-section per face
    g = (np.sqrt(5.0) - 1.0) / 2.0
    a = np.broadcast_to(s_out[..., None], mask.shape).copy()
    c = np.broadcast_to(L[..., None], mask.shape).copy()

    def dist(s):
        q = b[..., None, :] + s[..., None] * d[..., None, :]  # (n, m, 6, 3)
        diff = q - np.clip(q, flo, fhi)
        return np.sqrt(np.sum(diff * diff, -1))

    for _ in range(n_iter):
        x1, x2 = c - g * (c - a), a + g * (c - a)
        left = dist(x1) < dist(x2)
        c = np.where(left, x2, c)
        a = np.where(left, a, x1)
    best = np.minimum(dist(0.5 * (a + c)), np.minimum(dist(s_out[..., None] + 0 * a),
                                                      dist(L[..., None] + 0 * a)))
    best = np.where(mask, best, np.inf)
    return best.min(-1)


def _softmin(x, temperature, axis=-1):
    return -temperature * jax.nn.logsumexp(-x / temperature, axis=axis)


def smooth_clearances(robot: CableRobot, B_p, B_R_P, pairs: np.ndarray,
                      n_points: int = 12, temperature: float = 2e-3,
                      pulleys: bool | None = None):
    """Differentiable clearances per sample.

    Soft minima that never exceed the exact minimum by more than a few temperatures; body
    distances from ``n_points`` points per cable. A term that does not apply (no pair, no
    body box) is a large constant (10 m).

    Parameters
    ----------
    robot : CableRobot
    B_p : array (n, 3)
        Positions of P, base frame, m.
    B_R_P : array (n, 3, 3)
        Rotations platform -> base.
    pairs : numpy.ndarray (k, 2)
        Cable pairs to check (:func:`cable_pairs`).
    n_points : int
        Points per cable for the body distance.
    temperature : float
        Soft-minimum temperature, m.
    pulleys : bool, optional
        As :func:`cable_segments`.

    Returns
    -------
    cable_cable, cable_body : array (n,)
        Soft-minimum clearances, m.
    """
    n = B_p.shape[0]
    cc = jnp.full((n,), 10.0)
    if len(pairs):
        T, B = cable_segments(robot, B_p, B_R_P, pulleys)
        i, j = jnp.asarray(pairs[:, 0]), jnp.asarray(pairs[:, 1])
        dist = segment_distances(B[:, i], T[:, i], B[:, j], T[:, j], xp=jnp)
        cc = _softmin(dist, temperature)
    cb = jnp.full((n,), 10.0)
    pl = robot.platform
    if pl.body_min is not None:
        lo, hi = np.asarray(pl.body_min), np.asarray(pl.body_max)
        d, L = _cable_frame(robot, B_p, B_R_P, pulleys)
        b = robot.P_b[None]
        s_out, mask = _exit_and_mask(b, d, L, jnp.asarray(lo), jnp.asarray(hi), jnp)
        flo, fhi = (jnp.asarray(x) for x in _faces(lo, hi))
        u = jnp.linspace(0.0, 1.0, n_points)
        s = s_out[..., None] + (L - s_out)[..., None] * u  # (n, m, K)
        q = b[:, :, None, :] + s[..., None] * d[:, :, None, :]
        dist = _point_face_dist(q, flo, fhi, jnp)  # (n, m, K, 6)
        dist = jnp.where(mask[:, :, None, :], dist, 10.0)
        cb = _softmin(dist.reshape(n, -1), temperature)
    return cc, cb
