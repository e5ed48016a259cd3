"""Benchmark of cdprid.tuning: paper gains vs tuned SIHD vs tuned baselines.

Usage::

    .venv/bin/python benchmarks/tuning.py [--quick]

For each noise level (0.1, 0.2, 0.5, 1 mm) the SIHD methods are tuned by BFGS
through the scan on 4 noise seeds of the benchmark circle (R 0.3 m, 0.25 Hz,
100 Hz, 52 s) and the baselines by grid search on the same seeds; everything
is evaluated on 5 held-out seeds, on two other trajectories (generalisation)
and through the 4-parameter least squares on simulated tensions.  Writes
``results/tuning.md`` and ``results/tuning_*.png``.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time

import jax

jax.config.update("jax_enable_x64", True)

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from cdprid import tuning as T  # noqa: E402

NOISES_MM = (0.1, 0.2, 0.5, 1.0)
TRAIN, TEST = range(4), range(100, 105)
CAUSAL = {"sihd2-cascade": True, "sihd3": True, "sihd4": True, "sihd5": True,
          "euler-filtfilt": False, "euler-butter-causal": True, "savgol": False,
          "kalman": True, "rts": False}


def param_errors(pp, method, params, signal, noise, seeds):
    """RMS scaled parameter error (%) of the 4-parameter LS over seeds."""
    nz = T.noise_realisations(signal.t.size, seeds)
    Y = np.transpose(signal.position[None] + noise * nz, (1, 0, 2)).reshape(signal.t.size, -1)
    _, A = T.any_differentiate(Y, signal.dt, method, **params)
    A = A.reshape(signal.t.size, len(seeds), 3)
    e = np.asarray(pp.rel_error(A, signal.mask))
    return 100 * float(np.sqrt(np.mean(e)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only 0.5 mm")
    ap.add_argument("--outdir", default="results")
    args = ap.parse_args(argv)
    noises = (0.5,) if args.quick else NOISES_MM
    os.makedirs(args.outdir, exist_ok=True)
    circ = T.circle_signal()
    others = [T.lissajous_signal(), T.circle_signal(0.2, 0.5)]
    try:
        pp = T.ParamProblem(circ, TEST)
    except Exception as exc:  # noqa: BLE001
        pp = None
        print(f"parameter-error evaluation skipped: {exc}", file=sys.stderr)
    rows = {}
    timing = {}
    t_all = time.perf_counter()
    for nmm in noises:
        s = nmm * 1e-3
        entries = [("paper gains (sihd2-cascade)", "sihd2-cascade", dict(T.PAPER_PARAMS), None)]
        for m in ("sihd2-cascade", "sihd3", "sihd5"):
            r = T.tune(m, s, train_seeds=TRAIN, test_seeds=TEST)
            entries.append((f"{m} tuned", m, r.params, r))
            timing[(m, nmm)] = (r.wall_s, r.cpu_s)
            print(f"{nmm} mm {m}: {r.test_rmse:.4f} ({r.wall_s:.1f} s, {r.cpu_s:.1f} s CPU)",
                  flush=True)
        if nmm == 0.5:
            for m, zm in (("sihd4", None), ("sihd5", 0.5)):
                r = T.tune(m, s, train_seeds=TRAIN, test_seeds=TEST, zeta_min=zm)
                lab = f"{m} tuned" + ("" if zm is None else f" (zeta >= {zm:g})")
                entries.append((lab, m, r.params, r))
                timing[(lab, nmm)] = (r.wall_s, r.cpu_s)
        for b in ("euler-filtfilt", "euler-butter-causal", "savgol", "kalman", "rts"):
            r = T.tune_baseline(b, s, train_seeds=TRAIN, test_seeds=TEST)
            entries.append((f"{b} tuned", b, r.params, r))
            entries.append((f"{b} default", b, T.default_params(b), None))
        for lab, m, p, r in entries:
            tr = r.train_rmse if r else float(np.mean(T.evaluate(m, p, circ, s, TRAIN)))
            te = T.evaluate(m, p, circ, s, TEST)
            gen = [float(np.mean(T.evaluate(m, p, o, s, TEST))) for o in others]
            pe = param_errors(pp, m, p, circ, s, list(TEST)) if pp is not None else float("nan")
            rows[(lab, nmm)] = dict(method=m, params=p, train=tr, test=float(te.mean()),
                                    test_std=float(te.std()), gen=gen, perr=pe)
        print(f"{nmm} mm done", flush=True)
    total = time.perf_counter() - t_all

    # ---------------- lag-noise trade-off figure (0.5 mm) ----------------
    fig, ax = plt.subplots(figsize=(7, 4.2))
    oms = np.geomspace(3, 40, 14)
    for n, name in ((3, "sihd3"), (5, "sihd5")):
        tot, lag = [], []
        for om in oms:
            p = {f"lambda{q}": v for q, v in enumerate(
                np.real(np.poly([om * np.exp(1j * math.pi * (2 * k + n + 1) / (2 * n))
                                 for k in range(n)]))[1:], 1)}
            p.update(alpha=1.0, mu=1.0)
            tot.append(T.evaluate(name, p, circ, 5e-4, range(2)).mean())
            lag.append(T.evaluate(name, p, circ, 1e-12, [0]).mean())
        ax.loglog(oms, tot, "-o", ms=3, label=f"{name} (Butterworth poles), 0.5 mm noise")
        ax.loglog(oms, lag, "--", label=f"{name}: noise-free (lag/bias only)")
    ax.axhline(0.05, color="k", lw=0.8, ls=":", label="goal 0.05 m/s²")
    for lab in ("sihd3 tuned", "sihd5 tuned"):
        if (lab, 0.5) in rows:
            v = rows[(lab, 0.5)]["test"]
            ax.axhline(v, lw=0.8, color="C0" if "3" in lab else "C2", label=f"{lab}: {v:.3f}")
    ax.set_xlabel("bandwidth ω of the linear part (rad/s)")
    ax.set_ylabel("acceleration RMSE (m/s²)")
    ax.set_title("Lag-noise trade-off, circle 0.25 Hz, α = 1")
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(os.path.join(args.outdir, "tuning_tradeoff.png"), dpi=120)
    plt.close(fig)

    # ---------------- time series (0.5 mm) ----------------
    y = circ.position + 5e-4 * np.random.default_rng(100).standard_normal(circ.position.shape)
    fig, ax = plt.subplots(figsize=(8, 3.6))
    k = (circ.t >= 40) & (circ.t <= 46)
    ax.plot(circ.t[k], circ.acceleration[k, 0], "k", lw=2, label="true")
    for lab in ("paper gains (sihd2-cascade)", "sihd3 tuned", "sihd5 tuned", "kalman tuned"):
        if (lab, 0.5) in rows:
            r = rows[(lab, 0.5)]
            _, a = T.any_differentiate(y, circ.dt, r["method"], **r["params"])
            ax.plot(circ.t[k], a[k, 0], lw=1, label=lab)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("a_x (m/s²)")
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(args.outdir, "tuning_timeseries.png"), dpi=120)
    plt.close(fig)

    # ---------------- markdown ----------------
    labels = list(dict.fromkeys(lab for lab, _ in rows))
    L = ["# Differentiator tuning", "",
         f"Command: `python {' '.join(sys.argv)}`  ",
         f"Machine: {platform.platform()}, Python {platform.python_version()}, "
         f"{os.cpu_count()} CPUs (shared, loaded), jax {jax.__version__}  ",
         f"Date: {time.strftime('%Y-%m-%d %H:%M:%S')}; whole benchmark {total:.0f} s wall", "",
         "Training: circle R 0.3 m, 0.25 Hz, 100 Hz, 52 s, noise seeds 0-3; SIHD methods by "
         "optimistix BFGS through the scan (log gains / Hurwitz root parameters, sigmoid alpha), "
         "baselines by log-grid + golden section on the same seeds. Test: 5 held-out seeds "
         "(100-104). 3-D acceleration RMSE (m/s²) over t >= 2 s.", ""]
    L += ["## Acceleration RMSE on held-out seeds (mean over 5 seeds)", "",
          "| method | causal | " + " | ".join(f"{n:g} mm" for n in noises) + " |",
          "|---|:-:|" + "---:|" * len(noises)]
    for lab in labels:
        m = next(rows[(lab, n)]["method"] for n in noises if (lab, n) in rows)
        cells = [f"{rows[(lab, n)]['test']:.4f}" if (lab, n) in rows else "" for n in noises]
        L.append(f"| {lab} | {'yes' if CAUSAL[m] else 'no'} | " + " | ".join(cells) + " |")
    L += ["", "## Train vs held-out, generalisation and identified parameters (0.5 mm)", "",
          "Generalisation: parameters tuned on the circle, evaluated on a 3-D Lissajous "
          "(0.2/0.4/0.3 Hz, acceleration larger) and a circle R 0.2 m at 0.5 Hz "
          "(acceleration 1.97 m/s² amplitude). Parameter error: RMS over seeds and over "
          "(m, m s_G) of the error scaled by (m, |m s_G|), 4-parameter LS on simulated tensions "
          "(CRAFT-like robot, 0.5 N tension noise), in %.", "",
          "| method | train RMSE | test RMSE ± std | Lissajous | circle 0.2 m 0.5 Hz "
          "| param. error % |",
          "|---|---:|---:|---:|---:|---:|"]
    if 0.5 in noises:
        for lab in labels:
            if (lab, 0.5) in rows:
                r = rows[(lab, 0.5)]
                L.append(f"| {lab} | {r['train']:.4f} | {r['test']:.4f} ± {r['test_std']:.4f} | "
                         f"{r['gen'][0]:.4f} | {r['gen'][1]:.4f} | {r['perr']:.3f} |")
    L += ["", "## Parameter error (%) at every noise level", "",
          "| method | " + " | ".join(f"{n:g} mm" for n in noises) + " |",
          "|---|" + "---:|" * len(noises)]
    for lab in labels:
        cells = [f"{rows[(lab, n)]['perr']:.3f}" if (lab, n) in rows else "" for n in noises]
        L.append(f"| {lab} | " + " | ".join(cells) + " |")
    L += ["", "## Tuned parameters", ""]
    for n in noises:
        L.append(f"**{n:g} mm**")
        L.append("")
        for lab in labels:
            if (lab, n) in rows and "tuned" in lab:
                p = rows[(lab, n)]["params"]
                L.append(f"- {lab}: `" + ", ".join(f"{k}={v:.5g}" for k, v in p.items()) + "`")
        L.append("")
    L += ["## Tuning time (wall / CPU, s; machine shared with other jobs)", "",
          "| method | " + " | ".join(f"{n:g} mm" for n in noises) + " |",
          "|---|" + "---:|" * len(noises)]
    for key in dict.fromkeys(k for k, _ in timing):
        cells = [f"{timing[(key, n)][0]:.1f} / {timing[(key, n)][1]:.1f}" if (key, n) in timing
                 else "" for n in noises]
        L.append(f"| {key} | " + " | ".join(cells) + " |")
    L += ["", "Figures: `tuning_tradeoff.png` (lag-noise trade-off of SIHD-3 vs SIHD-5), "
          "`tuning_timeseries.png` (x acceleration, 0.5 mm).", ""]
    with open(os.path.join(args.outdir, "tuning.md"), "w") as f:
        f.write("\n".join(L))
    print("\n".join(L))


if __name__ == "__main__":
    main()
