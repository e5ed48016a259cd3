"""`cdprid diagnose` on the real UACDPR recording: the case study section of results/real-uacdpr.md.

What the paper's model gets wrong on FreeMotion02, each cause named with its size, the
held-out gain of each step, the models the data cannot tell apart and what remains. The
section between the markers ``<!-- diagnose:start -->`` and ``<!-- diagnose:end -->`` of
``--out`` is replaced (appended the first time); the rest of the file is left as it is.

Run (the import takes about a minute, the diagnosis about a minute)::

    python -m studies.real_uacdpr_diagnose [--dataset DIR] [--json DIAGNOSIS.json]
        [--out results/real-uacdpr.md]

``--dataset``: a folder written by ``cdprid import uacdpr`` (default: import
../shared/datasets/uacdpr-freemotion02 with UACDPR_LAB3.mat into a temporary folder);
``--json``: reuse the JSON of an earlier ``cdprid diagnose`` on that folder.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import tomllib

from cdprid.report import format_values as _fmt

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "datasets" / "uacdpr-freemotion02"
START, END = "<!-- diagnose:start -->", "<!-- diagnose:end -->"


def _cdprid(*args) -> None:
    subprocess.run([sys.executable, "-m", "cdprid", *map(str, args)], check=True)


def section(d: dict, meta: dict, command: str) -> list[str]:
    """The markdown lines of the case study from a diagnosis JSON and the dataset's meta."""
    info, nz = d["info"], meta.get("nuisance", {})
    lines = [START, "", "## What `cdprid diagnose` finds on this recording", "",
             f"Command: `{command}`; {info['n_samples']} aligned samples, held-out figures by "
             f"{info['heldout']}; the platform rotates {info['rotation_deg']:.0f} deg, so the "
             f"base model is the {info['base_model']} model (as `identify --model auto`).", "",
             f"Held-out force residual (taut samples): base model "
             f"{d['base']['heldout_residual_rms']:.2f} N -> extended model "
             f"{d['extended']['heldout_residual_rms']:.2f} N (goal 5 N). A step's "
             "'before' differs from the previous step's 'after' when findings accepted in "
             "between were removed later by backward elimination (listed under what "
             "remains).", "",
             "| step | effect | size | 95 % interval | held-out rms before -> after "
             "(weighted units) | indistinguishable here from |", "|---|---|---|---|---|---|"]
    for k, f in enumerate(d["findings"], 1):
        lines.append(f"| {k} | {f['effect']} | {_fmt(f['parameters'])} | {_fmt(f['interval'])} "
                     f"| {f['heldout_rms_before']:.3f} -> {f['heldout_rms_after']:.3f} | "
                     f"{', '.join(f['aliases']) or '-'} |")
    if "delay_s" in nz:
        dl = [f for f in d["findings"] if f["effect"] == "time_delay"]
        if dl:
            lo, hi = dl[0]["interval"]["delay_s"]
            std = (hi - lo) / (2 * 1.96)
            s_imp = nz.get("delay_std_s", 0.0)
            gap = abs(dl[0]["parameters"]["delay_s"] - nz["delay_s"]) / (std**2 + s_imp**2)**0.5
            lines += ["", f"Clock offset: the importer's nuisance fit gives "
                      f"{1e3 * nz['delay_s']:.1f} +- {1e3 * s_imp:.1f} ms, the diagnosis "
                      f"{1e3 * dl[0]['parameters']['delay_s']:.1f} +- {1e3 * std:.1f} ms: "
                      f"{gap:.1f} combined std apart."]
    comp = d.get("competing_models", [])
    lines += ["", f"Competing models ({len(comp)} of {info.get('competing_models_tried', 0)} "
              "alternatives tried predict the held-out data as well):", ""]
    lines += [f"- {c['by']} ({_fmt(c['parameters'])}) instead of {c['replaces']}: held-out "
              f"force {c['heldout_force_rms_N']:.2f} N ({100 * c['relative_difference']:+.1f} %, "
              f"p = {c['p_worse']:.2g} that it is worse)" for c in comp] or ["- none"]
    lines += ["", "Checked and not named:", ""]
    lines += [f"- {u['effect']} {_fmt(u['parameters'])}, 95 % interval {_fmt(u['interval'])} "
              f"(p = {u['p_value']:.2g} alone: {u['why']})" for u in d["not_named"]] or ["- none"]
    lines += ["", "What remains (structure no finding explains, force rms in N):", ""]
    lines += [f"- {u['where']}: {u['size']:.2f} N, like {u['correlates_with']}"
              + (f"; would be separated by {u['separated_by']}" if u.get("separated_by") else "")
              for u in d["unexplained"]] or ["- nothing significant"]
    w = info.get("weight_at_rest")
    if w:
        lines += ["", f"Weight at rest ({w['n_samples']} samples): {w['raw_kg']:.2f} kg from "
                  f"the raw tensions, {w['corrected_kg']:.2f} kg with the extended model's "
                  "sensor corrections; identified m "
                  f"{d['extended']['parameters']['m']['value']:.2f} kg."]
    return lines + ["", END]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--dataset", type=Path, default=None)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "real-uacdpr.md")
    args = ap.parse_args()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        ds = args.dataset
        if ds is None:
            ds = Path(tmp) / "freemotion02"
            _cdprid("import", "uacdpr", "--vicon", DATA / "FreeMotion02.txt", "--robot-log",
                    DATA / "FreeMotion02_exp.mat", "--config", DATA / "UACDPR_LAB3.mat",
                    "--out", ds)
        js = args.json
        if js is None:
            js = Path(tmp) / "diagnosis.json"
            _cdprid("diagnose", ds, "--json", js)
        d = json.loads(js.read_text())
        meta = tomllib.loads((ds / "meta.toml").read_text())
    lines = section(d, meta, "cdprid import uacdpr ... --config UACDPR_LAB3.mat --out DIR; "
                             "cdprid diagnose DIR --json D.json")
    rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True).stdout.strip()
    how = (f"the diagnosis JSON {args.json.name} reused" if args.json is not None
           else f"{time.perf_counter() - t0:.0f} s")
    lines.insert(-2, f"\nGenerated by `python -m studies.real_uacdpr_diagnose` at {rev} "
                     f"({how}).")
    text = args.out.read_text() if args.out.exists() else ""
    new = "\n".join(lines)
    if START in text and END in text:
        text = text[:text.index(START)] + new + text[text.index(END) + len(END):]
    else:
        text = text.rstrip("\n") + "\n\n" + new + "\n"
    tmp_out = args.out.with_suffix(".tmp")
    tmp_out.write_text(text)
    tmp_out.replace(args.out)
    print(new)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
