"""Higher-order semi-implicit homogeneous differentiators (SIHD-n, n = 2..6).

``sihdn_step`` generalises :func:`cdprid.signal.sihd2_step` and
:func:`cdprid.signal.sihd3_step` to ``n`` states (position and its
first ``n - 1`` derivatives).  One step, with the prior states ``z`` at
sample ``k`` and the error ``e = y_k - z_1``, is::

    c_q = sign(e) min(lambda_q mu^q |e|^(q alpha - (q - 1)),  |e| / h^q)   q = 1..n
    w_q = z_q + h c_q                              (posterior at t_k: outputs)
    z_i+ = sum_{j >= i} h^(j-i) / (j-i)! w_j       (exact Taylor prediction)

``c_q`` is the homogeneous correction of line ``q`` with the implicit
projector N_q (docs/sihd.md, eqs. P1-P3: the explicit homogeneous term,
unless it would overshoot, in which case the dead-beat term).  For n = 2
this is exactly SIHD-2 (D2) and for n = 3 exactly SIHD-3 (D3, the Taylor
term ``-h/2 z3+`` is the second row of the Pascal matrix), so the scheme is
the same semi-implicit discretisation: implicit Euler down the integrator
chain, corrections frozen in magnitude and implicit in sign.  Polynomials of
degree ``n - 1`` are fixed points with ``e = 0``.

With ``n = 5`` (states p, v, a, j, snap) the acceleration is estimated by an
internal model that is exact on quartics, so a sinusoid at 0.25 Hz is
followed with far less lag than by SIHD-3 at the same noise gain (see
``results/tuning.md``).  The exponents ``q alpha - (q - 1)`` must be
non-negative: ``alpha`` in ``[(n - 1) / n, 1]``.

Registered names (to be added to :data:`cdprid.signal.METHODS`):
see :data:`METHOD_INFO` and :func:`channel`.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError

__all__ = [
    "sihdn_step",
    "sihdn_channel",
    "channel",
    "poly_gains",
    "differentiate_high",
    "METHOD_INFO",
    "alpha_min",
]


def alpha_min(n: int) -> float:
    """Smallest admissible homogeneity exponent of an n-state SIHD: ``(n - 1) / n``.

    Below it the correction exponent ``n alpha - (n - 1)`` of the last line is negative.

    Parameters
    ----------
    n : int
        Number of states (position and its first ``n - 1`` derivatives), 2..6.

    Returns
    -------
    float
        ``(n - 1) / n`` (dimensionless).
    """
    return (n - 1) / n


def poly_gains(omega: float, n: int) -> list[float]:
    """Gains placing the linear part's n-fold pole at ``-omega``: ``binom(n, q) omega^q``.

    Parameters
    ----------
    omega : float
        Bandwidth of the linear part, rad/s (> 0).
    n : int
        Number of states.

    Returns
    -------
    list of float
        ``lambda_1..lambda_n``; ``lambda_q`` in s^-q.
    """
    return [math.comb(n, q) * omega**q for q in range(1, n + 1)]


def _corr(e, q, lam, alpha, mu, h):
    """Projected homogeneous correction of line q (docs/sihd.md P3), NaN-free gradients."""
    ae = jnp.abs(e)
    pos = ae > 0
    ae_s = jnp.where(pos, ae, 1.0)
    expl = lam * mu**q * jnp.exp((q * alpha - (q - 1)) * jnp.log(ae_s))
    dead = ae_s / h**q
    return jnp.where(pos, jnp.sign(e) * jnp.minimum(expl, dead), jnp.zeros_like(e))


def _pascal(n, h):
    """Taylor prediction matrix F_ij = h^(j-i) / (j-i)! (upper triangular)."""
    return [[h ** (j - i) / math.factorial(j - i) if j >= i else 0.0 for j in range(n)]
            for i in range(n)]


def sihdn_step(state, y, lams, alpha, mu, h):
    """One step of the n-state SIHD.

    Parameters
    ----------
    state : tuple of n jax.Array
        Prior estimates ``(z_1, ..., z_n)`` at the current sample time.
    y : jax.Array
        Current sample.
    lams : sequence of n jax.Array
        Gains ``lambda_1..lambda_n``.
    alpha, mu : jax.Array
        Homogeneity exponent and time scaling.
    h : jax.Array
        Sampling period.

    Returns
    -------
    new_state : tuple
        Priors at the next sample.
    post : tuple
        Posterior estimates ``(w_1, ..., w_n)`` at the current sample (``w_2``
        velocity, ``w_3`` acceleration).
    """
    n = len(state)
    e = y - state[0]
    w = tuple(state[q] + h * _corr(e, q + 1, lams[q], alpha, mu, h) for q in range(n))
    F = _pascal(n, h)
    new = []
    for i in range(n):
        acc = w[i]
        for j in range(i + 1, n):
            acc = acc + F[i][j] * w[j]
        new.append(acc)
    return tuple(new), w


def sihdn_channel(y, h, lams, alpha, mu):
    """Run an n-state SIHD (``n = len(lams)``) over one channel (``lax.scan``).

    The state starts at rest on the first sample (``z_1 = y[0]``, derivatives 0).

    Parameters
    ----------
    y : jax.Array (N,)
        Samples of one channel (any unit U), uniform step ``h``.
    h : jax.Array
        Sampling period, s.
    lams : sequence of n jax.Array
        Gains ``lambda_1..lambda_n`` (``lambda_q`` in s^-q).
    alpha : jax.Array
        Homogeneity exponent, in ``[(n - 1) / n, 1]`` (not checked here: see
        :func:`differentiate_high`).
    mu : jax.Array
        Time scaling of the gains (dimensionless).

    Returns
    -------
    d1 : jax.Array (N,)
        First derivative (posterior ``w_2``), U/s.
    d2 : jax.Array (N,)
        Second derivative (posterior ``w_3``), U/s^2; zeros for ``n = 2``.
    """
    n = len(lams)
    zero = jnp.zeros((), y.dtype)
    init = (y[0],) + (zero,) * (n - 1)

    def step(s, yk):
        s, w = sihdn_step(s, yk, lams, alpha, mu, h)
        return s, (w[1], w[2] if n > 2 else jnp.zeros_like(yk))

    _, (d1, d2) = jax.lax.scan(step, init, y)
    return d1, d2


def channel(n: int):
    """Channel function ``f(y, h, p)`` of the n-state SIHD for the scan's registry
    (``cdprid.signal._CHANNEL_FNS``).

    Parameters
    ----------
    n : int
        Number of states, 2..6.

    Returns
    -------
    callable
        ``f(y, h, p) -> (d1, d2)`` (see :func:`sihdn_channel`), ``p`` the parameter vector in
        the order of ``METHOD_INFO[f"sihd{n}"]``: ``lambda1..lambda_n, alpha, mu``.
    """

    def f(y, h, p):
        return sihdn_channel(y, h, tuple(p[q] for q in range(n)), p[n], p[n + 1])

    return f


#: Default parameters (tuned with ``cdprid tune --method sihd5 --noise-std 5e-4``
#: on the benchmark circle; see results/tuning.md) and alpha ranges.
METHOD_INFO = {
    "sihd4": {
        "params": dict(zip([f"lambda{q}" for q in range(1, 5)], poly_gains(9.0, 4), strict=True),
                       alpha=0.99, mu=1.0),
        "alpha_range": (alpha_min(4), 1.0),
        "causal": True,
        "description": "Semi-implicit homogeneous differentiator with 4 states (p, v, a, jerk) "
        "and 4 projectors; Taylor prediction, exact on cubics.",
    },
    "sihd5": {
        "params": {"lambda1": 19.81, "lambda2": 125.6, "lambda3": 959.0, "lambda4": 2164.0,
                   "lambda5": 7754.0, "alpha": 0.97, "mu": 1.0},
        "alpha_range": (alpha_min(5), 1.0),
        "causal": True,
        "description": "Semi-implicit homogeneous differentiator with 5 states (p..snap) "
        "and 5 projectors; Taylor prediction, exact on quartics; low-lag causal acceleration.",
    },
}


def _order_of(method: str) -> int:
    if method not in METHOD_INFO:
        raise InputError(
            f"unknown higher-order SIHD {method!r}; use one of {', '.join(METHOD_INFO)}.")
    return int(method[4:])


_jit_channels = jax.jit(
    lambda y, h, lams, alpha, mu: jax.vmap(
        lambda c: sihdn_channel(c, h, lams, alpha, mu), in_axes=1, out_axes=1)(y)
)


def differentiate_high(y, dt, method="sihd5", **params):
    """First and second derivatives by a higher-order SIHD (the methods of :data:`METHOD_INFO`),
    like :func:`cdprid.signal.differentiate`.

    Parameters
    ----------
    y : array_like (N,) or (N, k)
        Uniformly sampled signal(s), time first (any unit U).
    dt : float
        Sampling period, s.
    method : str
        A key of :data:`METHOD_INFO` (``"sihd4"``, ``"sihd5"``, ...).
    **params : float
        Overrides of the method's parameters (``lambda1..lambda_n``, ``alpha``, ``mu``).

    Returns
    -------
    d1 : ndarray, the shape of ``y``
        First derivative, U/s.
    d2 : ndarray, the shape of ``y``
        Second derivative, U/s^2.

    Raises
    ------
    InputError
        Unknown method or parameter, a parameter not finite and > 0, ``alpha`` outside
        ``[(n - 1) / n, 1]``.
    """
    n = _order_of(method)
    info = METHOD_INFO[method]
    bad = sorted(set(params) - set(info["params"]))
    if bad:
        raise InputError(f"unknown parameter(s) {', '.join(bad)} for method {method!r}.")
    p = {**info["params"], **{k: float(v) for k, v in params.items()}}
    if not all(math.isfinite(v) and v > 0 for v in p.values()):
        raise InputError(f"parameters of {method!r} must be finite and > 0.")
    lo, hi = info["alpha_range"]
    if not lo <= p["alpha"] <= hi:
        raise InputError(f"{method} needs {lo:g} <= alpha <= 1, got {p['alpha']!r}.")
    arr = np.asarray(y, np.float64)
    sq = arr.ndim == 1
    y2 = arr[:, None] if sq else arr
    with jax.enable_x64(True):
        lams = tuple(jnp.asarray(p[f"lambda{q}"], jnp.float64) for q in range(1, n + 1))
        d1, d2 = _jit_channels(jnp.asarray(y2, jnp.float64), jnp.asarray(float(dt)), lams,
                               jnp.asarray(p["alpha"]), jnp.asarray(p["mu"]))
    d1, d2 = np.asarray(d1), np.asarray(d2)
    return (d1[:, 0], d2[:, 0]) if sq else (d1, d2)
