"""Swivel-pulley geometry, written from the spec's words (not from cdprid.model).

A cable reaches its exit point A running along the swivel axis k (from the winch side); the
pulley of radius r swivels about k so that its plane holds the attachment B; the pulley's
centre is C = A + r e (e the unit vector of the plane normal to k, towards B); the cable wraps
over the rim from A and leaves at the tangent point T towards B. In the plane, with (e, k)
coordinates about C, the rim point at angle beta from A is ``r (-cos beta, sin beta)`` and the
cable's direction there ``(sin beta, cos beta)``; the leave point is where that direction
points at B: ``B - C = r n + s t`` with n the radial and t the tangent unit vectors and
``s = sqrt(|B - C|^2 - r^2)`` the free length.
"""

from __future__ import annotations

import numpy as np


def pulley_geometry(A, k, r, B, ref=(1.0, 0.0, 0.0)):
    """Leave points, wrap angles, free lengths and unit vectors of cables over swivel pulleys.

    Parameters
    ----------
    A : (m, 3) exit points (pulley entries on the swivel axes), base frame, m
    k : (m, 3) unit swivel axes, the way the cable runs into the pulley
    r : (m,) pulley radii, m (0: the cable leaves from A)
    B : (..., m, 3) attachment points, base frame, m
    ref : (3,) in-plane direction used when B lies on the axis

    Returns
    -------
    T : (..., m, 3) leave points, m
    beta : (..., m) wrap angles, rad, in [0, 2 pi)
    free : (..., m) straight lengths |B - T|, m
    u : (..., m, 3) unit vectors from B towards T
    """
    A, k, r, B = (np.asarray(z, float) for z in (A, k, r, B))
    v = B - A
    e = v - np.sum(v * k, -1, keepdims=True) * k
    ne = np.linalg.norm(e, axis=-1, keepdims=True)
    ref = np.asarray(ref, float)
    ref_e = ref - np.sum(ref * k, -1, keepdims=True) * k
    ref_e = ref_e / np.linalg.norm(ref_e, axis=-1, keepdims=True)
    e = np.where(ne > 1e-12, e / np.maximum(ne, 1e-300), ref_e)
    C = A + r[..., None] * e
    w = B - C
    bx = np.sum(w * e, -1)
    bk = np.sum(w * k, -1)
    d2 = bx * bx + bk * bk
    s = np.sqrt(np.maximum(d2 - r * r, 0.0))
    ne_ = (r * bx - s * bk) / d2  # radial unit vector n in (e, k) coordinates
    nk_ = (s * bx + r * bk) / d2
    beta = np.mod(np.arctan2(nk_, -ne_), 2 * np.pi)
    T = C + r[..., None] * (ne_[..., None] * e + nk_[..., None] * k)
    L = T - B
    free = np.linalg.norm(L, axis=-1)
    return T, beta, free, L / free[..., None]


def total_length(A, k, r, B):
    """Cable length from the pulley entry A to B: the arc on the rim plus the free part, m."""
    _, beta, free, _ = pulley_geometry(A, k, r, B)
    return np.asarray(r) * beta + free
