"""Kalman filter and Rauch-Tung-Striebel smoother of the constant-jerk model."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from cdprid.signal import _sihd_high as _sihd_high


def _cj_model(h, q):
    """Transition F and process covariance Q of the 4-state integrator chain."""
    n = 4
    F = jnp.eye(n)
    for i in range(n):
        for j in range(i + 1, n):
            F = F.at[i, j].set(h ** (j - i) / math.factorial(j - i))
    Q = jnp.zeros((n, n))
    for i in range(n):
        for j in range(n):
            a, b = n - 1 - i, n - 1 - j
            den = math.factorial(a) * math.factorial(b) * (a + b + 1)
            Q = Q.at[i, j].set(q * h ** (a + b + 1) / den)
    return F, Q


def _kalman_forward(y, h, q, r):
    """Filter one channel; returns filtered and predicted means/covariances."""
    F, Q = _cj_model(h, q)
    x0 = jnp.zeros(4).at[0].set(y[0])
    # diffuse-ish prior on the derivatives (units of m/s, m/s^2, m/s^3)
    P0 = jnp.diag(jnp.array([1.0, 1e2, 1e4, 1e6])) * jnp.array([r, 1.0, 1.0, 1.0])

    def step(carry, yk):
        xp, Pp = carry  # prior at this sample
        S = Pp[0, 0] + r
        K = Pp[:, 0] / S
        xf = xp + K * (yk - xp[0])
        Pf = Pp - jnp.outer(K, Pp[0, :])
        Pf = 0.5 * (Pf + Pf.T)
        xn = F @ xf
        Pn = F @ Pf @ F.T + Q
        return (xn, Pn), (xf, Pf, xp, Pp)

    _, out = jax.lax.scan(step, (x0, P0), y)
    return F, out


def _kalman_channel(y, h, q, r):
    _, (xf, _, _, _) = _kalman_forward(y, h, q, r)
    return xf[:, 1], xf[:, 2]


def _rts_channel(y, h, q, r):
    F, (xf, Pf, xp, Pp) = _kalman_forward(y, h, q, r)

    def back(carry, inp):
        xs_next, Ps_next = carry
        xf_k, Pf_k, xp_next, Pp_next = inp
        G = jnp.linalg.solve(Pp_next, F @ Pf_k).T  # Pf F^T Pp^{-1}
        xs = xf_k + G @ (xs_next - xp_next)
        Ps = Pf_k + G @ (Ps_next - Pp_next) @ G.T
        return (xs, 0.5 * (Ps + Ps.T)), xs

    inputs = (xf[:-1], Pf[:-1], xp[1:], Pp[1:])
    _, xs = jax.lax.scan(back, (xf[-1], Pf[-1]), inputs, reverse=True)
    xs = jnp.concatenate([xs, xf[-1:]], axis=0)
    return xs[:, 1], xs[:, 2]
