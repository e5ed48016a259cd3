"""SIHD parametrisation of the tuning: stable gains from unconstrained parameters
(Hurwitz polynomials by their roots), defaults and the loss of a parameter vector."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.signal import METHOD_INFO as HIGH_INFO
from cdprid.signal import METHODS, sihdn_channel

SIHD_METHODS = ("sihd2-cascade", "sihd3", "sihd4", "sihd5")


PAPER_PARAMS = dict(METHODS["sihd2-cascade"].params)


def _order(method: str) -> int:
    return 2 if method == "sihd2-cascade" else int(method[4:])


def _alpha_min(method: str) -> float:
    return 0.5 if method == "sihd2-cascade" else (_order(method) - 1) / _order(method)


def _sigmoid(x):
    return 1.0 / (1.0 + jnp.exp(-x))


def _logit(p):
    return math.log(p / (1 - p))


#: Default floor of the damping ratio of every complex root pair of SIHD-N (N >= 3).  With
#: 0 (default) the optimiser is free to place lightly damped pairs that resonate near the
#: training signal's frequency (zeta ~ 0.1-0.25 on the benchmark circle): lowest error on
#: that spectrum, worse on others (results/tuning.md); 0.5 trades some of one for the other.
ZETA_MIN = 0.0


def _poly_from_theta(th, n, zeta_min=None):
    """Monic Hurwitz polynomial coefficients [lambda1..lambdaN] from root parameters
    (pairs: ``omega = exp(th_i)``, ``zeta = zeta_min + exp(th_i+1)``)."""
    zmin = ZETA_MIN if zeta_min is None else zeta_min
    coef = jnp.ones((1,), th.dtype)
    i = 0
    if n % 2 == 1:
        coef = jnp.convolve(coef, jnp.stack([jnp.ones((), th.dtype), jnp.exp(th[0])]))
        i = 1
    while i < n:
        om, ze = jnp.exp(th[i]), zmin + jnp.exp(th[i + 1])
        coef = jnp.convolve(coef, jnp.stack([jnp.ones((), th.dtype), 2 * ze * om, om**2]))
        i += 2
    return coef[1:]


def _theta_to_gains(method, th, zeta_min=None, fixed_alpha=None):
    """(lambdas tuple, alpha) from theta (JAX-traceable); with ``fixed_alpha`` theta has no
    alpha entry."""
    n = _order(method)
    if fixed_alpha is None:
        amin = _alpha_min(method)
        alpha = amin + (1.0 - amin) * _sigmoid(th[-1])
        g = th[:-1]
    else:
        alpha, g = jnp.asarray(fixed_alpha, th.dtype), th
    if method == "sihd2-cascade":
        return tuple(jnp.exp(g[q]) for q in range(4)), alpha
    lam = _poly_from_theta(g, n, zeta_min)
    return tuple(lam[q] for q in range(n)), alpha


def params_from_theta(method, th, zeta_min=None, fixed_alpha=None) -> dict:
    """Method parameters (names of ``METHODS``/``METHOD_INFO``) from theta.

    Parameters
    ----------
    method : str
        One of :data:`SIHD_METHODS`.
    th : array
        Unconstrained coordinates (log root parameters, then a logit of alpha).
    zeta_min : float, optional
        Damping floor of the root pairs (default :data:`ZETA_MIN`).
    fixed_alpha : float, optional
        When given, theta has no alpha entry (alpha is this value).

    Returns
    -------
    dict
        The gains ``lambda1..lambdaN``, ``alpha`` (at most 1) and ``mu`` (1).
    """
    lams, alpha = _theta_to_gains(method, jnp.asarray(th, jnp.float64), zeta_min, fixed_alpha)
    p = {f"lambda{q + 1}": float(v) for q, v in enumerate(lams)}
    p["alpha"] = float(min(alpha, 1.0))
    p["mu"] = 1.0
    return p


def _roots_theta(lams, zeta_min=None):
    """Root parameters (log omega, log zeta) of a Hurwitz polynomial, for initialisation."""
    n = len(lams)
    r = np.roots(np.r_[1.0, np.asarray(lams, float)])
    if np.any(r.real >= 0):
        raise InputError("initial gains give an unstable linear part.")
    real = sorted([x.real for x in r if abs(x.imag) < 1e-9 * max(1, abs(x))])
    cplx = sorted([x for x in r if x.imag > 1e-9 * max(1, abs(x))], key=lambda z: abs(z))
    th = []
    if n % 2 == 1:
        th.append(math.log(-real.pop(len(real) // 2)))
    pairs = [(abs(z), -z.real / abs(z)) for z in cplx]
    while len(real) >= 2:  # two real roots a, b -> omega = sqrt(ab), zeta = (a+b)/(2 omega)
        a, b = -real.pop(0), -real.pop(-1)
        om = math.sqrt(a * b)
        pairs.append((om, (a + b) / (2 * om)))
    zmin = ZETA_MIN if zeta_min is None else zeta_min
    for om, ze in pairs:
        th += [math.log(om), math.log(max(ze - zmin, 1e-3))]
    return th


def theta_from_params(method, params, zeta_min=None, fixed_alpha=None) -> np.ndarray:
    """Inverse of :func:`params_from_theta` (alpha clipped into the open interval).

    Parameters
    ----------
    method : str
        One of :data:`SIHD_METHODS`.
    params : dict
        ``lambda1..lambdaN``, ``alpha`` and optionally ``mu`` (folded into the gains).
    zeta_min : float, optional
        Damping floor of the root pairs (default :data:`ZETA_MIN`).
    fixed_alpha : float, optional
        When given, theta has no alpha entry (alpha is this value).

    Returns
    -------
    ndarray
        theta.

    Raises
    ------
    InputError
        Gains whose linear part is unstable.
    """
    n = _order(method)
    amin = _alpha_min(method)
    mu = float(params.get("mu", 1.0))
    if method == "sihd2-cascade":
        lams = [params["lambda1"] * mu, params["lambda2"] * mu**2,
                params["lambda3"] * mu, params["lambda4"] * mu**2]
        th = [math.log(float(v)) for v in lams]
    else:
        th = _roots_theta([float(params[f"lambda{q}"]) * mu**q for q in range(1, n + 1)],
                           zeta_min)
    if fixed_alpha is not None:
        return np.asarray(th, float)
    a = min(max(float(params["alpha"]), amin + 1e-4 * (1 - amin)), 1 - 1e-4 * (1 - amin))
    th.append(_logit((a - amin) / (1 - amin)))
    return np.asarray(th, float)


def default_params(method) -> dict:
    """Starting parameters of a method (METHODS defaults, paper gains for the cascade).

    Parameters
    ----------
    method : str

    Returns
    -------
    dict
        A copy.
    """
    if method in METHODS:
        return dict(METHODS[method].params)
    return dict(HIGH_INFO[method]["params"])


def _acc_channel(method, y, h, lams, alpha):
    """Acceleration of one channel with the SIHD equations (NaN-free gradients)."""
    one = jnp.ones((), y.dtype)
    if method == "sihd2-cascade":
        v, _ = sihdn_channel(y, h, lams[:2], alpha, one)
        a, _ = sihdn_channel(v, h, lams[2:], alpha, one)
        return a
    return sihdn_channel(y, h, lams, alpha, one)[1]


def sihd_loss_fn(method, zeta_min=None):
    """``f(theta, (Y, acc, mask, h)) -> mean squared 3-D acceleration error``.

    ``Y`` is (n, 3 S) (S noise realisations of the 3 axes), ``acc`` (n, 3 S)
    the true accelerations, ``mask`` (n,) 0/1 weights, ``h`` the sampling period (s). All
    channels run in one ``vmap`` of the ``lax.scan``.

    Parameters
    ----------
    method : str
        One of :data:`SIHD_METHODS`.
    zeta_min : float, optional
        Damping floor of the root pairs (default :data:`ZETA_MIN`).

    Returns
    -------
    callable
        The loss, in (m/s^2)^2, JAX-traceable in theta.
    """

    def f(th, args):
        Y, acc, mask, h = args
        lams, alpha = _theta_to_gains(method, th, zeta_min)
        A = jax.vmap(lambda c: _acc_channel(method, c, h, lams, alpha), in_axes=1, out_axes=1)(Y)
        se = jnp.sum(((A - acc) ** 2) * mask[:, None])
        return se / (jnp.sum(mask) * (Y.shape[1] // 3))

    return f
