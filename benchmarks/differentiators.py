"""Benchmark of cdprid.signal._differentiators: accuracy on a noisy circle and speed.

Usage::

    .venv/bin/python -m benchmarks.differentiators [--quick] [--no-pynumdiff]

Accuracy: 3-D acceleration RMSE over t >= 2 s of a circle (R = 0.3 m,
0.25 Hz, sampled at 100 Hz for 52 s) with white Gaussian position noise of
0.1, 0.2, 0.5 and 1 mm, 5 seeds, every method of ``METHODS`` (plus a tuned
SIHD-2 cascade and, if ``pynumdiff`` imports, its auto-tuned methods).
Speed: SIHD-2 cascade throughput for one 5200x3 signal and a batch of
1000 x (5200x3) signals, against a pure-Python loop of the same equations, the
same loop with NumPy arrays over the channels, and scipy filtfilt.  Prints a
table and writes ``results/differentiators.md``.

The script exposes one XLA host device per core (``XLA_FLAGS=
--xla_force_host_platform_device_count=<cores>``, set before JAX is imported
unless XLA_FLAGS is already set) so that :func:`cdprid.differentiate` splits
wide batches across the cores; the single-device kernel is timed too.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
import warnings

if "XLA_FLAGS" not in os.environ:
    os.environ["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={os.cpu_count() or 1}"

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

from cdprid.signal import (  # noqa: E402  # noqa: E402
    _CHANNEL_FNS,
    METHODS,
    _block_size,
    _jax_kernel,
    _sharded_kernel,
    differentiate,
)

DT = 0.01
T_END = 52.0
R = 0.3
F_HZ = 0.25
NOISES_MM = (0.1, 0.2, 0.5, 1.0)
TUNED_CASCADE = {"lambda2": 500.0, "lambda4": 800.0}


def circle():
    """Noise-free positions and accelerations of the 3-D test trajectory."""
    t = np.arange(int(round(T_END / DT))) * DT
    w = 2.0 * math.pi * F_HZ
    pos = np.c_[R * np.cos(w * t), R * np.sin(w * t), np.full_like(t, 1.2)]
    acc = np.c_[-R * w**2 * np.cos(w * t), -R * w**2 * np.sin(w * t), np.zeros_like(t)]
    return t, pos, acc


def rmse3(a_hat, acc, mask):
    return float(np.sqrt(np.mean(np.sum((a_hat - acc)[mask] ** 2, axis=1))))


# ---------------------------------------------------------------------------
# pure-Python SIHD-2 cascade (same equations as cdprid.signal._differentiators)
# ---------------------------------------------------------------------------


def _corr(e, q, lam, alpha, mu, h):
    p = q * (1.0 - alpha)
    lq = lam * (mu * h) ** q
    s = (e > 0) - (e < 0)
    ae = abs(e)
    n = s * ae**p / lq if ae**p < lq else float(s)
    return lam * mu**q * ae ** (q * alpha - (q - 1)) * n


def cascade_python(y, h, l1=210.0, l2=210.0, l3=525.0, l4=525.0, alpha=0.95, mu=1.0):
    """Plain-Python loop of the SIHD-2 cascade for one channel."""
    z1, z2, w1, w2 = float(y[0]), 0.0, 0.0, 0.0
    d1 = [0.0] * len(y)
    d2 = [0.0] * len(y)
    for k, yk in enumerate(y):
        e = yk - z1
        z2 = z2 + h * _corr(e, 2, l2, alpha, mu, h)
        z1 = z1 + h * (z2 + _corr(e, 1, l1, alpha, mu, h))
        e = z2 - w1
        w2 = w2 + h * _corr(e, 2, l4, alpha, mu, h)
        w1 = w1 + h * (w2 + _corr(e, 1, l3, alpha, mu, h))
        d1[k], d2[k] = z2, w2
    return d1, d2


def cascade_numpy(y, h, l1=210.0, l2=210.0, l3=525.0, l4=525.0, alpha=0.95, mu=1.0):
    """The same loop over time with NumPy arrays over the channels (y: (n, k))."""

    def corr(e, q, lam):
        ae = np.abs(e)
        with np.errstate(divide="ignore", invalid="ignore"):
            expl = lam * mu**q * ae ** (q * alpha - (q - 1))
        return np.sign(e) * np.minimum(expl, ae / h**q)

    z1, z2 = y[0].copy(), np.zeros(y.shape[1])
    w1, w2 = np.zeros(y.shape[1]), np.zeros(y.shape[1])
    d1, d2 = np.empty_like(y), np.empty_like(y)
    for k in range(y.shape[0]):
        e = y[k] - z1
        z2 = z2 + h * corr(e, 2, l2)
        z1 = z1 + h * (z2 + corr(e, 1, l1))
        e = z2 - w1
        w2 = w2 + h * corr(e, 2, l4)
        w1 = w1 + h * (w2 + corr(e, 1, l3))
        d1[k], d2[k] = z2, w2
    return d1, d2


def best_time(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


# ---------------------------------------------------------------------------
# PyNumDiff (optional)
# ---------------------------------------------------------------------------


def pynumdiff_rows(t, pos, acc, mask, noises, seeds, quick):
    """Auto-tuned PyNumDiff methods, applied twice (x -> v -> a)."""
    try:
        import pynumdiff  # noqa: F401
        from pynumdiff.optimize import optimize
        from pynumdiff.polynomial_fit import savgoldiff
        from pynumdiff.smooth_finite_difference import butterdiff
    except Exception as exc:  # pragma: no cover - optional dependency
        return [], f"PyNumDiff rows skipped: `import pynumdiff` failed ({exc!r})."
    import pynumdiff as _p

    funcs = [butterdiff] if quick else [butterdiff, savgoldiff]
    rows = []
    for f in funcs:
        res = {}
        params_used = {}
        for noise in noises:
            tune_noise = 0.5 if quick else noise
            if tune_noise not in params_used:
                rng = np.random.default_rng(1000)
                x0 = pos[:, 0] + tune_noise * 1e-3 * rng.standard_normal(pos.shape[0])
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    p1, _ = optimize(f, x0, DT, bandlimit=2 * F_HZ, parallel=True)
                    _, v0 = f(x0, DT, **p1)
                    p2, _ = optimize(f, v0, DT, bandlimit=2 * F_HZ, parallel=True)
                params_used[tune_noise] = (p1, p2)
            p1, p2 = params_used[tune_noise]
            errs = []
            for seed in range(seeds):
                rng = np.random.default_rng(seed)
                y = pos + noise * 1e-3 * rng.standard_normal(pos.shape)
                a = np.empty_like(y)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    for c in range(3):
                        _, v = f(y[:, c], DT, **p1)
                        _, a[:, c] = f(v, DT, **p2)
                errs.append(rmse3(a, acc, mask))
            res[noise] = errs
        rows.append((f"pynumdiff {f.__name__} (auto x2)", False, res))
    note = (
        f"PyNumDiff {getattr(_p, '__version__', '?')}: each method is tuned with "
        "`pynumdiff.optimize.optimize(func, x, dt, bandlimit=0.5 Hz)` (ground-truth free) "
        "on position, then re-tuned on the resulting velocity to get the acceleration; "
        "tuning is done once per noise level (with --quick: once, at 0.5 mm) on an "
        "independent noise draw of the x channel and the parameters are reused for "
        "every seed and channel. "
        "rtsdiff is excluded (its tuning took > 8 min per signal on this machine)."
    )
    return rows, note


# ---------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 seeds, 100-signal batch")
    ap.add_argument("--no-pynumdiff", action="store_true", help="skip PyNumDiff rows")
    ap.add_argument("--speed-only", action="store_true",
                    help="only the speed part; prints it and writes nothing unless --out is given")
    ap.add_argument("--out", default=None, help="default: results/differentiators.md")
    args = ap.parse_args(argv)
    if args.out is None and not args.speed_only:
        args.out = "results/differentiators.md"
    seeds = 2 if args.quick else 5
    n_batch = 100 if args.quick else 1000
    command = " ".join([os.path.basename(sys.executable), *sys.argv])

    t, pos, acc = circle()
    mask = t >= 2.0

    # ---------------- accuracy ----------------
    entries = [(m, info.causal, {}) for m, info in METHODS.items()]
    entries.insert(1, ("sihd2-cascade", True, TUNED_CASCADE))
    rows = []
    for m, causal, kw in [] if args.speed_only else entries:
        res = {}
        for noise in NOISES_MM:
            errs = []
            for seed in range(seeds):
                rng = np.random.default_rng(seed)
                y = pos + noise * 1e-3 * rng.standard_normal(pos.shape)
                _, a = differentiate(y, DT, m, **kw)
                errs.append(rmse3(a, acc, mask))
            res[noise] = errs
        label = m if not kw else m + " (" + ", ".join(f"{k}={v:g}" for k, v in kw.items()) + ")"
        rows.append((label, causal, res))
        print(f"  {label:40s} done", flush=True)
    pnd_note = "PyNumDiff rows skipped (--no-pynumdiff)."
    if not args.no_pynumdiff and not args.speed_only:
        t0 = time.perf_counter()
        prows, pnd_note = pynumdiff_rows(t, pos, acc, mask, NOISES_MM, seeds, args.quick)
        rows += prows
        pnd_note += f" (PyNumDiff part: {time.perf_counter() - t0:.0f} s)"

    # ---------------- speed ----------------
    rng = np.random.default_rng(0)
    one = pos + 5e-4 * rng.standard_normal(pos.shape)
    batch = np.repeat(one[:, :, None], n_batch, axis=2)
    batch += 1e-4 * rng.standard_normal(batch.shape)
    batch2d = batch.reshape(pos.shape[0], 3 * n_batch)
    n_one = one.size
    n_bat = batch2d.size

    ndev = jax.local_device_count()
    differentiate(one, DT)  # compile
    t_one = best_time(lambda: differentiate(one, DT), 20)
    t0 = time.perf_counter()
    differentiate(batch2d, DT)  # compile + first run
    t_bat_first = time.perf_counter() - t0
    t_bat = best_time(lambda: differentiate(batch2d, DT), 3)
    # the kernel alone on one device, data already on the device
    p_vec = jnp.asarray(list(METHODS["sihd2-cascade"].params.values()), jnp.float64)
    h_dev = jnp.asarray(DT, jnp.float64)
    bat_dev = jnp.asarray(batch2d)
    jax.block_until_ready(_jax_kernel("sihd2-cascade", bat_dev, h_dev, p_vec))
    t_bat_k1 = best_time(
        lambda: jax.block_until_ready(_jax_kernel("sihd2-cascade", bat_dev, h_dev, p_vec)), 3
    )
    # output blocking (scan_blocked) on one signal, kernel only, timed interleaved
    one_dev = jnp.asarray(one)
    plain = jax.jit(lambda y, h, p: jax.vmap(
        lambda c: _CHANNEL_FNS["sihd2-cascade"](c, h, p, 0), in_axes=1, out_axes=1)(y))
    runs = {"blocked": [], "plain": []}
    fns = {"blocked": lambda: _jax_kernel("sihd2-cascade", one_dev, h_dev, p_vec),
           "plain": lambda: plain(one_dev, h_dev, p_vec)}
    for f in fns.values():
        jax.block_until_ready(f())
    for _ in range(20):
        for name, f in fns.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f())
            runs[name].append(time.perf_counter() - t0)
    t_blk, t_plain = min(runs["blocked"]), min(runs["plain"])
    t_bat_kn = None
    if ndev > 1:
        fn_sh, sharding = _sharded_kernel("sihd2-cascade", ndev)
        bat_sh = jax.device_put(batch2d, sharding)
        jax.block_until_ready(fn_sh(bat_sh, h_dev, p_vec))
        t_bat_kn = best_time(lambda: jax.block_until_ready(fn_sh(bat_sh, h_dev, p_vec)), 3)
    n_py = 520
    t_py_piece = best_time(lambda: cascade_python(one[:n_py, 0].tolist(), DT), 3)
    t_py_one = t_py_piece * n_one / n_py
    t_py_bat = t_py_piece * n_bat / n_py
    t_np_one = best_time(lambda: cascade_numpy(one, DT), 3)
    t_np_bat = best_time(lambda: cascade_numpy(batch2d, DT), 1)
    b, a = signal.butter(2, 4.0, fs=1 / DT)
    t_ff_one = best_time(lambda: signal.filtfilt(b, a, one, axis=0), 20)
    t_ff_bat = best_time(lambda: signal.filtfilt(b, a, batch2d, axis=0), 2)
    # consistency of the timed implementations
    d1_py, d2_py = cascade_python(one[:, 0].tolist(), DT)
    d1_j, d2_j = differentiate(one[:, 0], DT)
    d1_n, d2_n = cascade_numpy(one, DT)
    max_dev = float(max(np.max(np.abs(d1_j - d1_py)), np.max(np.abs(d2_j - d2_py)),
                        np.max(np.abs(d2_n[:, 0] - d2_py))))

    # ---------------- report ----------------
    hdr = "| method | causal | " + " | ".join(f"{n:g} mm" for n in NOISES_MM) + " |"
    sep = "|---|:-:|" + "---:|" * len(NOISES_MM)
    lines = [hdr, sep]
    for label, causal, res in rows:
        cells = [f"{np.mean(res[n]):.4f} ± {np.std(res[n]):.4f}" for n in NOISES_MM]
        lines.append(f"| {label} | {'yes' if causal else 'no'} | " + " | ".join(cells) + " |")
    acc_table = "\n".join(lines)

    def thr(n, s):
        return f"{n / s / 1e6:.3g} M samples/s"

    speed = [
        "| case | SIHD-2 cascade: `differentiate` (JAX scan, jit) | pure-Python loop (scaled) "
        "| NumPy loop over time | scipy filtfilt (4 Hz, order 2) | JAX / Python | JAX / NumPy "
        "| JAX / filtfilt |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
        f"| one 5200x3 signal | {t_one * 1e3:.2f} ms ({thr(n_one, t_one)}) | "
        f"{t_py_one * 1e3:.0f} ms ({thr(n_one, t_py_one)}) | {t_np_one * 1e3:.0f} ms | "
        f"{t_ff_one * 1e3:.2f} ms | "
        f"{t_py_one / t_one:.1f}x faster | {t_np_one / t_one:.0f}x faster | "
        f"{t_one / t_ff_one:.1f}x the time |",
        f"| batch {n_batch} x (5200x3), {ndev} device(s) | {t_bat:.2f} s ({thr(n_bat, t_bat)}) | "
        f"{t_py_bat:.0f} s ({thr(n_bat, t_py_bat)}) | {t_np_bat:.1f} s | {t_ff_bat:.2f} s | "
        f"{t_py_bat / t_bat:.0f}x faster | {t_np_bat / t_bat:.1f}x faster | "
        f"{t_bat / t_ff_bat:.1f}x the time |",
        f"| same batch, kernel only, 1 device, data on device | {t_bat_k1:.2f} s "
        f"({thr(n_bat, t_bat_k1)}) | | | | {t_py_bat / t_bat_k1:.0f}x faster | "
        f"{t_np_bat / t_bat_k1:.1f}x faster | |",
    ]
    if t_bat_kn is not None:
        speed.append(
            f"| same batch, kernel only, {ndev} devices, data on devices | {t_bat_kn:.2f} s "
            f"({thr(n_bat, t_bat_kn)}) | | | | {t_py_bat / t_bat_kn:.0f}x faster | "
            f"{t_np_bat / t_bat_kn:.1f}x faster | |"
        )
    speed_table = "\n".join(speed)
    machine = (
        f"{platform.platform()}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs ({platform.processor() or platform.machine()}), "
        f"jax {jax.__version__} ({jax.default_backend()}), numpy {np.__version__}"
    )
    md = f"""# Differentiator benchmark

Command: `{command}`\
Machine: {machine}\
Date: {time.strftime("%Y-%m-%d %H:%M:%S")}

## Accuracy: 3-D acceleration RMSE (m/s²), t ≥ 2 s

Circle R = {R} m at {F_HZ} Hz (acceleration amplitude {R * (2 * math.pi * F_HZ) ** 2:.3f} m/s²),
dt = {DT} s, {T_END:g} s, white Gaussian position noise (std per axis), mean ± std over
{seeds} seeds. Default parameters of `METHODS` unless given in the row name.
Causal = the estimate at sample k only uses samples 0..k.

{acc_table}

{pnd_note}

## Speed

Best of several runs after compilation, end to end from NumPy arrays (the
"kernel only" rows: the jitted kernel alone on device-resident data). The
pure-Python loop (same equations, scalar floats, one channel) is timed on the
first {n_py} samples and scaled linearly to the full sizes; the NumPy loop
runs the same equations over time with arrays over the channels. JAX sees
{ndev} host device(s) (`XLA_FLAGS={os.environ.get("XLA_FLAGS", "")}`); with
more than one, `differentiate` splits wide arrays by channel across them.
First batch call including compilation: {t_bat_first:.2f} s. Max deviation
between the implementations on the full 5200-sample channel: {max_dev:.1e}.

Why one signal stays far from the Python loop's 100x: the recursion is
sequential in time, so a 3-channel signal is 5200 dependent steps of a few
dozen flops and four transcendental functions; XLA:CPU executes the loop
body as ~14 small fused kernels per step (~0.5-0.9 us per step on this
machine), which bounds the speed-up over a scalar Python loop (~7.5 us per
3-channel step) to the order of 10x (the ratio below varies between runs with
the speed of both sides). The output blocking of
`cdprid.signal._differentiators.scan_blocked` keeps the body on XLA's sequential
executor path: kernel alone on this signal, timed interleaved (best of 20),
{t_blk * 1e3:.2f} ms with output blocks of {_block_size(3)} steps vs
{t_plain * 1e3:.2f} ms for the plain scan ({t_blk / 5200 * 1e9:.0f} vs
{t_plain / 5200 * 1e9:.0f} ns per step).

{speed_table}
"""
    print()
    print(md)
    if args.out is None:
        return
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write(md)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
