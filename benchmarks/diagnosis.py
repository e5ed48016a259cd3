"""Detection table of `cdprid diagnose` on simulated datasets with one hidden effect each.

Usage: python benchmarks/diagnosis.py [--seeds N] [--out results/diagnosis.md]

For every effect of the vocabulary (and `none`), draws (cable, magnitude, sign) from a seeded
RNG at the issue's realistic magnitudes, simulates a CRAFT-like dataset on the `rich`
trajectory (several orbits, frequencies and planes; quaternions in pose.csv; noise drawn in
0.2-0.4 mm and 0.5-1 N), runs the diagnosis and scores: named (the effect, or among the
aliases), size (within tolerance), wrong (another effect named), none.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

EFFECTS = ["none", "time_delay", "tension_offset", "tension_gain", "exit_point_error",
           "anchor_point_error", "viscous_drag", "pulley", "cable_mass", "frame_tilt",
           "rotational_dynamics", "pulley_friction", "oov_load_cell_coulomb"]


def draw(effect: str, rng: np.random.Generator, m: int = 8) -> dict:
    """Parameters of one hidden effect at the issue's magnitudes."""
    sign = rng.choice([-1.0, 1.0])
    cable = int(rng.integers(1, m + 1))
    if effect == "time_delay":
        return {"delay_s": float(rng.uniform(0.010, 0.040))}
    if effect == "tension_offset":
        return {"cable": cable, "offset_N": float(sign * rng.uniform(2, 8))}
    if effect == "tension_gain":
        return {"cable": cable, "gain": float(1 + sign * rng.uniform(0.03, 0.08))}
    if effect in ("exit_point_error", "anchor_point_error"):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        return {"cable": cable, "displacement_m": [float(v) for v in u * rng.uniform(0.01, 0.04)]}
    if effect == "viscous_drag":
        return {"coefficient_Ns_per_m": float(rng.uniform(3, 10))}
    if effect == "pulley":
        return {"radius_m": float(rng.uniform(0.02, 0.06))}
    if effect == "cable_mass":
        return {"linear_density_kg_per_m": float(rng.uniform(0.1, 0.3))}
    if effect == "frame_tilt":
        a = np.deg2rad(rng.uniform(0.5, 1.5))
        phi = rng.uniform(0, 2 * np.pi)
        return {"tilt_rad": [float(a * np.cos(phi)), float(a * np.sin(phi))]}
    if effect == "rotational_dynamics":
        return {"amplitude_rad": float(rng.uniform(0.05, 0.15))}
    if effect == "pulley_friction":
        return {"cable": cable, "coulomb_N": float(rng.uniform(1.0, 3.0)),
                "viscous_Ns_per_m": 0.0}
    if effect == "oov_load_cell_coulomb":  # outside the vocabulary: every cable, either sign
        return {"coulomb_N": float(sign * rng.uniform(1.0, 2.0))}
    return {}


def size_ok(effect: str, truth: dict, est: dict) -> bool:
    """Whether the estimated size matches the truth within the stated tolerance."""
    if effect in ("exit_point_error", "anchor_point_error"):
        # the size of a displacement is its norm; its component along the cable barely
        # changes the cable direction and is weakly observable (docs/diagnosis.md)
        n_est = np.linalg.norm(est["displacement_m"])
        n_true = np.linalg.norm(truth["displacement_m"])
        return est.get("cable") == truth["cable"] and abs(n_est - n_true) <= 0.35 * n_true
    if effect == "frame_tilt":
        return (np.linalg.norm(np.subtract(est["tilt_rad"], truth["tilt_rad"]))
                <= 0.25 * np.linalg.norm(truth["tilt_rad"]))
    if effect == "pulley_friction":
        return (est.get("cable") == truth["cable"]
                and abs(est["coulomb_N"] - truth["coulomb_N"]) <= 0.25 * truth["coulomb_N"])
    if effect == "tension_gain":
        return est.get("cable") == truth["cable"] and abs(est["gain"] - truth["gain"]) <= 0.25 * abs(truth["gain"] - 1)
    key = [k for k in truth if k != "cable"][0]
    if "cable" in truth and est.get("cable") != truth["cable"]:
        return False
    return abs(est[key] - truth[key]) <= 0.25 * abs(truth[key])


def score(effect: str, params: dict, found: list) -> str:
    """Outcome of one draw from the truth and the findings (JSON form, best first)."""
    true_label = effect if "cable" not in params else f"{effect}:cable={params['cable']}"
    if effect == "none":
        return "correct-none" if not found else "false-positive"
    if effect.startswith("oov_"):  # must not be named: no finding (it goes to 'unexplained')
        return "correct-none" if not found else "wrong"
    if not found:
        return "missed"
    top = found[0]
    if top["effect"] == effect and top["parameters"].get("cable") == params.get("cable"):
        return "named" if size_ok(effect, params, top["parameters"]) else "named-wrong-size"
    if true_label in top["aliases"] or effect in top["aliases"]:
        return "alias"
    if top["effect"] == effect:
        return "named-wrong-size"  # right effect, wrong cable
    return "wrong"


def six_cable_robot() -> dict:
    """A suspended, non-redundant 6-cable robot (square W), robot.toml mapping."""
    cab = []
    for i in range(6):
        a = np.deg2rad(60 * i)
        b = a + np.deg2rad(50) * (1 if i % 2 == 0 else -1)
        cab.append({"exit": [round(2.0 * np.cos(a), 4), round(2.0 * np.sin(a), 4), 2.6],
                    "anchor": [round(0.15 * np.cos(b), 4), round(0.15 * np.sin(b), 4),
                               0.05 if i % 2 else -0.05]})
    return {"name": "six-suspended", "gravity": [0.0, 0.0, -9.81],
            "limits": {"tension_min": 1.0, "tension_max": 300.0,
                       "workspace_min": [-0.9, -0.9, 0.6], "workspace_max": [0.9, 0.9, 1.8]},
            "cable": cab,
            "platform": {"mass": 9.88, "com": [0.0, 0.0, -0.1],
                         "inertia": [[0.12, 0, 0], [0, 0.12, 0], [0, 0, 0.1]]}}


def make_robot(name: str):
    """``craft8`` (the CRAFT-like 8-cable robot) or ``six`` (:func:`six_cable_robot`)."""
    from cdprid.geometry import robot_from_dict
    from cdprid.robots import craft_like_robot

    return craft_like_robot() if name == "craft8" else robot_from_dict(six_cable_robot())


def score_many(truth: list, found: list) -> str:
    """Several hidden effects: ``named`` when each is a finding of the right size (cable) and
    nothing else is; ``extra`` when all are named plus something else; else ``partial``."""
    hit = 0
    used = set()
    for eff, params in truth:
        for k, f in enumerate(found):
            if k in used or f["effect"] != eff:
                continue
            if params.get("cable") is not None and f["parameters"].get("cable") != params["cable"]:
                continue
            if size_ok(eff, params, f["parameters"]):
                hit += 1
                used.add(k)
                break
    if hit == len(truth):
        return "named" if len(found) == len(truth) else "extra"
    return "partial" if hit else "missed"


def run_case(truth: list, seed: int, workdir: Path, robot_name: str = "craft8",
             noise_scale: float = 1.0) -> dict:
    """Simulate one robot with several effects (``[(name, params)]``), diagnose, score."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.diagnosis import diagnose
    from cdprid.effects import Effect
    from cdprid.io import read_dataset
    from cdprid.robots import craft_like_truth
    from cdprid.simulate import SensorNoise, simulate, write_simulation
    from cdprid.trajectories import preset

    robot = make_robot(robot_name)
    noise = SensorNoise(position_m=3e-4 * noise_scale, tension_N=0.7 * noise_scale,
                        orientation_rad=2e-4)
    sim = simulate(robot, preset("rich", robot), craft_like_truth(),
                   effects=[Effect(n, p) for n, p in truth], noise=noise, seed=seed)
    tag = "+".join(n for n, _ in truth) or "none"
    out = write_simulation(sim, workdir / f"{robot_name}-{tag}-{seed}", overwrite=True)
    t1 = time.perf_counter()
    res = diagnose(read_dataset(out))
    dt = time.perf_counter() - t1
    found = [x.as_json() for x in res.findings]
    outcome = ("correct-none" if not found else "false-positive") if not truth else \
        score_many(truth, found)
    return {"robot": robot_name, "truth": truth, "seed": seed, "outcome": outcome,
            "found": found, "unexplained": res.as_json()["unexplained"], "diagnose_s": dt}


#: paired and non-redundant cases of the v2 table: (robot, [(effect, params)])
CASES = [
    ("six", []),
    ("six", [("tension_gain", {"cable": 2, "gain": 1.04})]),
    ("six", [("anchor_point_error", {"cable": 4, "displacement_m": [0.02, -0.01, 0.0]})]),
    ("craft8", [("time_delay", {"delay_s": 0.02}), ("tension_offset", {"cable": 2,
                                                                       "offset_N": 4.0})]),
    ("craft8", [("tension_gain", {"cable": 5, "gain": 1.05}),
                ("viscous_drag", {"coefficient_Ns_per_m": 6.0})]),
    ("craft8", [("cable_mass", {"linear_density_kg_per_m": 0.2}),
                ("frame_tilt", {"tilt_rad": [0.015, -0.01]})]),
    ("craft8", [("pulley_friction", {"cable": 3, "coulomb_N": 2.0, "viscous_Ns_per_m": 0.0})]),
]


def with_load_cell_coulomb(sim, coulomb_N: float):
    """Add ``coulomb_N sign(dl/dt)`` to every load cell (an effect outside the vocabulary)."""
    import dataclasses

    mt = sim.motion_tension
    twist = np.concatenate([np.asarray(mt.v), np.asarray(mt.omega)], axis=1)
    ldot = -np.einsum("nim,ni->nm", np.asarray(sim.W_true), twist)
    return dataclasses.replace(sim, tension=sim.tension + coulomb_N * np.sign(ldot))


def run_one(effect: str, seed: int, workdir: Path) -> dict:
    """Simulate, diagnose, score one draw."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.diagnosis import diagnose
    from cdprid.effects import Effect
    from cdprid.io import read_dataset
    from cdprid.robots import craft_like_robot, craft_like_truth
    from cdprid.simulate import SensorNoise, simulate, write_simulation
    from cdprid.trajectories import preset

    rng = np.random.default_rng(1000 + seed * 17 + EFFECTS.index(effect))
    params = draw(effect, rng)
    noise = SensorNoise(position_m=float(rng.uniform(0.0002, 0.0004)),
                        tension_N=float(rng.uniform(0.5, 1.0)), orientation_rad=2e-4)
    robot = craft_like_robot()
    traj = preset("rich", robot)
    effects = [] if effect == "none" or effect.startswith("oov_") else [Effect(effect, params)]
    t0 = time.perf_counter()
    sim = simulate(robot, traj, craft_like_truth(), effects=effects, noise=noise, seed=seed)
    if effect == "oov_load_cell_coulomb":
        sim = with_load_cell_coulomb(sim, params["coulomb_N"])
    out = write_simulation(sim, workdir / f"{effect}-{seed}", overwrite=True)
    t1 = time.perf_counter()
    res = diagnose(read_dataset(out))
    t2 = time.perf_counter()
    found = [x.as_json() for x in res.findings]
    outcome = score(effect, params, found)
    if effect.startswith("oov_") and outcome == "correct-none" and not res.unexplained:
        outcome = "missed"  # an effect outside the vocabulary must show up as unexplained
    return {"effect": effect, "seed": seed, "truth": params, "outcome": outcome,
            "found": found, "unexplained": res.as_json()["unexplained"], "sim_s": t1 - t0,
            "diagnose_s": t2 - t1}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument("--out", default="results/diagnosis.md")
    ap.add_argument("--jsonl", default=None, help="append every draw's record to this file")
    ap.add_argument("--cases", action="store_true",
                    help="run the paired / 6-cable cases (CASES) and append their table")
    ap.add_argument("--from-jsonl", default=None,
                    help="re-score the records of an earlier run instead of running again")
    args = ap.parse_args()
    rows = []
    if args.from_jsonl:
        rows = [json.loads(line) for line in open(args.from_jsonl)]
        for r in rows:
            r["outcome"] = score(r["effect"], r["truth"], r["found"])
        args.seeds = len({r["seed"] for r in rows})
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(0 if args.from_jsonl else args.seeds):
            for eff in [e for e in args.effects.split(",") if e]:
                r = run_one(eff, seed, Path(tmp))
                rows.append(r)
                found = r["found"][0]["effect"] + " " + json.dumps(r["found"][0]["parameters"]) if r["found"] else "-"
                print(f"{eff:22s} seed {seed}: {r['outcome']:16s} truth {json.dumps(r['truth'])}  found {found}"
                      f"  ({r['diagnose_s']:.1f} s)", flush=True)
                if args.jsonl:
                    with open(args.jsonl, "a") as fh:
                        fh.write(json.dumps(r) + "\n")
    outcomes = ["named", "alias", "named-wrong-size", "missed", "wrong", "correct-none",
                "false-positive"]
    lines = ["# Diagnosis detection table", "",
             f"Command: `python benchmarks/diagnosis.py --seeds {args.seeds}`"
             + (f" (outcomes re-scored from `{args.from_jsonl}` with `--from-jsonl`)"
                if args.from_jsonl else "") + "; machine: "
             f"{platform.platform()}, {platform.processor() or 'cpu'}; python {sys.version.split()[0]}.", "",
             "Each draw: a CRAFT-like 8-cable robot on the `rich` trajectory (six orbits, "
             "0.2-0.6 Hz, several planes, 52 s at 100 Hz, quaternions in pose.csv), position "
             "noise 0.2-0.4 mm, tension noise 0.5-1 N, orientation noise 0.2 mrad, one effect "
             "drawn at the issue's magnitudes (delay 10-40 ms, offset 2-8 N, gain 3-8 %, exit or "
             "anchor 1-4 cm, drag 3-10 N s/m, pulley 2-6 cm, tilt 0.5-1.5 deg, cable mass "
             "0.1-0.3 kg/m, rotation 0.05-0.15 rad), or none. Diagnose times are wall-clock with "
             "other jobs sharing the 2 cores (see benchmarks.md for a quiet-machine figure).", "",
             "Outcomes: `named` = right effect (and cable) with the size within tolerance (25 % "
             "for scalars and tilt; the norm within 35 % for displacements, whose component "
             "along the cable is weakly observable); `alias` = the true effect is "
             "listed among the aliases of the finding (the data cannot separate them); "
             "`named-wrong-size` = right effect, wrong size or cable; `wrong` = another effect "
             "named; `missed` = no finding.", "",
             "| effect | " + " | ".join(outcomes) + " | mean diagnose time [s] |",
             "|---|" + "---|" * (len(outcomes) + 1)]
    for eff in [e for e in args.effects.split(",") if e]:
        sub = [r for r in rows if r["effect"] == eff]
        counts = [sum(r["outcome"] == o for r in sub) for o in outcomes]
        lines.append(f"| {eff} | " + " | ".join(str(c) for c in counts)
                     + f" | {np.mean([r['diagnose_s'] for r in sub]):.1f} |")
    if args.cases:
        lines += ["", "## Paired effects and the non-redundant 6-cable robot", "",
                  "Noise 0.3 mm / 0.7 N; `named` = every hidden effect named with its size and "
                  "nothing else; `extra` = all named plus another finding; `partial`/`missed`.",
                  "", "| robot | hidden effects | seed | outcome | findings | unexplained | "
                  "time [s] |", "|---|---|---|---|---|---|---|"]
        with tempfile.TemporaryDirectory() as tmp:
            for seed in range(args.seeds):
                for rname, truth in CASES:
                    r = run_case(truth, seed, Path(tmp), rname)
                    fnd = "; ".join(f"{f['effect']} {json.dumps(f['parameters'])}"
                                    for f in r["found"]) or "-"
                    une = "; ".join(f"{u['correlates_with'][:40]} ({u['size']:.2g} N)"
                                    for u in r["unexplained"]) or "-"
                    tru = "; ".join(f"{n} {json.dumps(p)}" for n, p in truth) or "none"
                    lines.append(f"| {rname} | {tru} | {seed} | {r['outcome']} | {fnd} | {une} "
                                 f"| {r['diagnose_s']:.0f} |")
                    print(lines[-1], flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
