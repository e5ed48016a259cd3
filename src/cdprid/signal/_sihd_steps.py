"""Semi-implicit homogeneous differentiators (paper eqs. 22-27): per-step functions
of SIHD-2, SIHD-3 and Levant's differentiator."""

from __future__ import annotations

import jax.numpy as jnp

from cdprid.signal import _sihd_high as _sihd_high


def projector(e, q, lam, alpha, mu, h):
    """Implicit projector :math:`\\mathcal{N}_q` of the SIHD (paper eq. 25/34).

    Parameters
    ----------
    e : array_like
        Output error :math:`e_1 = y - z_1` (measurement minus estimate).
    q : int
        Index of the line (1 for position, 2 for velocity, 3 for acceleration).
    lam : array_like
        Gain :math:`\\lambda_q` (> 0).
    alpha : array_like
        Homogeneity exponent.
    mu : array_like
        Scaling :math:`\\mu` (> 0).
    h : array_like
        Sampling period.

    Returns
    -------
    jax.Array
        ``sign(e) |e|^{q(1-alpha)} / (lam (mu h)^q)`` where
        ``|e|^{q(1-alpha)} < lam (mu h)^q``, else ``sign(e)``: the solution of
        the implicit (multivalued) sign, always in ``[-1, 1]``.
    """
    p = q * (1.0 - alpha)
    lq = lam * (mu * h) ** q
    aep = jnp.abs(e) ** p
    s = jnp.sign(e)
    return jnp.where(aep < lq, s * aep / lq, s)


def _corrections(e, n, lams, alpha, mu, h):
    """The ``n`` projected corrections of one SIHD step with one log and one exp.

    The corrections ``lam_q mu^q |e|^(q alpha-(q-1)) N_q(e)`` of :func:`projector`,
    ``q = 1..n``, in the equivalent form (docs/sihd.md, eq. P3,
    "smaller magnitude wins")::

        c_q = sign(e) min(lam_q mu^q |e|^(q alpha - (q-1)), |e| / h^q)

    with ``|e|^(q alpha-(q-1)) = |e|^alpha (|e|^(alpha-1))^(q-1)``: one ``log``
    and one ``exp`` per step instead of one ``exp`` per line (the SIHD's cost
    is dominated by these transcendental functions).  ``e = 0`` gives 0, and the
    guarded logarithm keeps gradients finite there.
    """
    a = jnp.abs(e)
    a_s = jnp.where(a > 0, a, jnp.ones_like(a))
    p = jnp.exp(alpha * jnp.log(a_s))  # |e|^alpha
    r = p / a_s  # |e|^(alpha - 1)
    s = jnp.sign(e)
    out = []
    hq = h
    for q in range(1, n + 1):
        out.append(s * jnp.minimum(lams[q - 1] * mu**q * p, a / hq))
        p = p * r
        hq = hq * h
    return out


def sihd2_step(state, y, gains, h):
    """One step of the semi-implicit homogeneous differentiator SIHD-2.

    Implements (docs/sihd.md, eq. D2)::

        e   = y - z1
        z2+ = z2 + h lambda2 mu^2 |e|^(2 alpha - 1) N_2(e)
        z1+ = z1 + h (z2+ + lambda1 mu |e|^alpha N_1(e))

    Parameters
    ----------
    state : tuple of jax.Array
        ``(z1, z2)``: prior estimates of the signal and of its derivative.
    y : jax.Array
        Current sample.
    gains : tuple of jax.Array
        ``(lambda1, lambda2, alpha, mu)``.
    h : jax.Array
        Sampling period.

    Returns
    -------
    new_state : tuple of jax.Array
        ``(z1+, z2+)``; ``z1+`` is the prediction of the next sample.
    d1 : jax.Array
        Derivative estimate at the current sample (``z2+``).
    """
    z1, z2 = state
    lam1, lam2, alpha, mu = gains
    c1, c2 = _corrections(y - z1, 2, (lam1, lam2), alpha, mu, h)
    z2n = z2 + h * c2
    z1n = z1 + h * (z2n + c1)
    return (z1n, z2n), z2n


def sihd3_step(state, y, gains, h):
    """One step of the semi-implicit homogeneous differentiator SIHD-3.

    Implements (docs/sihd.md, eq. D3; projectors always active, E_q = 1)::

        e   = y - z1
        z3+ = z3 + h lambda3 mu^3 |e|^(3 alpha - 2) N_3(e)
        z2+ = z2 + h (z3+ + lambda2 mu^2 |e|^(2 alpha - 1) N_2(e))
        z1+ = z1 + h (z2+ - h z3+ / 2 + lambda1 mu |e|^alpha N_1(e))

    Parameters
    ----------
    state : tuple of jax.Array
        ``(z1, z2, z3)``: prior estimates of the signal and its two derivatives.
    y : jax.Array
        Current sample.
    gains : tuple of jax.Array
        ``(lambda1, lambda2, lambda3, alpha, mu)``.
    h : jax.Array
        Sampling period.

    Returns
    -------
    new_state : tuple of jax.Array
        ``(z1+, z2+, z3+)``, estimates at the next sample time.
    out : tuple of jax.Array
        ``(z2+ - h z3+, z3+)``: first and second derivative at the current
        sample time (the velocity is shifted back by one step).
    """
    z1, z2, z3 = state
    lam1, lam2, lam3, alpha, mu = gains
    c1, c2, c3 = _corrections(y - z1, 3, (lam1, lam2, lam3), alpha, mu, h)
    z3n = z3 + h * c3
    z2n = z2 + h * (z3n + c2)
    z1n = z1 + h * (z2n - 0.5 * h * z3n + c1)
    return (z1n, z2n, z3n), (z2n - h * z3n, z3n)


def _spow(x, p):
    """Signed power ``|x|^p sign(x)``."""
    return jnp.sign(x) * jnp.abs(x) ** p


def levant_step(state, f, gains, h):
    """One explicit-Euler step of Levant's recursive 2nd-order differentiator.

    Implements (Levant 2003, recursive form, n = 2)::

        v0  = -lambda2 L^(1/3) |z0 - f|^(2/3) sign(z0 - f) + z1
        v1  = -lambda1 L^(1/2) |z1 - v0|^(1/2) sign(z1 - v0) + z2
        z0+ = z0 + h v0,  z1+ = z1 + h v1,
        z2+ = z2 - h lambda0 L sign(z2 - v1)

    Parameters
    ----------
    state : tuple of jax.Array
        ``(z0, z1, z2)`` estimates of the signal and its two derivatives at
        the current sample time (computed from the past samples).
    f : jax.Array
        Current sample.
    gains : tuple of jax.Array
        ``(L, lambda0, lambda1, lambda2)``.
    h : jax.Array
        Sampling period.

    Returns
    -------
    new_state : tuple of jax.Array
        ``(z0+, z1+, z2+)``.
    out : tuple of jax.Array
        ``(z1, z2)``: derivative estimates at the current sample time.
    """
    z0, z1, z2 = state
    L, l0, l1, l2 = gains
    v0 = -l2 * L ** (1.0 / 3.0) * _spow(z0 - f, 2.0 / 3.0) + z1
    v1 = -l1 * L**0.5 * _spow(z1 - v0, 0.5) + z2
    z2n = z2 - h * l0 * L * jnp.sign(z2 - v1)
    return (z0 + h * v0, z1 + h * v1, z2n), (z1, z2)
