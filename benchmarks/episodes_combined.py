"""Episodes with everything at once (issue 38's acceptance on the unseen 8-cable robot).

Recordings of the floor-winch 8-cable robot by the independent test simulator
(``tests._testbench.floor8_combined``: 45-55 s, the 3-6 load-cell and clock effects of
``floor8_case``, white + AR(1) tension noise) with 2-3 hand pushes (10-40 N for 1-3 s, smooth
ramps, a moment from a hand on the platform's rim) and 4 marker glitches (1-3 samples,
3-8 cm, 2-6 deg); and each recording's clean twin (the same noise, no push, no glitch).
On both, ``cdprid identify`` (:func:`cdprid.identify.identify_dataset` with the CLI's
defaults) and ``cdprid diagnose`` (:func:`cdprid.diagnosis.diagnose` with the CLI's defaults).

Scored per recording:

* a push is *located* when the wrench episodes that overlap it (``external_wrench`` or
  ``load_cell_step``; their union when it is split) start and end within 0.5 s of its
  ``start_s`` / ``end_s`` (where its ramps begin and end);
* false episodes: on the clean twin every episode; on the recording every episode that
  overlaps no push (within 0.5 s) and no glitch;
* a glitch is *excluded* when a ``pose_glitches`` episode covers its samples;
* mass and m s_G errors (norm of the vector error over the truth's norm), identify's
  estimate and the diagnosis's extended model;
* the diagnosis's findings against the truth's effects (the scoring of
  ``benchmarks.many_effects``: named with size, wrong, missed);
* the verdict: it may say the model explains the data within its noise only when the
  held-out force residual is within the noise-predicted rms times (1 + margin).

Run from the repository root (about 3-6 min per seed on a loaded 2-core machine)::

    nice -n 10 python -m benchmarks.episodes_combined [--seeds 0-3] \
        [--out results/episodes-combined.md]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: a push's start and end must be located within this, s (issue 38's acceptance)
EDGE_TOL_S = 0.5
WRENCH_KINDS = ("external_wrench", "load_cell_step")


def push_scores(pushes, episodes) -> list:
    """Per push ``{located, start_err, end_err, pieces}`` from the episodes (JSON dicts)."""
    out = []
    for p in pushes:
        over = [e for e in episodes if e["kind"] in WRENCH_KINDS
                and e["start_s"] <= p.end_s and e["end_s"] >= p.start_s]
        if not over:
            out.append({"located": False, "start_err": None, "end_err": None, "pieces": 0})
            continue
        a = min(e["start_s"] for e in over) - p.start_s
        b = max(e["end_s"] for e in over) - p.end_s
        out.append({"located": abs(a) <= EDGE_TOL_S and abs(b) <= EDGE_TOL_S,
                    "start_err": a, "end_err": b, "pieces": len(over)})
    return out


def glitch_windows(rec) -> list:
    """``(first, last)`` pose time of each glitch's displaced samples, s."""
    from tests._testbench._episodes import glitch_indices

    return [(float(rec.pose_t[i[0]]), float(rec.pose_t[i[-1]]))
            for i in glitch_indices(rec.pose_t, rec.glitches)]


def false_episodes(rec, episodes) -> list:
    """The episodes that overlap no push (within :data:`EDGE_TOL_S`) and no glitch."""
    dt = 1.0 / rec.sensors.pose_rate_hz
    spans = [(p.start_s - EDGE_TOL_S, p.end_s + EDGE_TOL_S) for p in rec.pushes]
    spans += [(a - 2 * dt, b + 2 * dt) for a, b in glitch_windows(rec)]
    return [e for e in episodes
            if not any(e["start_s"] <= b and e["end_s"] >= a for a, b in spans)]


def glitches_excluded(rec, episodes) -> int:
    """How many of the recording's glitches a ``pose_glitches`` episode covers."""
    dt = 1.0 / rec.sensors.pose_rate_hz
    gl = [e for e in episodes if e["kind"] == "pose_glitches"]
    return sum(any(e["start_s"] <= a + dt / 2 and e["end_s"] >= b - dt / 2 for e in gl)
               for a, b in glitch_windows(rec))


def inertial_errors(params: dict, rob) -> dict:
    """Relative mass error and the m s_G vector error over its norm."""
    x = {k: v["value"] if isinstance(v, dict) else v for k, v in params.items()}
    ms = rob.mass * np.asarray(rob.com, float)
    est = np.array([x.get(k, np.nan) for k in ("mxG", "myG", "mzG")], float)
    return {"mass_err": float(x.get("m", np.nan) / rob.mass - 1.0),
            "ms_err": float(np.linalg.norm(est - ms) / np.linalg.norm(ms))}


def _identify(path: Path) -> dict:
    """``cdprid identify`` as the CLI calls it (its defaults), as JSON."""
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset

    rep = identify_dataset(read_dataset(path), model="auto", differentiator="euler-filtfilt",
                           params={}, t_start=None, t_end=None, weighting="eiv",
                           covariance="hac", wrench_filter="matched", inertia_about="P",
                           keep_episodes=False)
    return rep.as_json()


def _diagnose(path: Path) -> dict:
    """``cdprid diagnose`` as the CLI calls it (its defaults), as JSON."""
    from cdprid.diagnosis import diagnose
    from cdprid.io import read_dataset

    return diagnose(read_dataset(path), train_until=None, alpha=1e-3, n_null=30,
                    max_effects=8, seed=0, keep_episodes=False).as_json()


def score_twin(rec, ident: dict, diag: dict | None) -> dict:
    """Every score of one recording (see the module docstring)."""
    from benchmarks.many_effects import score

    row = {"identify": {"episodes": ident["episodes"],
                        "pushes": push_scores(rec.pushes, ident["episodes"]),
                        "false": false_episodes(rec, ident["episodes"]),
                        "glitches": glitches_excluded(rec, ident["episodes"]),
                        **inertial_errors(ident["parameters"], rec.robot)}}
    if diag is not None:
        v = diag["info"]["verdict"]
        exp, named, wrong, notes = score(rec.effects, diag["findings"],
                                         diag["info"].get("base_model"))
        row["diagnose"] = {
            "episodes": diag["episodes"], "pushes": push_scores(rec.pushes, diag["episodes"]),
            "false": false_episodes(rec, diag["episodes"]),
            "glitches": glitches_excluded(rec, diag["episodes"]),
            **inertial_errors(diag["extended"]["parameters"], rec.robot),
            "findings": [(f["effect"], f["parameters"]) for f in diag["findings"]],
            "expected": exp, "named": named, "wrong": wrong, "finding_notes": notes,
            "unexplained": len(diag["unexplained"]),
            "heldout": diag["extended"]["heldout_residual_rms"],
            "heldout_with": diag["extended"]["heldout_residual_rms_with_episodes"],
            "verdict": v, "verdict_honest": bool(
                not v["within_noise"] or v["heldout_force_rms_N"]
                <= v["noise_predicted_rms_N"] * (1 + v["margin"]))}
    return row


def run_seed(seed: int, workdir: Path, with_diagnose: bool = True) -> dict:
    """Both twins of one seed, written, identified, diagnosed and scored."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from tests._testbench import floor8_combined, write

    out = {"seed": seed}
    for twin in ("combined", "clean"):
        rec = floor8_combined(seed, clean=twin == "clean")
        path = write(rec, workdir / f"floor8-{twin}-{seed}", overwrite=True)
        t0 = time.perf_counter()
        ident = _identify(path)
        t1 = time.perf_counter()
        diag = _diagnose(path) if with_diagnose else None
        t2 = time.perf_counter()
        row = score_twin(rec, ident, diag)
        row.update(duration_s=float(rec.pose_t[-1]), wall_identify_s=t1 - t0,
                   wall_diagnose_s=t2 - t1, effects=rec.effects,
                   pushes=[p.truth() for p in rec.pushes],
                   glitches=[g.truth() for g in rec.glitches])
        out[twin] = row
        print(f"seed {seed} {twin}: {_summary(row)}", flush=True)
    return out


def _summary(row: dict) -> str:
    parts = []
    for who in ("identify", "diagnose"):
        if who not in row:
            continue
        r = row[who]
        ok = sum(p["located"] for p in r["pushes"])
        parts.append(f"{who}: pushes {ok}/{len(r['pushes'])}, false {len(r['false'])}, "
                     f"glitches {r['glitches']}, mass {100 * r['mass_err']:+.2f} %, m s_G "
                     f"{100 * r['ms_err']:.1f} %")
    return "; ".join(parts)


def _edges(pushes) -> str:
    return ", ".join("miss" if p["start_err"] is None else
                     f"{p['start_err']:+.2f}/{p['end_err']:+.2f}" + ("" if p["located"] else "!")
                     for p in pushes) or "-"


def table(rows: list, cmd: str, commit: str) -> str:
    """The markdown page."""
    lines = ["# Episodes with everything at once: the unseen 8-cable robot (issue 38)", "",
             f"Generated by `{cmd}` (commit {commit}, {time.strftime('%Y-%m-%d')}, shared "
             "2-core machine). See `benchmarks/episodes_combined.py` for the recordings and "
             "the scoring; every row's episodes, findings and verdict are in the `.jsonl` file "
             "beside this one. Push edges: episode minus truth, start/end in s (`!`: beyond "
             f"{EDGE_TOL_S} s). Glitches: covered by a `pose_glitches` episode / drawn. "
             "Mass error signed, m s_G error the norm of the vector error over the truth's.",
             "", "| seed | effects | pushes located (identify) | edges s (identify) | "
             "pushes located (diagnose) | edges s (diagnose) | false ep. (id / diag) | false "
             "ep. clean twin (id / diag) | glitches (id / diag) | mass id / diag | m s_G id / "
             "diag | findings named / expected, wrong | verdict | clean twin: mass / m s_G "
             "diag, verdict |", "|" + "---|" * 14]
    for r in rows:
        c, k = r["combined"], r["clean"]
        ci, cd = c["identify"], c.get("diagnose")
        ki, kd = k["identify"], k.get("diagnose")
        ng = len(c["glitches"])
        eff = len([e for e in c["effects"] if e[0] != "rotational_dynamics"])

        def loc(x):
            return f"{sum(p['located'] for p in x['pushes'])}/{len(x['pushes'])}"

        def pct(x, key):
            return f"{100 * x[key]:+.2f} %" if key == "mass_err" else f"{100 * x[key]:.1f} %"

        def verdict(d):
            if d is None:
                return "-"
            v = d["verdict"]
            word = "within noise" if v["within_noise"] else "not within noise"
            return (f"{word}: {v['heldout_force_rms_N']:.2f} N vs {v['noise_predicted_rms_N']:.2f}"
                    f" N ({v['ratio']:.2f}x){'' if d['verdict_honest'] else ' DISHONEST'}")

        lines.append(
            f"| {r['seed']} | {eff} | {loc(ci)} | {_edges(ci['pushes'])} | "
            + (f"{loc(cd)} | {_edges(cd['pushes'])} | " if cd else "- | - | ")
            + f"{len(ci['false'])} / {len(cd['false']) if cd else '-'} | "
            + f"{len(ki['false'])} / {len(kd['false']) if kd else '-'} | "
            + f"{ci['glitches']}/{ng} / {cd['glitches'] if cd else '-'}/{ng} | "
            + f"{pct(ci, 'mass_err')} / {pct(cd, 'mass_err') if cd else '-'} | "
            + f"{pct(ci, 'ms_err')} / {pct(cd, 'ms_err') if cd else '-'} | "
            + (f"{cd['named']}/{cd['expected']}, {cd['wrong']} wrong" if cd else "-") + " | "
            + f"{verdict(cd)} | "
            + (f"{pct(kd, 'mass_err')} / {pct(kd, 'ms_err')}, {verdict(kd)}" if kd else "-")
            + " |")
    lines += ["", *_totals(rows), "", "Findings not named, wrong findings and the false "
              "episodes, per recording:", ""]
    for r in rows:
        for twin in ("combined", "clean"):
            for who in ("identify", "diagnose"):
                x = r[twin].get(who)
                if x is None:
                    continue
                notes = list(x.get("finding_notes", []))
                notes += [f"false {e['kind']} {e['start_s']:.2f}-{e['end_s']:.2f} s"
                          + (f" {e['size_N']:.2g} N" if e.get("size_N") is not None else "")
                          for e in x["false"]]
                if notes:
                    lines.append(f"* seed {r['seed']} {twin}, {who}: {'; '.join(notes)}")
    return "\n".join(lines) + "\n"


def _totals(rows: list) -> list:
    out = []
    for who in ("identify", "diagnose"):
        sel = [r["combined"][who] for r in rows if who in r["combined"]]
        if not sel:
            continue
        ps = [p for x in sel for p in x["pushes"]]
        se = [abs(p["start_err"]) for p in ps if p["start_err"] is not None]
        ee = [abs(p["end_err"]) for p in ps if p["end_err"] is not None]
        twins = [r["clean"][who] for r in rows if who in r["clean"]]
        clean = sum(len(x["false"]) for x in twins)
        hours = sum(r["clean"]["duration_s"] for r in rows) / 3600.0
        out.append(f"* **{who}**: {sum(p['located'] for p in ps)} of {len(ps)} pushes located "
                   f"(start errors max {max(se, default=float('nan')):.2f} s, end errors max "
                   f"{max(ee, default=float('nan')):.2f} s); {sum(len(x['false']) for x in sel)}"
                   f" false episodes on the recordings, {clean} on the clean twins "
                   f"({hours:.3f} h); glitches excluded {sum(x['glitches'] for x in sel)} of "
                   f"{sum(len(r['combined']['glitches']) for r in rows)}; |mass error| max "
                   f"{100 * max(abs(x['mass_err']) for x in sel):.2f} % (goal 1 %), m s_G "
                   f"error max {100 * max(x['ms_err'] for x in sel):.1f} % (goal 5 %); on the "
                   f"clean twins {100 * max(abs(x['mass_err']) for x in twins):.2f} % and "
                   f"{100 * max(x['ms_err'] for x in twins):.1f} %.")
    return out


def _seeds(text: str) -> list:
    if "-" in text:
        lo, hi = (int(x) for x in text.split("-"))
        return list(range(lo, hi + 1))
    return [int(x) for x in text.split(",")]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", default="0-3", help="a range 0-3 or a list 0,2,5")
    p.add_argument("--workdir", default="/tmp/cdprid-episodes-combined")
    p.add_argument("--out", default=str(ROOT / "results" / "episodes-combined.md"))
    p.add_argument("--no-diagnose", action="store_true", help="identify only (fast)")
    p.add_argument("--merge", nargs="*", default=None,
                   help=".jsonl files of earlier runs: one table from their rows")
    p.add_argument("--commit", default=None,
                   help="with --merge: the commit the merged rows were run at")
    a = p.parse_args(argv)
    commit = a.commit or subprocess.run(["git", "rev-parse", "--short", "HEAD"],
                                        capture_output=True, text=True,
                                        cwd=ROOT).stdout.strip() or "unknown"
    cmd = " ".join(["python -m benchmarks.episodes_combined"] + list(argv or sys.argv[1:]))
    out = Path(a.out)
    rows = []
    if a.merge is not None:
        for f in a.merge:
            rows += [json.loads(s) for s in Path(f).read_text().splitlines() if s.strip()]
        rows.sort(key=lambda r: r["seed"])
    else:
        for seed in _seeds(a.seeds):
            rows.append(run_seed(seed, Path(a.workdir), not a.no_diagnose))
            out.with_suffix(".jsonl").write_text(
                "".join(json.dumps(r, default=str) + "\n" for r in rows))
            out.write_text(table(rows, cmd, commit))  # a partial table after each seed
    out.write_text(table(rows, cmd, commit))
    print(out.read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
