"""Benchmark: safe excitation designs vs the gentle initial design, the paper's orbit and the
best hand-made orbit, on 4-, 6- and 8-cable robots with tight spec-1.1 limits.

Writes ``results/excitation.md`` and ``results/excitation_<robot>_<family>.png`` (the safety
time series of each optimised design). Run from the repository root::

    .venv/bin/python -m benchmarks.excitation [--mc 3] [--starts 3] [--cases robot:family,...]

Robots (:mod:`cdprid.model._robots`, no ../shared needed): ``four-point`` (4 cables, point mass),
``six-tight`` (6 cables, the issue's 0.8 x 0.7 x 0.45 m workspace, 1 m/s), ``small-8`` (8 cables,
small workspace, tight limits, body box) and the CRAFT-like robot (robot.toml gives no spec 1.1
limits: the stated defaults apply).

Per case: the gentle first run (the default initial design: the paper's orbit scaled so that
every peak is at most 50 % of its limit), the paper's orbit unscaled, for the orbit family the
best hand-made orbit (a grid of horizontal and vertical orbits, each scaled to 92 % of the
limits, the certified one with the lowest cond), and the optimised design. Reported: cond(W_ID)
on the 100 Hz grid, the predicted std of the worst-determined parameter (largest predicted std
relative to its scale, at sigma_rho = 1 N), a Monte-Carlo identification through the full
pipeline (simulate with its default pose and tension noise -> euler-filtfilt differentiator ->
least squares): RMS error of that parameter, the safety checks, and the optimiser's time
(including the JIT compilation: a fresh process without the persistent cache).
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

import cdprid.excitation as ex  # noqa: E402
from cdprid.excitation import safety_series  # noqa: E402
from cdprid.model import (  # noqa: E402
    CRAFT_LIKE,
    FOUR_POINT,
    SIX_TIGHT,
    SMALL_EIGHT,
    robot_from_dict,  # noqa: E402
)
from cdprid.report import plot_safety_series  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

SMALL8 = SMALL_EIGHT  # the sample robot of cdprid.model._robots (also used by the tests)
SPEED: list = []  # (case, goal s, optimiser s incl. JIT, starts, whole call s)
SUMMARY: list = []  # one row per case


def hand_made_orbits(prob):
    """Certified hand-made orbits: (cond, report, description) sorted by cond.

    A grid of horizontal and vertical orbits about the workspace centre (radius 50, 75, 100 %
    of the room), each at the highest frequency whose steady acceleration and jerk are within
    92 % of the limits, then scaled down (:func:`cdprid.excitation.fit_to_limits`) until every
    peak of the whole trajectory (ramps and home moves included) is within 92 % of its limit.
    """
    fam = prob.family
    lim = prob.limits
    base = fam.initial_params(prob.robot)
    lo, hi = np.asarray(lim.workspace_min), np.asarray(lim.workspace_max)
    half = 0.5 * (hi - lo) - 0.03
    out = []
    for plane, (az, tilt), rmax in (("horizontal", (0.0, 0.0), min(half[0], half[1])),
                                    ("vertical xz", (0.0, np.pi / 2), min(half[0], half[2]))):
        for frac in (0.5, 0.75, 1.0):
            r = min(frac * rmax, fam.radius_max)
            w = min(np.sqrt(0.92 * lim.acceleration_max / r), np.cbrt(0.92 * lim.jerk_max / r))
            f = min(w / (2 * np.pi), fam.freq_max * 0.999)
            p = dict(base, radius=np.array([r]), frequency=np.array([f]),
                     azimuth=np.array([az]), tilt=np.array([tilt]))
            p, k = ex.fit_to_limits(prob, p, prob.fractions.kinematic)
            rep = ex.evaluate_design(prob, fam.from_params(p))
            if rep.certified:
                out.append((rep.cond, rep, f"{plane}, r = {float(p['radius'][0]):.3f} m, "
                            f"f = {f:.3f} Hz"))
    return sorted(out, key=lambda x: x[0])


def worst_parameter(prob, rep):
    """The parameter with the largest predicted std relative to its scale: |m| for the mass,
    max(|x|, 1 cm x m) for a first moment, max(|x|, 1e-3 m^2 x m) for an inertia entry (a
    relative std of a parameter whose nominal value is 0 means nothing)."""
    x = np.asarray(prob.nominal.vector(prob.model))
    m = abs(float(x[0]))
    floors = [0.0, 0.01 * m, 0.01 * m, 0.01 * m] + [1e-3 * m] * 6
    rel = {n: rep.sigma[n] / max(abs(v), fl)
           for n, v, fl in zip(prob.names, x, floors[: len(x)], strict=True)}
    return max(rel, key=rel.get)


def mc_pipeline(prob, rep, n_runs, seed):
    """RMS errors (p,) of n_runs simulate -> differentiate -> identify runs (true = nominal)."""
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset
    from cdprid.simulation import simulate, write_simulation

    traj = prob.homed(jnp.asarray(rep.z))
    x_true = np.asarray(prob.nominal.vector(prob.model))
    errs = []
    for k in range(n_runs):
        with tempfile.TemporaryDirectory() as d:
            sim = simulate(prob.robot, traj, params=prob.nominal, seed=seed + k)
            write_simulation(sim, Path(d) / "ds")
            res = identify_dataset(read_dataset(Path(d) / "ds"), model=prob.model)
        errs.append(np.asarray(res.result.x) - x_true)
    return np.sqrt(np.mean(np.array(errs) ** 2, axis=0))


def run_case(robot, family, args, out, L):
    prob = ex.make_problem(robot, family, "cond")
    t0 = time.perf_counter()
    res = ex.optimise_excitation(prob, n_starts=args.starts, seed=args.seed, progress=True)
    t_call = time.perf_counter() - t0
    ini, opt = res.initial, res.optimised
    paper = ex.evaluate_design(prob, prob.family.from_params(prob.family.initial_params(robot)))
    designs = [("gentle first run (initial)", ini, res.initial_rule.split(":")[0]),
               ("paper's orbit, unscaled", paper, "" if paper.certified else
                "NOT certified: " + "; ".join(paper.certificate.failed))]
    if family == "orbit":
        hm = hand_made_orbits(prob)
        if hm:
            designs.append(("best hand-made orbit", hm[0][1], hm[0][2]))
        else:
            designs.append(("best hand-made orbit", None, "none of the grid is certified"))
    designs.append(("optimised", opt, res.note))
    designs = [d for d in designs if d[1] is not None]
    # reference: the best hand-made orbit when there is one, else the gentle initial design
    ref_name = "best hand-made orbit" if any(d[0] == "best hand-made orbit" for d in designs) \
        else designs[0][0]
    worst = worst_parameter(prob, dict((d[0], d[1]) for d in designs)[ref_name])
    names = list(prob.names)
    j = names.index(worst)
    tr = res.trajectory
    t = np.arange(int(np.floor(tr.t_end * 100.0 + 1e-9)) + 1) / 100.0
    fig = out / f"excitation_{robot.name}_{family}.png"
    ser = safety_series(robot, tr.evaluate(t), prob.limits, prob.box)
    plot_safety_series(ser, prob.limits, fig, title=f"{robot.name}, {family}: optimised design")
    L.append(f"## {robot.name}, family `{family}` (model `{prob.model}`)\n")
    L.append(f"Limits: {prob.limits.as_json()}; uncertainty {prob.box.source} "
             f"({prob.box.description['n_corners']} corners); defaults used: "
             f"{list(prob.limits.defaults_used) + prob.box.description['defaults_used']}.\n")
    L.append(f"Worst-determined parameter (of the reference design): `{worst}` "
             f"(nominal {float(prob.nominal.vector(prob.model)[j]):.4g}).\n")
    L.append("| design | cond(W_ID) | predicted std of worst (sigma_rho = 1 N) | MC RMS error of "
             f"worst ({args.mc} runs, full pipeline) | robust tension margin (N) | peak acc "
             "(m/s^2) | peak jerk (m/s^3) | peak tilt (rad) | certified | notes |")
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    rows = {}
    for name, r, note in designs:
        rms = (mc_pipeline(prob, r, args.mc, args.seed) if args.mc > 0 and "unscaled" not in name
               else np.full(len(names), np.nan))
        rows[name] = (r, rms)
        pk = r.certificate.peaks
        L.append(f"| {name} | {r.cond:.3f} | {r.sigma[worst]:.4g} | {rms[j]:.4g} | "
                 f"{r.min_tension_margin_N:.2f} | {pk['acceleration_m_s2']:.3f} | "
                 f"{pk['jerk_m_s3']:.3f} | {pk['tilt_rad']:.3f} | {r.certified} | {note} |")
    ref, ref_rms = rows[ref_name]
    L.append(f"\nRatios {ref_name} / optimised: cond **{ref.cond / opt.cond:.2f}x**, predicted std "
             f"of `{worst}` **{ref.sigma[worst] / opt.sigma[worst]:.2f}x**, Monte-Carlo RMS error "
             f"**{ref_rms[j] / rows['optimised'][1][j]:.2f}x**. Initial (gentle) / optimised: "
             f"cond **{ini.cond / opt.cond:.2f}x**, predicted std of `{worst}` "
             f"**{ini.sigma[worst] / opt.sigma[worst]:.2f}x**.\n")
    cert = opt.certificate
    SUMMARY.append(
        f"| {robot.name} | {robot.n_cables} | {family} ({prob.model}) | {ini.cond:.2f} -> "
        f"{opt.cond:.2f} | **{ini.cond / opt.cond:.2f}x** | `{worst}` {ini.sigma[worst]:.3g} -> "
        f"{opt.sigma[worst]:.3g} | {len(cert.failed)} | "
        f"{int(np.sum(np.any(ser.margin < 0, axis=0)))} ({cert.n_corners}) | "
        f"{cert.robust_margin_N:.2f} |")
    if prob.model == "translation":
        g = float(np.linalg.norm(np.asarray(robot.gravity)))
        a = prob.limits.acceleration_max
        floor92 = np.sqrt(1 + g * g / (0.92 * a) ** 2)
        L.append(f"Physical floor for the translation model: any rest-to-rest trajectory with "
                 f"|a| <= {a:g} m/s^2 has cond(W_ID) >= sqrt(1 + g^2 / a_max^2) = "
                 f"**{np.sqrt(1 + g * g / (a * a)):.2f}** ({floor92:.2f}"
                 f" at the optimiser's 92 % of the limit): the optimised design is "
                 f"{opt.cond / np.sqrt(1 + g * g / (a * a)):.2f}x this floor.\n")
    SPEED.append((f"{robot.name} {family}", 30.0 if family != "fourier" else 90.0,
                  res.optimiser_time_s, res.starts, t_call))
    L.append(f"Optimiser time (BFGS, {args.starts} starts, including JIT): "
             f"**{res.optimiser_time_s:.1f} s**; whole call with the exact certificates: "
             f"{t_call:.1f} s. Per start: " + "; ".join(
                 f"{s['start']}: {s['steps']} steps, {s['status']}" for s in res.starts) + ".\n")
    L.append("Optimised parameters: " + ", ".join(
        f"{k} = {np.array2string(np.asarray(v), precision=3)}" for k, v in opt.params.items())
        + f". Figure: `results/{fig.name}`.\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=4)
    ap.add_argument("--mc", type=int, default=8, help="full-pipeline Monte-Carlo runs per design")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", default="four-point:orbit,six-tight:orbit,small-8:orbit,"
                    "craft-like:orbit,six-tight:fourier,small-8:fourier,craft-like:fourier")
    ap.add_argument("--speed", action="store_true",
                    help="optimiser speed only (no Monte Carlo, no hand-made grid): writes "
                    "results/excitation_speed.md")
    args = ap.parse_args(argv)
    robots = {"four-point": robot_from_dict(FOUR_POINT, "four-point"),
              "six-tight": robot_from_dict(SIX_TIGHT, "six-tight"),
              "small-8": robot_from_dict(SMALL8, "small-8"),
              "craft-like": robot_from_dict(CRAFT_LIKE, "craft-like")}
    out = ROOT / "results"
    out.mkdir(exist_ok=True)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                                capture_output=True, text=True, check=True).stdout.strip()
    except Exception:  # noqa: BLE001
        commit = "unknown"
    cmd = "python -m benchmarks.excitation " + " ".join(argv if argv is not None else sys.argv[1:])
    if args.speed:
        return speed_only(robots, args, out, cmd, commit)
    L = ["# Safe excitation design\n"]
    load0 = os.getloadavg()
    body = []
    for case in args.cases.split(","):
        name, family = case.split(":")
        run_case(robots[name], family, args, out, body)
        write(out, L, body, cmd, commit, load0)
    print("\n".join(write(out, L, body, cmd, commit, load0)))
    return 0


def speed_only(robots, args, out, cmd, commit) -> int:
    """Optimiser time per case, each in a fresh compilation (results/excitation_speed.md)."""
    rows = []
    for case in args.cases.split(","):
        name, family = case.split(":")
        prob = ex.make_problem(robots[name], family, "cond")
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        res = ex.optimise_excitation(prob, n_starts=args.starts, seed=args.seed, progress=True)
        t_call = time.perf_counter() - t0
        st = res.starts
        rest = [x["time_s"] for x in st[1:]]
        rows.append(f"| {name} {family} | {90 if family == 'fourier' else 30} | "
                    f"**{res.optimiser_time_s:.1f}** | {st[0]['time_s']:.1f} | "
                    + (f"{np.mean(rest):.1f}" if rest else "-")
                    + f" | {', '.join(str(x['steps']) for x in st)} | {t_call:.1f} | "
                    f"{load:.1f} | {res.initial.cond / res.optimised.cond:.2f}x |")
        L = ["# Excitation optimiser speed\n",
             f"Generated by `{cmd.strip()}` at commit `{commit}` on {platform.node() or 'host'} "
             f"({os.cpu_count()} cores, jax {jax.__version__}). Each case in the same process, "
             "its own compilation (no persistent cache); the machine is shared with other "
             "jobs (load average at the start of each case in the table, 2 cores).\n",
             f"| case | goal (s) | optimiser incl. JIT, {args.starts} starts (s) | first start "
             "incl. compile (s) | other starts (s each) | BFGS steps per start | whole call "
             "with certificates (s) | load | cond initial / optimised |",
             "|---|---|---|---|---|---|---|---|---|"] + rows
        (out / "excitation_speed.md").write_text("\n".join(L) + "\n")
    print((out / "excitation_speed.md").read_text())
    return 0


def write(out, L, body, cmd, commit, load0):
    """Write results/excitation.md with the cases done so far."""
    load1 = os.getloadavg()
    L = list(L)
    L.append("## Summary\n")
    L.append("Initial design = the gentle first run (`cdprid.excitation.initial_design`: the "
             "paper's orbit, 0.4 m at 0.25 Hz about the workspace centre, radius fitted to the "
             "workspace, amplitude scaled so that every peak is at most 50 % of its limit). "
             "Worst parameter = largest predicted std relative to its scale (sigma_rho = 1 N). "
             "Checks: every limit on a 500 Hz grid, clearances and tensions at every point of "
             "the uncertainty hull on the 100 Hz grid of the CSV (exact; LP).\n")
    L.append("| robot | cables | family (model) | cond initial -> optimised | ratio | worst "
             "parameter: predicted std initial -> optimised | violated limits | infeasible "
             "samples at any corner (corners) | robust margin (N) |")
    L.append("|---|---|---|---|---|---|---|---|---|")
    L += SUMMARY
    L.append("\n## Speed (optimiser, including JIT; fresh process, no persistent cache)\n")
    L.append("| case | goal (s) | optimiser incl. JIT (s) | first start incl. compile (s) | "
             "other starts (s each) | whole call with certificates (s) |")
    L.append("|---|---|---|---|---|---|")
    for case, goal, t_opt, starts, t_call in SPEED:
        rest = [st["time_s"] for st in starts[1:]]
        L.append(f"| {case} | {goal:g} | **{t_opt:.1f}** | {starts[0]['time_s']:.1f} | "
                 + (f"{np.mean(rest):.1f}" if rest else "-") + f" | {t_call:.1f} |")
    L.append("")
    L.append(f"Generated by `{cmd.strip()}` at commit `{commit}` on {platform.node() or 'host'} "
             f"({os.cpu_count()} cores, Python {platform.python_version()}, jax "
             f"{jax.__version__}). The machine was SHARED with other jobs while this ran (load "
             f"average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end, on 2 cores): "
             "times are upper bounds of what a quiet machine gives.\n")
    L += body
    (out / "excitation.md").write_text("\n".join(L) + "\n")
    return L


if __name__ == "__main__":
    sys.exit(main())
