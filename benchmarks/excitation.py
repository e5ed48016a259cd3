"""Benchmark: paper-like orbit vs optimised excitation trajectory for the CRAFT-like robot.

Writes ``results/excitation.md`` and ``results/excitation_trajectory.png``,
``results/excitation_mc.png``. Reads the robot from
``../shared/datasets/craft-sim-orbits/robot.toml`` (exits with a clear message if absent).

Run from the repository root::

    .venv/bin/python benchmarks/excitation.py [--family orbit] [--mc 200] [--slsqp-starts 4]

Monte Carlo (cheap, no differentiator): along each design at 100 Hz, the true tensions are
the certified-feasible centred least-norm distribution for the nominal platform; each run adds
N(0, 0.5 N) to every tension and N(0, sigma_a) to every acceleration component (the residual
error of a differentiator), stacks W_ID / Y_ID and identifies with
:func:`cdprid.identification.least_squares`. A full simulate -> differentiate -> identify run
per design (:func:`cdprid.simulate.simulate`, :func:`cdprid.pipeline.identify_dataset`) is
reported beside it.
"""

from __future__ import annotations

import argparse
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

from cdprid import excitation as ex  # noqa: E402
from cdprid.cli_excite import plot_trajectory  # noqa: E402
from cdprid.geometry import load_robot  # noqa: E402
from cdprid.identification import least_squares  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROBOT = ROOT.parent / "shared" / "datasets" / "craft-sim-orbits" / "robot.toml"


def monte_carlo(prob, z, n_runs, seed, sigma_tau=0.5, sigma_a=0.05):
    """RMS parameter errors (p,) and mean LS-predicted std (p,) over n_runs noisy identifications."""
    t = jnp.asarray(prob.grid(100.0))
    states = prob.family.states(jnp.asarray(z), t)
    Wm, w = ex._required_wrench(prob.robot, prob.nominal, states, prob.pulleys)
    Wm, w = np.asarray(Wm), np.asarray(w)
    mid = 0.5 * (prob.tmin + prob.tmax)
    tau = mid + np.einsum("nim,ni->nm", Wm, np.linalg.solve(Wm @ Wm.transpose(0, 2, 1),
                                                             (w - Wm.sum(axis=2) * mid)[..., None])[..., 0])
    x_true = np.asarray(prob.nominal.vector(prob.model))
    a = np.asarray(states.a)
    from cdprid.dynamics import regressor_translation

    reg = jax.jit(jax.vmap(lambda acc: regressor_translation(jnp.eye(3), acc, prob.robot.gravity)))
    key = jax.random.PRNGKey(seed)
    errs, stds = [], []
    for _ in range(n_runs):
        key, k1, k2 = jax.random.split(key, 3)
        tau_m = tau + sigma_tau * np.asarray(jax.random.normal(k1, tau.shape))
        a_m = a + sigma_a * np.asarray(jax.random.normal(k2, a.shape))
        Y = np.einsum("nim,nm->ni", Wm, tau_m).reshape(-1)
        W_ID = np.asarray(reg(jnp.asarray(a_m))).reshape(-1, 4)
        r = least_squares(W_ID, Y, prob.names)
        errs.append(r.x - x_true)
        stds.append(r.std)
    errs = np.array(errs)
    return np.sqrt(np.mean(errs**2, axis=0)), np.mean(np.array(stds), axis=0), x_true


def full_pipeline(prob, traj, seed):
    """One simulate -> write -> read -> identify run; returns the identified x (or None)."""
    try:
        from cdprid.io import read_dataset
        from cdprid.pipeline import identify_dataset
        from cdprid.simulate import simulate, write_simulation
    except ImportError:
        return None
    with tempfile.TemporaryDirectory() as d:
        sim = simulate(prob.robot, traj, seed=seed)
        write_simulation(sim, Path(d) / "ds")
        rep = identify_dataset(read_dataset(Path(d) / "ds"), model=prob.model)
    return np.asarray(rep.result.x)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--family", default="orbit", choices=list(ex.FAMILIES[:2]))
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--slsqp-starts", type=int, default=4)
    ap.add_argument("--mc", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if not ROBOT.is_file():
        print(f"benchmarks/excitation.py: {ROBOT} is not present (../shared is provided beside "
              "the repository); nothing to do.", file=sys.stderr)
        return 2
    robot = load_robot(ROBOT)
    prob = ex.make_problem(robot, args.family, "cond", duration=args.duration)

    t0 = time.perf_counter()
    res = ex.optimise_excitation(prob, n_starts=args.starts, seed=args.seed, progress=True)
    t_ours = time.perf_counter() - t0
    # the same call again: compiled functions are cached, so this times the solves without JIT
    res2 = ex.optimise_excitation(prob, n_starts=args.starts, seed=args.seed, progress=False)
    t_nojit = res2.optimiser_time_s
    ini, opt = res.initial, res.optimised

    # SLSQP baseline with finite differences from the same starts (jit-compiled objective)
    starts = ex.start_points(prob, max(args.starts, args.slsqp_starts), args.seed)[: args.slsqp_starts]
    sl = []
    for i, z0 in enumerate(starts):
        r = ex.slsqp_baseline(prob, z0)
        rep = ex.evaluate_design(prob, r["z"])
        sl.append((r, rep))
        print(f"slsqp start {i + 1}: objective {r['objective']:.4f}, cond {rep.cond:.3f}, "
              f"certified {rep.certified}, {r['nfev']} evaluations, {r['time_s']:.1f} s",
              file=sys.stderr)
    sl_time = sum(r["time_s"] for r, _ in sl)
    sl_cert = [(r, rep) for r, rep in sl if rep.certified]
    sl_best = min(sl_cert or sl, key=lambda x: x[1].objective)

    # Monte Carlo and one full-pipeline run per design
    mc = {}
    for name, rep in (("initial", ini), ("optimised", opt)):
        rms, std, x_true = monte_carlo(prob, rep.z, args.mc, args.seed)
        full = full_pipeline(prob, prob.family.trajectory(jnp.asarray(rep.z)), args.seed)
        mc[name] = (rms, std, full)

    # figures
    out = ROOT / "results"
    out.mkdir(exist_ok=True)
    plot_trajectory(robot, res.trajectory, out / "excitation_trajectory.png",
                    initial=prob.family.trajectory(jnp.asarray(ini.z)),
                    title=f"{prob.family.name}: cond {ini.cond:.2f} -> {opt.cond:.2f}")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    names = list(prob.names)
    xs = np.arange(len(names))
    for k, name in enumerate(("initial", "optimised")):
        ax.bar(xs + (k - 0.5) * 0.38, 100 * mc[name][0] / np.abs(x_true), 0.38, label=name)
    ax.set_xticks(xs, names)
    ax.set_yscale("log")
    ax.set_ylabel("MC RMS error (% of |x|)")
    ax.set_title(f"{args.mc} noisy identifications per design")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "excitation_mc.png", dpi=110)
    plt.close(fig)

    # report
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True, check=True).stdout.strip()
    except Exception:  # noqa: BLE001
        commit = "unknown"
    cmd = "python benchmarks/excitation.py " + " ".join(argv if argv is not None else sys.argv[1:])
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    L = []
    L.append("# Excitation design: paper-like orbit vs optimised\n")
    L.append(f"Generated by `{cmd.strip()}` at commit `{commit}` on {platform.node() or 'host'} "
             f"({platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
             f"{load[0]:.1f} during the run, Python {platform.python_version()}, jax {jax.__version__}).\n")
    L.append(f"Robot: `{ROBOT.name}` of craft-sim-orbits (CRAFT-like, 8 cables); family "
             f"`{prob.family.name}` ({prob.family.n_params} parameters, {prob.family.duration:g} s), "
             f"model `{prob.model}`, objective smooth log cond(W_ID) with penalties; W_ID from the "
             "trajectory's analytic accelerations at 100 Hz. Tension limits "
             f"{prob.tmin:g}-{prob.tmax:g} N, cable speed <= {prob.speed_max:g} m/s, workspace box of robot.toml.\n")
    L.append("## Designs\n")
    L.append("| | cond(W_ID) | cond scaled | min tension margin (LP, N) | max cable speed (m/s) | certified |")
    L.append("|---|---|---|---|---|---|")
    for name, r in (("paper-like orbit (initial)", ini), ("optimised (BFGS, multi-start)", opt),
                    ("SLSQP + finite differences (best)", sl_best[1])):
        L.append(f"| {name} | {r.cond:.3f} | {r.cond_scaled:.4f} | {r.min_tension_margin_N:.2f} | "
                 f"{r.max_cable_speed:.2f} | {r.certified} |")
    L.append(f"\ncond ratio initial/optimised: **{ini.cond / opt.cond:.2f}x**.\n")
    L.append("Optimised parameters: " + ", ".join(
        f"{k} = {np.array2string(np.asarray(v), precision=3)}" for k, v in opt.params.items()) + "\n")
    if res.note:
        L.append(f"Note: {res.note}\n")
    L.append("## Predicted and Monte-Carlo parameter errors\n")
    L.append(f"Predicted sigma at sigma_rho = {prob.sigma_rho:g} N per row (eq. 20). Monte Carlo: "
             f"{args.mc} runs per design, tension noise 0.5 N, acceleration noise 0.05 m/s^2, "
             "ordinary least squares; `LS std` is the mean of eq. (20) with the estimated sigma_rho. "
             "`full pipeline` is one simulate (default sensor noise) -> euler-filtfilt -> identify run.\n")
    L.append("| parameter | nominal | pred. rel. sigma initial | pred. rel. sigma optimised | ratio | MC RMS err initial | MC RMS err optimised | ratio | LS std initial | LS std optimised | full pipeline err initial | full pipeline err optimised |")
    L.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for j, n in enumerate(names):
        fi, fo = mc["initial"][2], mc["optimised"][2]
        fe = ("n/a", "n/a") if fi is None else (f"{fi[j] - x_true[j]:+.4g}", f"{fo[j] - x_true[j]:+.4g}")
        L.append(f"| {n} | {x_true[j]:.4g} | {100 * ini.rel_sigma[n]:.3g} % | {100 * opt.rel_sigma[n]:.3g} % | "
                 f"{ini.rel_sigma[n] / opt.rel_sigma[n]:.1f}x | {mc['initial'][0][j]:.3g} | {mc['optimised'][0][j]:.3g} | "
                 f"{mc['initial'][0][j] / mc['optimised'][0][j]:.1f}x | {mc['initial'][1][j]:.3g} | "
                 f"{mc['optimised'][1][j]:.3g} | {fe[0]} | {fe[1]} |")
    L.append("\n## Optimiser time\n")
    L.append("| optimiser | starts | wall time (s) | best objective (smooth log cond) | cond of answer | certified |")
    L.append("|---|---|---|---|---|---|")
    L.append(f"| optimistix BFGS, exact JAX gradients (incl. JIT) | {args.starts} | {res.optimiser_time_s:.1f} | "
             f"{min(s['objective'] for s in res.starts):.4f} | {opt.cond:.3f} | {opt.certified} |")
    L.append(f"| optimistix BFGS, exact JAX gradients (JIT cached, second call) | {args.starts} | {t_nojit:.1f} | "
             f"{min(s['objective'] for s in res2.starts):.4f} | {res2.optimised.cond:.3f} | {res2.optimised.certified} |")
    L.append(f"| scipy SLSQP, finite differences (jit-compiled objective, JIT excluded) | {args.slsqp_starts} | "
             f"{sl_time:.1f} | {sl_best[0]['objective']:.4f} | {sl_best[1].cond:.3f} | {sl_best[1].certified} |")
    L.append(f"\nSpeed-up (SLSQP time / BFGS time): **{sl_time / res.optimiser_time_s:.1f}x** including JIT, "
             f"**{sl_time / t_nojit:.1f}x** with JIT cached. "
             f"Whole `optimise_excitation` call (solves + 100 Hz evaluation + CasADi certificates): {t_ours:.1f} s.")
    L.append("Per start (BFGS): " + "; ".join(
        f"{s['start']}: {s['objective']:.4f} in {s['steps']} steps" for s in res.starts) + ".")
    L.append("Per start (SLSQP): " + "; ".join(
        f"{i + 1}: {r['objective']:.4f}, {r['nfev']} evals, {r['time_s']:.1f} s, {r['message']}"
        for i, (r, _) in enumerate(sl)) + ".\n")
    L.append("Figures: `results/excitation_trajectory.png` (trajectory in the robot), "
             "`results/excitation_mc.png` (Monte-Carlo errors).\n")
    (out / "excitation.md").write_text("\n".join(L) + "\n")
    print("\n".join(L))
    return 0


if __name__ == "__main__":
    sys.exit(main())
