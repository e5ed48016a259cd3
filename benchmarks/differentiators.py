"""Benchmark of cdprid.differentiators: accuracy on a noisy circle and speed.

Usage::

    .venv/bin/python benchmarks/differentiators.py [--quick] [--no-pynumdiff]

Accuracy: 3-D acceleration RMSE over t >= 2 s of a circle (R = 0.3 m,
0.25 Hz, sampled at 100 Hz for 52 s) with white Gaussian position noise of
0.1, 0.2, 0.5 and 1 mm, 5 seeds, every method of ``METHODS`` (plus a tuned
SIHD-2 cascade and, if ``pynumdiff`` imports, its auto-tuned methods).
Speed: SIHD-2 cascade throughput for one 5200x3 signal and a batch of
1000 x (5200x3) signals, against a pure-Python loop of the same equations and
scipy filtfilt.  Prints a table and writes ``results/differentiators.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time
import warnings

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
from scipy import signal  # noqa: E402

from cdprid.differentiators import METHODS, differentiate  # noqa: E402

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
# pure-Python SIHD-2 cascade (same equations as cdprid.differentiators)
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
    ap.add_argument("--out", default="results/differentiators.md")
    args = ap.parse_args(argv)
    seeds = 2 if args.quick else 5
    n_batch = 100 if args.quick else 1000
    command = " ".join([os.path.basename(sys.executable), *sys.argv])

    t, pos, acc = circle()
    mask = t >= 2.0

    # ---------------- accuracy ----------------
    entries = [(m, info.causal, {}) for m, info in METHODS.items()]
    entries.insert(1, ("sihd2-cascade", True, TUNED_CASCADE))
    rows = []
    for m, causal, kw in entries:
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
    if not args.no_pynumdiff:
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

    differentiate(one, DT)  # compile
    t_one = best_time(lambda: differentiate(one, DT), 5)
    t0 = time.perf_counter()
    differentiate(batch2d, DT)  # compile + first run
    t_bat_first = time.perf_counter() - t0
    t_bat = best_time(lambda: differentiate(batch2d, DT), 2)
    n_py = 520
    t_py_piece = best_time(lambda: cascade_python(one[:n_py, 0].tolist(), DT), 3)
    t_py_one = t_py_piece * n_one / n_py
    t_py_bat = t_py_piece * n_bat / n_py
    b, a = signal.butter(2, 4.0, fs=1 / DT)
    t_ff_one = best_time(lambda: signal.filtfilt(b, a, one, axis=0), 20)
    t_ff_bat = best_time(lambda: signal.filtfilt(b, a, batch2d, axis=0), 2)
    # consistency of the timed implementations
    d1_py, d2_py = cascade_python(one[:, 0].tolist(), DT)
    d1_j, d2_j = differentiate(one[:, 0], DT)
    max_dev = float(max(np.max(np.abs(d1_j - d1_py)), np.max(np.abs(d2_j - d2_py))))

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
        "| case | SIHD-2 cascade (JAX scan, jit) | pure-Python loop (scaled) "
        "| scipy filtfilt (4 Hz, order 2) | JAX / Python | JAX / filtfilt |",
        "|---|---:|---:|---:|---:|---:|",
        f"| one 5200x3 signal | {t_one * 1e3:.2f} ms ({thr(n_one, t_one)}) | "
        f"{t_py_one * 1e3:.0f} ms ({thr(n_one, t_py_one)}) | {t_ff_one * 1e3:.2f} ms | "
        f"{t_py_one / t_one:.0f}x faster | {t_one / t_ff_one:.1f}x the time |",
        f"| batch {n_batch} x (5200x3) | {t_bat:.2f} s ({thr(n_bat, t_bat)}) | "
        f"{t_py_bat:.0f} s ({thr(n_bat, t_py_bat)}) | {t_ff_bat:.2f} s | "
        f"{t_py_bat / t_bat:.0f}x faster | {t_bat / t_ff_bat:.1f}x the time |",
    ]
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

Best of several runs after compilation. The pure-Python loop (same
equations, one channel) is timed on the first {n_py} samples and scaled
linearly to the full sizes. First batch call including compilation:
{t_bat_first:.2f} s. Max |JAX - Python| on the full 5200-sample channel:
{max_dev:.1e}.

{speed_table}
"""
    print()
    print(md)
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write(md)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
