"""Scan machinery of the differentiators: blocked lax.scan, per-channel kernels,
sharding over devices and the trace counter."""

from __future__ import annotations

import os
from collections import Counter

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.signal import _sihd_high as _sihd_high
from cdprid.signal._kalman import _kalman_channel, _rts_channel
from cdprid.signal._sihd_steps import levant_step, sihd2_step, sihd3_step

#: Number of times each JAX kernel has been traced (a trace precedes every
#: compilation); used by the tests to check that repeated calls do not recompile.
TRACE_COUNTS: Counter = Counter()


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
