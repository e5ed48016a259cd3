"""Numerical differentiators for sampled platform positions.

One public entry point, :func:`differentiate`, returns the first and second
time derivatives of time-first arrays with one of the methods listed in
:data:`METHODS`:

==========================  ======  ==========================================
method                      causal  principle
==========================  ======  ==========================================
``sihd2-cascade`` (default) yes     two SIHD-2 in cascade (seed paper, Fig. 2)
``sihd3``                   yes     one SIHD-2-like observer with 3 projectors
``euler-filtfilt``          no      zero-phase Butterworth + central differences
``euler-butter-causal``     yes     causal Butterworth + backward differences
``levant``                  yes     Levant's 2nd-order robust exact
                                    differentiator, explicit Euler
``savgol``                  no      Savitzky-Golay local polynomial fit
``kalman``                  yes     constant-jerk Kalman filter
``rts``                     no      Rauch-Tung-Striebel smoother (same model)
==========================  ======  ==========================================

The semi-implicit homogeneous differentiators (SIHD) are written as pure
per-step functions (:func:`sihd2_step`, :func:`sihd3_step`) driven by
``jax.lax.scan`` and vmapped over channels.  The derivation, the
continuous-time systems and every resolved typo of the seed paper are in
``docs/sihd.md``.

All JAX-based methods go through one module-level jitted kernel whose only
static argument is the method name; gains and the sampling period are
traced, so calling :func:`differentiate` again with new data of the same
shape (and dtype) does not recompile.  Computations are float64: callers are
expected to enable ``jax_enable_x64``; if it is disabled, :func:`differentiate`
runs its JAX kernels under a temporary x64 scope.
"""

from __future__ import annotations

import contextlib
import math
import os
from collections import Counter
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.signal import _sihd_high as _sihd_high
from cdprid.signal._filters import butter_sos, sosfilt, sosfilt_zi, sosfiltfilt

__all__ = [
    "acceleration_filter",
    "METHODS",
    "MethodInfo",
    "differentiate",
    "zero_phase_filter",
    "projector",
    "sihd2_step",
    "sihd3_step",
    "levant_step",
]


@dataclass(frozen=True)
class MethodInfo:
    """Description of one differentiation method.

    Parameters
    ----------
    name : str
        Key of the method in :data:`METHODS` and value of ``method=``.
    causal : bool
        True when the estimate at sample ``k`` only uses samples ``0..k``.
    params : dict
        Default values of every accepted keyword parameter (do not mutate).
    description : str
        One-line description.
    """

    name: str
    causal: bool
    params: dict = field(hash=False)
    description: str = ""


METHODS: dict[str, MethodInfo] = {
    m.name: m
    for m in (
        MethodInfo(
            "sihd2-cascade",
            True,
            {
                "lambda1": 210.0,
                "lambda2": 210.0,
                "lambda3": 525.0,
                "lambda4": 525.0,
                "alpha": 0.95,
                "mu": 1.0,
            },
            "Two semi-implicit homogeneous differentiators SIHD-2 in cascade "
            "(position->velocity with lambda1, lambda2; velocity->acceleration "
            "with lambda3, lambda4); seed-paper gains (eq. 35).",
        ),
        MethodInfo(
            "sihd3",
            True,
            # triple pole of the linear part (alpha = 1) at s = -omega,
            # omega = 15 rad/s: (s + w)^3 = s^3 + 3w s^2 + 3w^2 s + w^3.
            {"lambda1": 45.0, "lambda2": 675.0, "lambda3": 3375.0, "alpha": 0.95, "mu": 1.0},
            "Semi-implicit homogeneous differentiator with three projectors "
            "(states z1, z2, z3), trapezoidal Taylor term; defaults place the "
            "linear part's triple pole at -15 rad/s.",
        ),
        MethodInfo(
            "euler-filtfilt",
            False,
            {"cutoff_hz": 4.0, "order": 2},
            "Zero-phase Butterworth (filtfilt as scipy's, order 2 -> effective order 4, "
            "cutoff 4 Hz), then second-order central differences (np.gradient for "
            "d1, 3-point second difference for d2).",
        ),
        MethodInfo(
            "euler-butter-causal",
            True,
            {"cutoff_hz": 4.0, "order": 2},
            "Causal Butterworth (lfilter as scipy's, steady-state initial conditions), "
            "then backward differences.",
        ),
        MethodInfo(
            "levant",
            True,
            {"L": 2.0, "lambda0": 1.1, "lambda1": 1.5, "lambda2": 2.0},
            "Levant's recursive 2nd-order robust exact differentiator, explicit "
            "Euler; L bounds |y'''|.",
        ),
        MethodInfo(
            "savgol",
            False,
            {"window_s": 1.5, "polyorder": 5},
            "Savitzky-Golay filter (scipy savgol_filter deriv=1, 2; mode='interp'); "
            "window_s is rounded to an odd number of samples.",
        ),
        MethodInfo(
            "kalman",
            True,
            {"q": 0.3, "r": 2.5e-7},
            "Constant-jerk Kalman filter (states pos, vel, acc, jerk; white snap "
            "with spectral density q, measurement variance r).",
        ),
        MethodInfo(
            "rts",
            False,
            {"q": 0.1, "r": 2.5e-7},
            "Rauch-Tung-Striebel smoother of the constant-jerk model.",
        ),
    )
}
# higher-order SIHD (5 and 4 states), see cdprid.signal._sihd_high and docs/sihd.md
for _n in (4, 5):
    _info = _sihd_high.METHOD_INFO[f"sihd{_n}"]
    METHODS[f"sihd{_n}"] = MethodInfo(f"sihd{_n}", True, dict(_info["params"]),
                                      _info["description"])

#: Number of times each JAX kernel has been traced (a trace precedes every
#: compilation); used by the tests to check that repeated calls do not recompile.
TRACE_COUNTS: Counter = Counter()


# ----------------------------------------------------------------------------
# Semi-implicit homogeneous differentiators: pure per-step functions
# ----------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------
# Constant-jerk Kalman filter / RTS smoother
# ----------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------
# JAX kernels
# ----------------------------------------------------------------------------


# lax.scan unroll factor of the SIHD scans.  Unrolling by 8-16 speeds the
# scan up ~2x on CPU but multiplies the compile time (1 s -> 8-14 s per shape),
# so it is opt-in through the environment variable.
_UNROLL = int(os.environ.get("CDPRID_SCAN_UNROLL", "1"))

# Output blocks (see scan_blocked) for few channels: the SIHD scans collect their
# outputs in blocks of ``B`` steps, each block buffer at most this many bytes
# (benchmarks/differentiators.py times one signal with and without blocking).
_SMALL_BUFFER_BYTES = 384


def _block_size(k: int, itemsize: int = 8) -> int:
    """Output block length for ``k`` channels (0 = plain scan: buffers too wide)."""
    return min(16, _SMALL_BUFFER_BYTES // (itemsize * max(k, 1)))


def _tmap(f, *trees):
    return jax.tree_util.tree_map(f, *trees)


def scan_blocked(step, init, xs, block: int = 0, return_carry: bool = False):
    """``jax.lax.scan(step, init, xs)`` with the outputs gathered in blocks.

    XLA:CPU runs a while-loop body whose buffers are all small (about 512 bytes
    or less) in order on the calling thread; a body that writes its per-step
    outputs into the full ``(n, ...)`` output arrays goes through the concurrent
    executor instead, at a cost per fused kernel and step.  This
    driver keeps the last ``block`` outputs in the carry (a shift register),
    emits one block per outer step, and returns exactly what ``lax.scan``
    returns.

    Parameters
    ----------
    step : callable
        ``(carry, x) -> (carry, y)`` as for :func:`jax.lax.scan` (``y`` a
        pytree of arrays).
    init : pytree
        Initial carry.
    xs : pytree of arrays
        Inputs, time first (same leading length).
    block : int, optional
        Steps per output block; ``<= 0`` runs a plain ``lax.scan``.
    return_carry : bool, optional
        Return ``(final_carry, ys)`` instead of ``ys``.

    Returns
    -------
    ys or (carry, ys)
        The stacked per-step outputs (and the final carry), as ``lax.scan``.
    """
    if block <= 0:
        carry, ys = jax.lax.scan(step, init, xs, unroll=_UNROLL)
        return (carry, ys) if return_carry else ys
    n = jax.tree_util.tree_leaves(xs)[0].shape[0]
    x0 = _tmap(lambda v: v[0], xs)
    y_shape = jax.eval_shape(step, init, x0)[1]

    def run(carry, xpart, b):
        """Scan ``xpart`` (length a multiple of ``b``) in blocks of ``b`` steps."""
        m = jax.tree_util.tree_leaves(xpart)[0].shape[0]
        xb = _tmap(lambda v: v.reshape((m // b, b) + v.shape[1:]), xpart)
        buf0 = _tmap(lambda sd: jnp.zeros((b,) + sd.shape, sd.dtype), y_shape)

        def inner(c, x):
            s, buf = c
            s, y = step(s, x)
            buf = _tmap(lambda bb, v: jnp.concatenate([bb[1:], v[None]], axis=0), buf, y)
            return (s, buf), None

        def outer(s, xblk):
            (s, buf), _ = jax.lax.scan(inner, (s, buf0), xblk, unroll=_UNROLL)
            return s, buf

        carry, yb = jax.lax.scan(outer, carry, xb)
        return carry, _tmap(lambda v: v.reshape((m,) + v.shape[2:]), yb)

    n_main = (n // block) * block
    parts = []
    carry = init
    if n_main:
        carry, ys = run(carry, _tmap(lambda v: v[:n_main], xs), block)
        parts.append(ys)
    if n_main < n:  # the tail as one shorter block: the final carry stays exact
        carry, ys = run(carry, _tmap(lambda v: v[n_main:], xs), n - n_main)
        parts.append(ys)
    ys = parts[0] if len(parts) == 1 else _tmap(lambda *v: jnp.concatenate(v, axis=0), *parts)
    return (carry, ys) if return_carry else ys


def _sihd2_cascade_channel(y, h, p, block=0):
    g1 = (p[0], p[1], p[4], p[5])
    g2 = (p[2], p[3], p[4], p[5])

    def step(carry, yk):
        s1, s2 = carry
        s1, v = sihd2_step(s1, yk, g1, h)
        s2, a = sihd2_step(s2, v, g2, h)
        return (s1, s2), (v, a)

    zero = jnp.zeros((), y.dtype)
    # stage 1 starts at (y0, 0); its first output is exactly 0 (e = 0), so
    # stage 2 starts at (first input sample, 0) = (0, 0)
    init = ((y[0], zero), (zero, zero))
    return scan_blocked(step, init, y, block)


def _sihd3_channel(y, h, p, block=0):
    zero = jnp.zeros((), y.dtype)
    g = (p[0], p[1], p[2], p[3], p[4])
    return scan_blocked(lambda s, yk: sihd3_step(s, yk, g, h), (y[0], zero, zero), y, block)


def _levant_channel(y, h, p, block=0):
    zero = jnp.zeros((), y.dtype)
    g = (p[0], p[1], p[2], p[3])
    return scan_blocked(lambda s, fk: levant_step(s, fk, g, h), (y[0], zero, zero), y, block)


_CHANNEL_FNS = {
    "sihd2-cascade": _sihd2_cascade_channel,
    "sihd3": _sihd3_channel,
    "levant": _levant_channel,
    # no output blocking for these (block ignored)
    "kalman": lambda y, h, p, block=0: _kalman_channel(y, h, p[0], p[1]),
    "rts": lambda y, h, p, block=0: _rts_channel(y, h, p[0], p[1]),
    "sihd4": lambda y, h, p, block=0: _sihd_high.channel(4)(y, h, p),
    "sihd5": lambda y, h, p, block=0: _sihd_high.channel(5)(y, h, p),
}


def _jax_kernel_impl(method, y, h, p):
    """Run a JAX method on a (n, k) array; vmapped over the k channels."""
    TRACE_COUNTS[method] += 1
    fn = _CHANNEL_FNS[method]
    block = _block_size(y.shape[1], y.dtype.itemsize)
    return jax.vmap(lambda col: fn(col, h, p, block), in_axes=1, out_axes=1)(y)


_jax_kernel = jax.jit(_jax_kernel_impl, static_argnames=("method",))

# Channels are independent, so with several host devices (one per core, e.g.
# XLA_FLAGS=--xla_force_host_platform_device_count=2) a wide array is split
# across them by channel; XLA:CPU otherwise runs the scan on one core.
_MIN_CHANNELS_PER_DEVICE = 64
_SHARDED = {}


def _sharded_kernel(method, ndev):
    """Jitted ``shard_map`` of the kernel over ``ndev`` devices (channel axis)."""
    key = (method, ndev)
    if key not in _SHARDED:
        from jax.sharding import Mesh, NamedSharding, PartitionSpec

        mesh = Mesh(np.array(jax.local_devices()[:ndev]), ("c",))
        spec = PartitionSpec(None, "c")
        fn = jax.jit(
            jax.shard_map(
                lambda y, h, p: _jax_kernel_impl(method, y, h, p),
                mesh=mesh,
                in_specs=(spec, PartitionSpec(), PartitionSpec()),
                out_specs=(spec, spec),
                check_vma=False,
            )
        )
        _SHARDED[key] = (fn, NamedSharding(mesh, spec))
    return _SHARDED[key]


def _run_jax_kernel(method, y2, dt, vec):
    """Kernel on a numpy (n, k) array; split over host devices when wide."""
    ndev = jax.local_device_count()
    k = y2.shape[1]
    if ndev > 1 and k >= ndev * _MIN_CHANNELS_PER_DEVICE:
        fn, sharding = _sharded_kernel(method, ndev)
        pad = (-k) % ndev
        yp = np.concatenate([y2, np.repeat(y2[:, -1:], pad, axis=1)], axis=1) if pad else y2
        d1, d2 = fn(jax.device_put(yp, sharding), jnp.asarray(dt, jnp.float64),
                    jnp.asarray(vec, jnp.float64))
        return np.asarray(d1, np.float64)[:, :k], np.asarray(d2, np.float64)[:, :k]
    d1, d2 = _jax_kernel(
        method,
        jnp.asarray(y2, jnp.float64),
        jnp.asarray(dt, jnp.float64),
        jnp.asarray(vec, jnp.float64),
    )
    return np.asarray(d1, np.float64), np.asarray(d2, np.float64)


# ----------------------------------------------------------------------------
# SciPy-based methods
# ----------------------------------------------------------------------------


def _butter(order, cutoff_hz, dt):
    """Second-order sections of the Butterworth low-pass (:func:`cdprid.signal.butter_sos`)."""
    fs = 1.0 / dt
    if not 0.0 < cutoff_hz < 0.5 * fs:
        raise ValueError(
            f"cutoff_hz must lie in (0, Nyquist = {0.5 * fs:g} Hz), got {cutoff_hz!r}."
        )
    return butter_sos(int(order), cutoff_hz, fs)


def zero_phase_filter(x, dt, cutoff_hz=4.0, order=2):
    """Zero-phase low-pass Butterworth filter used by ``euler-filtfilt``.

    The identification pipeline applies this same filter to the cable wrench
    (matched filtering), so that positions and forces share the same
    (zero) phase and magnitude distortion.

    Parameters
    ----------
    x : array_like, shape (n,) or (n, k)
        Time-first signal.
    dt : float
        Sampling period in seconds.
    cutoff_hz : float, optional
        -3 dB cutoff of the single-pass filter (default 4 Hz, seed paper).
    order : int, optional
        Order of the Butterworth design (default 2); ``filtfilt`` applies it
        forward and backward, so the magnitude response is squared
        (effective order ``2 * order``) and the phase is zero.

    Returns
    -------
    numpy.ndarray
        Filtered float64 signal, same shape as ``x``.

    Notes
    -----
    The signal is extended at both ends by odd reflection over
    ``min(n - 1, ceil(5 / (cutoff_hz * dt)))`` samples (scipy's default of
    ``3 * (order + 1)`` samples leaves a visible start-up transient), so
    straight lines are reproduced exactly; curvature near the two ends is
    distorted over roughly ``1 / cutoff_hz`` seconds.
    """
    x = np.asarray(x, dtype=np.float64)
    sos = _butter(order, cutoff_hz, float(dt))
    # odd (point-symmetric) extension long enough (5 / cutoff seconds) for the
    # start-up transient to die out inside the padding: straight lines pass
    # exactly, end effects stay confined to about 1/cutoff seconds
    padlen = min(x.shape[0] - 1, int(math.ceil(5.0 / (cutoff_hz * float(dt)))))
    return sosfiltfilt(sos, x, padlen)


def _central(x, dt):
    """Central first and second differences, same length (2nd order one-sided ends)."""
    d1 = np.gradient(x, dt, axis=0, edge_order=2)
    d2 = np.empty_like(x)
    d2[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt**2
    d2[0] = d2[1]
    d2[-1] = d2[-2]
    return d1, d2


def _euler_filtfilt(y, dt, cutoff_hz, order):
    return _central(zero_phase_filter(y, dt, cutoff_hz, order), dt)


def _euler_butter_causal(y, dt, cutoff_hz, order):
    sos = _butter(order, cutoff_hz, dt)
    xf = sosfilt(sos, y, sosfilt_zi(sos)[:, :, None] * y[0][None, None, :])
    d1 = np.zeros_like(xf)
    d2 = np.zeros_like(xf)
    d1[1:] = (xf[1:] - xf[:-1]) / dt
    d2[2:] = (xf[2:] - 2.0 * xf[1:-1] + xf[:-2]) / dt**2
    return d1, d2


def _savgol(y, dt, window_s, polyorder):
    n = y.shape[0]
    w = int(round(window_s / dt))
    w += 1 - w % 2  # odd
    polyorder = int(polyorder)
    if w <= polyorder or polyorder < 2:
        raise ValueError(
            f"savgol needs polyorder >= 2 and an odd window of more than polyorder samples "
            f"(window_s={window_s!r} -> {w} samples, polyorder={polyorder!r})."
        )
    if w > n:
        raise ValueError(f"savgol window ({w} samples) is longer than the signal ({n} samples).")
    from scipy.signal import savgol_filter  # lazy: scipy.signal costs ~1 s of start-up

    kw = dict(window_length=w, polyorder=polyorder, delta=dt, axis=0, mode="interp")
    return savgol_filter(y, deriv=1, **kw), savgol_filter(y, deriv=2, **kw)


# ----------------------------------------------------------------------------
# Public entry point
# ----------------------------------------------------------------------------


def _check_params(method, params):
    if method not in METHODS:
        raise ValueError(
            f"Unknown differentiation method {method!r}; valid names are: {', '.join(METHODS)}."
        )
    info = METHODS[method]
    bad = sorted(set(params) - set(info.params))
    if bad:
        raise ValueError(
            f"Unknown parameter(s) {', '.join(bad)} for method {method!r}; valid "
            f"parameters are: {', '.join(info.params)}."
        )
    p = {**info.params, **params}
    for k, v in p.items():
        try:
            fv = float(v)
        except (TypeError, ValueError):
            raise ValueError(
                f"Parameter {k!r} of method {method!r} must be a number, got {v!r}."
            ) from None
        if not (math.isfinite(fv) and fv > 0.0):
            raise ValueError(
                f"Parameter {k!r} of method {method!r} must be finite and > 0, got {v!r}."
            )
        if k in ("order", "polyorder"):
            if fv != int(fv):
                raise ValueError(
                    f"Parameter {k!r} of method {method!r} must be an integer, got {v!r}."
                )
            fv = int(fv)
        p[k] = fv
    if method == "sihd2-cascade" and not 0.5 <= p["alpha"] <= 1.0:
        raise ValueError(f"sihd2-cascade needs 0.5 <= alpha <= 1, got {p['alpha']!r}.")
    if method == "sihd3" and not 2.0 / 3.0 <= p["alpha"] <= 1.0:
        raise ValueError(f"sihd3 needs 2/3 <= alpha <= 1, got {p['alpha']!r}.")
    for _n in (4, 5):
        if method == f"sihd{_n}" and not (_n - 1) / _n <= p["alpha"] <= 1.0:
            raise ValueError(f"sihd{_n} needs {(_n - 1) / _n:g} <= alpha <= 1, got {p['alpha']!r}.")
    if method == "levant" and p["lambda0"] <= 1.0:
        raise ValueError(f"levant needs lambda0 > 1, got {p['lambda0']!r}.")
    return p


def _x64_scope():
    if jax.config.read("jax_enable_x64"):
        return contextlib.nullcontext()
    return jax.enable_x64(True)  # pragma: no cover - callers normally enable x64


def differentiate(y, dt, method="sihd2-cascade", **params) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of sampled signals.

    Parameters
    ----------
    y : array_like, shape (n,) or (n, k)
        Time-first samples (numpy or JAX array), uniformly sampled.
    dt : float
        Sampling period in seconds (> 0).
    method : str, optional
        One of :data:`METHODS` (default ``"sihd2-cascade"``, the seed paper's
        cascade of two SIHD-2 with its gains, eq. 35).
    **params
        Method parameters overriding ``METHODS[method].params``.

    Returns
    -------
    d1, d2 : numpy.ndarray
        float64 estimates of the first and second derivatives, same shape as
        ``y``.  Causal methods return, at sample ``k``, an estimate that only
        uses ``y[:k+1]``.

    Raises
    ------
    ValueError
        Unknown method, unknown or invalid parameter, bad shape or ``dt``.

    Examples
    --------
    >>> t = np.arange(0, 10, 0.01)
    >>> v, a = differentiate(np.c_[np.cos(t), np.sin(t)], 0.01, method="savgol")
    """
    p = _check_params(method, params)
    arr = np.asarray(y, dtype=np.float64)
    if arr.ndim not in (1, 2) or arr.shape[0] < 3:
        raise ValueError(f"y must have shape (n,) or (n, k) with n >= 3, got shape {arr.shape}.")
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise ValueError(f"dt must be a positive number, got {dt!r}.") from None
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"dt must be a positive number, got {dt!r}.")
    squeeze = arr.ndim == 1
    y2 = arr[:, None] if squeeze else arr

    if method == "euler-filtfilt":
        d1, d2 = _euler_filtfilt(y2, dt, p["cutoff_hz"], p["order"])
    elif method == "euler-butter-causal":
        d1, d2 = _euler_butter_causal(y2, dt, p["cutoff_hz"], p["order"])
    elif method == "savgol":
        d1, d2 = _savgol(y2, dt, p["window_s"], p["polyorder"])
    else:
        vec = np.array(list(p.values()), dtype=np.float64)
        with _x64_scope():
            d1, d2 = _run_jax_kernel(method, y2, dt, vec)
    if squeeze:
        d1, d2 = d1[:, 0], d2[:, 0]
    return np.ascontiguousarray(d1), np.ascontiguousarray(d2)


def acceleration_filter(y, dt, method: str = "euler-filtfilt", scale=None, **params) -> np.ndarray:
    """Pass a signal through the filter that ``method`` applies to accelerations.

    Matched filtering (paper section 7 for the zero-phase recipe; ``results/mzg-gap.md`` for the
    causal differentiators): the regressor sees the *estimated* acceleration, i.e. the true one
    through the differentiator's low-pass ``H`` (zero-phase or causal, with its lag). Filtering
    ``W tau`` by the same ``H`` keeps both sides of ``W tau = A x`` on the same footing, so the
    lag does not bias the estimate.

    ``euler-filtfilt`` uses its zero-phase Butterworth directly. Every other method gets ``H``
    from itself: the mean-free signal is integrated twice (trapezoid) and differentiated twice
    by ``method``; for a linear method this is exactly ``H`` applied to the signal; for the
    homogeneous (SIHD, Levant) ones it is their response at the amplitude ``scale`` (the signal
    is divided by ``scale`` first, so that it is an acceleration-sized input like the
    positions' second derivative, then multiplied back), the describing function of the
    linearised low-pass. The mean passes unchanged (a constant wrench is what a platform at
    rest gives).

    Parameters
    ----------
    y : array_like (n,) or (n, k)
        Time-first signal (e.g. the measured wrench ``W tau``, (n, 6)).
    dt : float
        Sampling period, s.
    method : str
        A method of :data:`METHODS`.
    scale : float or array (k,), optional
        Amplitude normalisation per channel (e.g. the mass for force rows, so the input is an
        acceleration in m/s^2). Default 1.
    **params
        The method's parameters (as given to :func:`differentiate`).

    Returns
    -------
    ndarray, same shape as ``y``
    """
    arr = np.asarray(y, np.float64)
    if method == "euler-filtfilt":
        p = _check_params(method, params)
        return zero_phase_filter(arr, dt, p["cutoff_hz"], p["order"])
    squeeze = arr.ndim == 1
    x = arr[:, None] if squeeze else arr
    s = np.ones(x.shape[1]) if scale is None else np.broadcast_to(np.asarray(scale, float),
                                                                   (x.shape[1],))
    mu = x.mean(axis=0)
    u = (x - mu) / s
    i1 = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(0.5 * dt * (u[1:] + u[:-1]), 0)])
    i2 = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(0.5 * dt * (i1[1:] + i1[:-1]), 0)])
    _, a = differentiate(i2, dt, method=method, **params)
    out = a * s + mu
    return out[:, 0] if squeeze else out
