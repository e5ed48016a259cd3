"""Smooth ramps (7th-order smoothstep) and their exact derivatives, shared by trajectories
and rotations."""

from __future__ import annotations

import jax
import jax.numpy as jnp


def smoothstep7(x):
    """Septic smoothstep ``35 x^4 - 84 x^5 + 70 x^6 - 20 x^7`` of ``clip(x, 0, 1)``.

    Its first three derivatives vanish at 0 and 1.

    Parameters
    ----------
    x : array
        Any shape; dimensionless.

    Returns
    -------
    array
        Same shape, in [0, 1].
    """
    x = jnp.clip(x, 0.0, 1.0)
    return x**4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)))


def _binom(n: int, k: int) -> int:
    from math import comb

    return comb(n, k)


def smoothstep7_derivs(x, scale, sign, order: int):
    """[g, g', ..., g^(order)] of ``g(u) = S(x)`` with ``dx/du = sign / scale``.

    S is :func:`smoothstep7`; outside [0, 1] the derivatives are 0 (S is constant there).

    Parameters
    ----------
    x : array
        The argument of S (any shape).
    scale : float
        Length of the ramp in u (e.g. s).
    sign : float
        +1 for a ramp up in u, -1 for a ramp down.
    order : int
        Highest derivative, at most 3.

    Returns
    -------
    list of array
        ``order + 1`` arrays of the shape of ``x``; the k-th in units of u^-k.
    """
    inside = (x > 0.0) & (x < 1.0)
    x = jnp.clip(x, 0.0, 1.0)
    # S and its derivatives as polynomials in x (exact)
    polys = [
        x**4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x))),
        x**3 * (140.0 + x * (-420.0 + x * (420.0 - 140.0 * x))),
        x**2 * (420.0 + x * (-1680.0 + x * (2100.0 - 840.0 * x))),
        x * (840.0 + x * (-5040.0 + x * (8400.0 - 4200.0 * x))),
    ]
    out = [polys[0]]
    for k in range(1, order + 1):
        out.append(jnp.where(inside, polys[k], 0.0) * (sign / scale) ** k)
    return out


def _derivs(f, t, order):
    """[f(t), f'(t), ..., f^(order)(t)] by nested forward-mode differentiation (scalar t)."""
    out = [f]
    for _ in range(order):
        out.append(jax.jacfwd(out[-1]))
    return [g(t) for g in out]
