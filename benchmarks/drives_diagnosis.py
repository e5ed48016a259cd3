"""`cdprid diagnose --source currents` (issue 41 item 4): drive-side effects hidden in recordings
of the independent winch simulator (``tests/identify/winch_sim.py``) and found.

Usage (from the repository root): python -m benchmarks.drives_diagnosis [--seeds 5]
       [--first-seed 0] [--robots six,eight] [--cases clean,single,all,clock]
       [--out results/drives-diagnosis.md] [--jsonl runs.jsonl] [--from-jsonl]

Per robot (the six-cable suspended one, the CRAFT-like eight) and seed, 30 s sums of sines,
currents at 500 Hz with 0.03 A noise, encoder lengths, poses at 100 Hz (0.2 mm, 0.3 mrad), drive
1 calibrated and the others' datasheets stated +- 10 %:

- ``clean``: ideal drives, exact datasheets: nothing may be named;
- ``single``: one drive-side effect of the vocabulary on one drawn cable (friction 2-10 N and
  2-10 N s/m, inertia 0.5-5 kg, offset 0.05-0.15 A, a torque constant 5-10 % off the datasheet);
- ``all``: every drive off in every way (the simulator's own draws: inertia 0.5-5 kg, friction
  2-10 N and N s/m, offsets within +-0.05 A, datasheets up to 10 % off);
- ``clock``: ideal drives, the currents' time stamps 20 ms late: ``time_delay`` must be named.

Scored: each hidden effect named (its 95 % interval covering the truth or not) or missed; a
finding that is not hidden is wrong; the mass error.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.conftest import ROBOT_CRAFT  # noqa: E402
from tests.identify import winch_sim  # noqa: E402

from cdprid.model import SIX_SUSPENDED  # noqa: E402

ROBOTS = {"six": (dict(SIX_SUSPENDED, home=[0.0, 0.0, 1.4]), 40.0),
          "eight": (dict(ROBOT_CRAFT, home=[0.0, 0.0, 1.3]), 30.0)}
PLATFORM = (6.0, np.array([0.01, -0.005, -0.05]), np.diag([0.06, 0.07, 0.09]))
KEYS = {"drive_friction": ("coulomb_N", "viscous_Ns_per_m"), "drive_inertia": ("J_kg",),
        "current_offset": ("offset_A",), "torque_constant_error": ("ratio",),
        "time_delay": ("delay_s",)}


def _ideal(d):
    for key in ("Jm", "Jd", "b", "Tc", "i0"):
        d[key] = 0.0 * d[key]
    return d


def _single(rng, m):
    """One drawn drive-side effect: (name, cable, truth dict) and the winch edit."""
    name = str(rng.choice(list(KEYS)[:4]))
    j = int(rng.integers(2 if name == "torque_constant_error" else 1, m + 1))
    size = {"drive_friction": (rng.uniform(2, 10), rng.uniform(2, 10)),
            "drive_inertia": (rng.uniform(0.5, 5),), "current_offset": (rng.uniform(0.05, 0.15),),
            "torque_constant_error": (rng.choice([-1, 1]) * rng.uniform(0.05, 0.10) + 1,)}[name]

    def edit(d):
        d = _ideal(d)
        r = d["r"][j - 1]
        if name == "drive_friction":
            d["Tc"][j - 1], d["b"][j - 1] = size[0] * r, size[1] * r * r
        elif name == "drive_inertia":
            d["Jd"][j - 1] = size[0] * r * r
        elif name == "current_offset":
            d["i0"][j - 1] = size[0]
        return d
    return name, j, dict(zip(KEYS[name], size, strict=True)), edit


def _case(robot: str, case: str, seed: int, out: Path):
    """Write one recording; return its hidden effects {(name, cable): truth}."""
    rob, tau_ref = ROBOTS[robot]
    m = len(rob["cable"])
    rng = np.random.default_rng([seed, 41, ["clean", "single", "all", "clock"].index(case)])
    hidden, edit, err = {}, _ideal, 0.0
    if case == "single":
        name, j, truth, edit = _single(rng, m)
        hidden[(name, j)] = truth
    if case == "all":
        edit, err = None, 0.1
    sim = winch_sim.simulate(rob, PLATFORM, seed=seed, duration=30.0, rate_drive=500.0,
                             tau_ref=tau_ref, datasheet_error=err, drive_edit=edit)
    for f in sim["drive_fields"][1:]:
        f["torque_constant_tolerance"] = 0.1
    if case == "single" and name == "torque_constant_error":
        sim["drive_fields"][j - 1]["torque_constant"] /= truth["ratio"]
    if case == "clock":
        td, cur, lens = sim["drives"]
        sim["drives"] = (td + 0.02, cur, lens)
        hidden[("time_delay", None)] = {"delay_s": 0.02}
    if case == "all":
        k, J, fv, fc, c = sim["truth"]
        kn = np.array([d["torque_constant"] * d["gear_ratio"] / d["drum_radius"]
                       for d in sim["drive_fields"]])
        for j in range(1, m + 1):
            if j > 1:
                hidden[("torque_constant_error", j)] = {"ratio": k[j - 1] / kn[j - 1]}
            hidden[("drive_friction", j)] = {"coulomb_N": fc[j - 1], "viscous_Ns_per_m": fv[j - 1]}
            hidden[("drive_inertia", j)] = {"J_kg": J[j - 1]}
            hidden[("current_offset", j)] = {"offset_A": c[j - 1] / k[j - 1]}
    winch_sim.write(out, rob, sim)
    return hidden


def run_one(robot: str, case: str, seed: int) -> dict:
    """Diagnose one recording and score it."""
    from cdprid.diagnosis import diagnose
    from cdprid.identify import identify_currents
    from cdprid.io import read_dataset

    with tempfile.TemporaryDirectory() as tmp:
        hidden = _case(robot, case, seed, Path(tmp) / "d")
        t0 = time.perf_counter()
        res = diagnose(read_dataset(Path(tmp) / "d", require_tensions=False), source="currents",
                       drive_fit=identify_currents)
        wall = time.perf_counter() - t0
    named, covered, wrong = [], 0, []
    for f in res.findings:
        key = (f.effect, f.parameters.get("cable"))
        if key not in hidden:
            wrong.append(f"{f.effect} {f.parameters}")
            continue
        named.append(key)
        covered += all(f.interval[p][0] <= v <= f.interval[p][1] for p, v in hidden[key].items())
    return {"robot": robot, "case": case, "seed": seed, "hidden": len(hidden),
            "named": len(named), "covered": covered, "wrong": wrong,
            "mass_err_pct": 100 * (res.extended_parameters["m"].value / PLATFORM[0] - 1),
            "mass_z": (res.extended_parameters["m"].value - PLATFORM[0])
            / res.extended_parameters["m"].std,
            "wall_s": wall}


def _worst_z(rs) -> str:
    z = [abs(r["mass_z"]) for r in rs if "mass_z" in r]
    return f"{max(z):.2f}" if z else "-"


def table(rows: list) -> str:
    """The markdown table of the runs, one line per robot and case."""
    out = ["| robot | case | runs | hidden | named | intervals covering | wrong findings | "
           "mass error (median / worst) | mass z (worst) | wall (median) |", "|---" * 10 + "|"]
    for robot in ROBOTS:
        for case in ("clean", "single", "all", "clock"):
            rs = [r for r in rows if r["robot"] == robot and r["case"] == case]
            if not rs:
                continue
            err = np.abs([r["mass_err_pct"] for r in rs])
            out.append(f"| {robot} | {case} | {len(rs)} | {sum(r['hidden'] for r in rs)} | "
                       f"{sum(r['named'] for r in rs)} | {sum(r['covered'] for r in rs)} | "
                       f"{sum(len(r['wrong']) for r in rs)} | {np.median(err):.2f} / "
                       f"{err.max():.2f} % | {_worst_z(rs)} | "
                       f"{np.median([r['wall_s'] for r in rs]):.0f} s |")
    return "\n".join(out)


def main(argv=None) -> int:
    """Run the benchmark; print and write the table."""
    import jax

    jax.config.update("jax_enable_x64", True)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--from-jsonl", action="store_true",
                    help="only write the table of the runs already in --jsonl")
    ap.add_argument("--robots", default="six,eight")
    ap.add_argument("--cases", default="clean,single,all,clock")
    ap.add_argument("--out", default=None)
    ap.add_argument("--jsonl", default=None)
    a = ap.parse_args(argv)
    robots, cases = a.robots.split(","), a.cases.split(",")
    bad = [x for x in robots if x not in ROBOTS] + [
        x for x in cases if x not in ("clean", "single", "all", "clock")]
    if bad or a.seeds < 1 or a.first_seed < 0 or (a.from_jsonl and not a.jsonl):
        print(f"drives_diagnosis: unknown robot or case {bad} (or --seeds < 1, --first-seed "
              "< 0, --from-jsonl without --jsonl).", file=sys.stderr)
        return 2
    rows = []
    if a.from_jsonl:
        rows = [json.loads(x) for x in Path(a.jsonl).read_text().splitlines() if x.strip()]
    for seed in range(a.first_seed, a.first_seed + (0 if a.from_jsonl else a.seeds)):
        for robot in robots:
            for case in cases:
                r = run_one(robot, case, seed)
                rows.append(r)
                print(json.dumps(r), flush=True)
                if a.jsonl:
                    with open(a.jsonl, "a") as fh:
                        fh.write(json.dumps(r) + "\n")
    text = table(rows)
    print(text)
    if a.out:
        Path(a.out).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
