"""Efficiency of identify against the Cramer-Rao bound (issue 24), orientation noise included.

For each robot (six-suspended, eight-redundant, CRAFT-like): ``--reps`` noisy simulations
(rich orbits shortened to 26 s with 3 deg rotations; noise 0.3 mm, 0.3 mrad, 0.5 N; the seed
varies), each identified with several methods (the default: euler-filtfilt with its cutoff
chosen from the data and the errors-in-variables weighting; the same at 4 Hz; the paper's OLS;
eiv at 2 Hz; rts, kalman, sihd3 and the SIHD-2 cascade with eiv; online identification, whose
bound is the batch default's). Reported per parameter: bias (% of the truth where the truth is
not ~0, and in units of the bound), RMSE over the bound (``RMSE / median crb_std``, the bound
being identify's own ``crb_std`` of each recording), the mean reported efficiency
``std / crb_std`` and the RMS z-score of the HAC std.

``--antithetic``: every seed gives two recordings, the second with every noise sample of the
first negated (positions, tensions, the orientation perturbation); the mean of a pair cancels
the estimate's first-order noise term, so the bias (second order) is measured with a standard
error far below the bound's: the only way to tell a 1 % inertia bias from zero when the bound
is tens of % of the inertia. Written to ``results/efficiency-antithetic.md``.

Runs go through :func:`cdprid.run_sweep` (``--workers N`` for a local Dask cluster,
``--jsonl`` to resume). Run: ``python -m benchmarks.efficiency [--reps 16]`` ->
``results/efficiency.md``.
"""

from __future__ import annotations

import argparse
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.diagnosis import positive_int

ROOT = Path(__file__).resolve().parents[1]
METHODS = {
    "euler-filtfilt, cutoff from the data, eiv weighting (default)": ("euler-filtfilt", {}, "eiv"),
    "euler-filtfilt 4 Hz, eiv weighting (the default before)": ("euler-filtfilt",
                                                                {"cutoff_hz": 4.0}, "eiv"),
    "euler-filtfilt 4 Hz, OLS (the paper's)": ("euler-filtfilt", {"cutoff_hz": 4.0}, "none"),
    "euler-filtfilt 2 Hz, eiv weighting": ("euler-filtfilt", {"cutoff_hz": 2.0}, "eiv"),
    "rts, eiv weighting": ("rts", {}, "eiv"),
    "kalman (causal), eiv weighting": ("kalman", {}, "eiv"),
    "sihd3 (causal), eiv weighting": ("sihd3", {}, "eiv"),
    "sihd2-cascade (causal), eiv weighting": ("sihd2-cascade", {}, "eiv"),
    "online (SIHD-2 cascade, recursive LS)": ("online", {}, "none")}
ROBOTS = ("six", "eight", "craft8")


def _case(name):
    from cdprid.model import (
        EIGHT_REDUNDANT,
        SIX_SUSPENDED,
        InertialParameters,
        craft_like_robot,
        craft_like_truth,
        robot_from_dict,
    )

    small = InertialParameters(4.5, np.array([0.01, -0.005, -0.04]),
                               np.diag([0.03, 0.035, 0.05]))
    if name == "six":
        return robot_from_dict(SIX_SUSPENDED, source="six"), small, 25.0
    if name == "eight":
        return robot_from_dict(EIGHT_REDUNDANT, source="eight"), small, 40.0
    return craft_like_robot(), craft_like_truth(), 25.0


def _mirrored(sim, clean):
    """The antithetic twin of the noisy simulation ``sim``: every noise sample negated.

    ``clean`` is the same simulation without noise. Positions, tensions and encoder lengths:
    ``2 clean - noisy``; orientation: the platform-frame perturbation ``dq = q_clean^* q``
    replaced by its inverse, ``q_clean dq^*`` (the noise rotation vector negated).
    """
    import dataclasses

    import jax
    import jax.numpy as jnp

    from cdprid.model import quat_conjugate, quat_multiply

    q = None
    if sim.quaternion is not None:
        qc, qn = jnp.asarray(clean.quaternion), jnp.asarray(sim.quaternion)
        dq = jax.vmap(quat_multiply)(jax.vmap(quat_conjugate)(qc), qn)
        q = np.asarray(jax.vmap(quat_multiply)(qc, jax.vmap(quat_conjugate)(dq)))
        q = q / np.linalg.norm(q, axis=1, keepdims=True)
        q = np.where(q[:, :1] < 0, -q, q)
    lengths = None if sim.lengths is None else 2 * clean.lengths - sim.lengths
    return dataclasses.replace(sim, position=2 * clean.position - sim.position, quaternion=q,
                               tension=2 * clean.tension - sim.tension, lengths=lengths)


def run(spec: dict) -> dict:
    """One recording identified by every method of :data:`METHODS` (``spec["mirror"]``: the
    antithetic twin of the seed's recording)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset
    from cdprid.model import preset
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    robot, truth, tau_ref = _case(spec["robot"])
    traj = preset("rich", robot, duration=spec.get("duration", 26.0),
                  rotation_amplitude=spec.get("rotation_rad", 0.05))
    noise = SensorNoise(position_m=3e-4, tension_N=0.5, orientation_rad=3e-4)
    sim = simulate(robot, traj, truth, noise=noise, seed=spec["seed"], tau_ref=tau_ref)
    if spec.get("mirror"):
        clean = simulate(robot, traj, truth, noise=SensorNoise(0.0, 0.0, 0.0, length_m=0.0),
                         seed=spec["seed"], tau_ref=tau_ref)
        sim = _mirrored(sim, clean)
    out = {"robot": spec["robot"], "seed": spec["seed"], "mirror": bool(spec.get("mirror")),
           "methods": {}}
    with tempfile.TemporaryDirectory() as tmp:
        ds = read_dataset(write_simulation(sim, Path(tmp) / "d"))
        crb = None
        for label in spec.get("methods") or list(METHODS):
            method, params, weighting = METHODS[label]
            if method == "online":
                out["methods"][label] = _online(ds, robot, crb, truth)
                continue
            rep = identify_dataset(ds, differentiator=method, params=params, weighting=weighting)
            crb = crb if rep.crb is None else rep.crb.std.tolist()
            out["methods"][label] = {
                "model": rep.model, "x": rep.result.x.tolist(),
                "std": rep.result.std.tolist(),
                "crb": None if rep.crb is None else rep.crb.std.tolist(),
                "truth": list(map(float, truth.vector(rep.model)))}
    return out


def _online(ds, robot, crb, truth) -> dict:
    """Online identification (full model) of the whole recording: its final estimate and HAC
    std (as ``identify --online --json`` reports it)."""
    from cdprid.core import std_from_cov
    from cdprid.identify import online_identify
    from cdprid.io import align

    res = online_identify(align(ds), robot, model="full")
    return {"model": "full", "x": np.asarray(res.x_final).tolist(),
            "std": std_from_cov(res.hac_cov_final()[0]).tolist(), "crb": crb,
            "truth": list(map(float, truth.vector("full")))}


def _table(recs: list, label: str, names) -> list:
    rows = [r["methods"][label] for r in recs]
    x = np.array([r["x"] for r in rows])
    s = np.array([r["std"] for r in rows])
    t = np.array(rows[0]["truth"])
    crb = np.array([r["crb"] for r in rows if r["crb"] is not None])
    err = x - t
    groups = [slice(0, 1), slice(1, 4), slice(4, 10)]
    scale = np.zeros_like(t)
    for g in groups:
        scale[g] = np.max(np.abs(t[g])) if len(t[g]) else 0.0
    cb = np.median(crb, axis=0)
    out = [f"### {label}", "",
           "| parameter | bias (% of truth) | bias / CRB | RMSE / CRB | mean std / CRB "
           "| RMS z (HAC) |", "|---|---:|---:|---:|---:|---:|"]
    for i, n in enumerate(names[:x.shape[1]]):
        rmse = np.sqrt(np.mean(err[:, i] ** 2))
        b = np.mean(err[:, i])
        pct = f"{100 * b / t[i]:+.2f}" if abs(t[i]) > 0.05 * scale[i] else "-"
        out.append(f"| {n} | {pct} | {b / cb[i]:+.2f} | {rmse / cb[i]:.2f} | "
                   f"{np.mean(s[:, i]) / cb[i]:.2f} | "
                   f"{np.sqrt(np.mean((err[:, i] / s[:, i]) ** 2)):.2f} |")
    ratio = [np.sqrt(np.mean(err[:, i] ** 2)) / cb[i] for i in range(x.shape[1])]
    out += ["", f"RMSE / CRB: median {np.median(ratio):.2f}, worst {np.max(ratio):.2f} "
            f"({names[int(np.argmax(ratio))]}).", ""]
    return out


def _bias_table(recs: list, label: str, names) -> list:
    """Bias per parameter from antithetic pairs: mean of the pair means, its Monte-Carlo
    standard error, in % of the truth and in units of the bound."""
    pairs = {}
    for r in recs:
        pairs.setdefault(r["seed"], {})[bool(r.get("mirror"))] = r["methods"][label]
    both = [p for p in pairs.values() if len(p) == 2]
    if not both:
        return []
    xm = np.array([(np.array(p[False]["x"]) + np.array(p[True]["x"])) / 2 for p in both])
    t = np.array(both[0][False]["truth"])
    crb = np.median([p[False]["crb"] for p in both if p[False]["crb"] is not None], axis=0)
    b, se = xm.mean(axis=0) - t, xm.std(axis=0, ddof=1) / np.sqrt(len(both))
    scale = np.zeros_like(t)
    for g in (slice(0, 1), slice(1, 4), slice(4, 10)):
        scale[g] = np.max(np.abs(t[g])) if len(t[g]) else 0.0
    out = [f"### {label}: bias from {len(both)} antithetic pairs", "",
           "| parameter | truth | bias | +- MC s.e. | bias (% of truth) | +- s.e. (%) "
           "| bias / CRB | s.e. / CRB |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for i, n in enumerate(names[:xm.shape[1]]):
        rel = abs(t[i]) > 0.05 * scale[i]
        pct = f"{100 * b[i] / t[i]:+.3f} | {100 * se[i] / abs(t[i]):.3f}" if rel else "- | -"
        out.append(f"| {n} | {t[i]:.4g} | {b[i]:+.3g} | {se[i]:.2g} | {pct} | "
                   f"{b[i] / crb[i]:+.3f} | {se[i] / crb[i]:.3f} |")
    return out + [""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=16)
    ap.add_argument("--robots", default=",".join(ROBOTS))
    ap.add_argument("--jsonl", default=str(ROOT / "results" / "efficiency_runs.jsonl"))
    ap.add_argument("--out", default=str(ROOT / "results" / "efficiency.md"))
    ap.add_argument("--methods", default=None,
                    help="semicolon-separated starts of method labels to run (default: all), "
                         "e.g. 'euler-filtfilt, cutoff;rts'")
    ap.add_argument("--duration", type=float, default=26.0,
                    help="recording length, s (the rich orbits shortened or stretched)")
    ap.add_argument("--rotation-deg", type=float, default=2.865,
                    help="rotation amplitude of the orbits, deg (default 0.05 rad)")
    ap.add_argument("--seed0", type=int, default=1000,
                    help="first seed (recording k has seed seed0 + k; another seed0 gives an "
                         "independent Monte Carlo of the same design)")
    ap.add_argument("--antithetic", action="store_true",
                    help="each seed also as its antithetic twin (noise negated); adds the "
                         "bias from the pair means with its standard error")
    ap.add_argument("--workers", type=positive_int, default=None)
    ap.add_argument("--scheduler", default=None)
    args = ap.parse_args(argv)
    from cdprid.base import UserError, run_sweep
    from cdprid.model import PARAMETER_NAMES

    robots = args.robots.split(",")
    bad = [r for r in robots if r not in ROBOTS]
    if bad or args.reps < 1:
        ap.error(f"--robots {args.robots}: unknown robot {bad[0]!r} (choose from "
                 f"{', '.join(ROBOTS)})" if bad else f"--reps {args.reps}: must be >= 1")
    keep = tuple(m.strip() for m in (args.methods or "").split(";") if m.strip())
    labels = [k for k in METHODS if not keep or k.startswith(keep)]
    tag = f"|{args.methods}" if args.methods else ""
    design = {}
    if args.duration != 26.0 or args.rotation_deg != 2.865:
        design = {"duration": args.duration, "rotation_rad": np.radians(args.rotation_deg)}
        tag += f"|{args.duration:g} s|{args.rotation_deg:g} deg"
    specs = [{"key": f"{r}|{args.seed0 + k}{tag}", "robot": r, "seed": args.seed0 + k,
              "methods": labels, **design} for r in robots for k in range(args.reps)]
    if args.antithetic:
        specs += [{**s, "key": s["key"] + "|mirror", "mirror": True} for s in specs]
    t0 = time.time()
    try:
        recs = run_sweep(specs, run, args.jsonl, workers=args.workers, scheduler=args.scheduler)
    except UserError as exc:  # an unreachable --scheduler: one sentence, exit 2
        ap.error(str(exc))
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    lines = ["# Efficiency of identify against the Cramer-Rao bound", "",
             f"Generated by `python -m benchmarks.efficiency --reps {args.reps} --robots "
             f"{args.robots}" + (f" --methods '{args.methods}'" if args.methods else "") +
             (f" --duration {args.duration:g} --rotation-deg {args.rotation_deg:g}"
              if design else "") + (f" --seed0 {args.seed0}" if args.seed0 != 1000 else "") +
             (" --antithetic" if args.antithetic else "") +
             "` at commit "
             f"`{commit}` on {platform.machine()}, Python {platform.python_version()}; "
             f"{time.strftime('%Y-%m-%d %H:%M')}; {len(recs)} recordings, "
             f"{time.time() - t0:.0f} s.", "",
             f"Each recording: `rich` orbits over {args.duration:g} s with "
             f"{args.rotation_deg:.3g} deg rotations, noise "
             "0.3 mm / 0.3 mrad / 0.5 N, identified with `model auto` (the full model). CRB: "
             "identify's own `crb_std` (errors-in-variables bound, noise levels estimated from "
             "the data). RMSE / CRB = 1 is the best any unbiased estimator can do on these "
             "recordings; RMS z = 1 means the HAC std is honest.", ""]
    names = PARAMETER_NAMES["full"]
    for r in robots:
        sub = [x for x in recs if x["robot"] == r]
        lines += [f"## {r} ({len(sub)} recordings)", ""]
        for label in labels:
            lines += _table(sub, label, names)
            if args.antithetic:
                lines += _bias_table(sub, label, names)
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
