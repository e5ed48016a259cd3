"""Wall-clock figures of the main commands (cold start included), side by side in one run.

Usage: python benchmarks/speed.py  -> prints a table and writes results/benchmarks.md.
Each command runs in a fresh process (JAX import and compilation included), as a user
would run it. Goals from the issues: simulate 52 s @ 100 Hz < 10 s; diagnose a 52 s dataset
<= 30 s; excitation optimiser <= 30 s (see results/excitation.md for its own breakdown).
"""

from __future__ import annotations

import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CDPRID = [sys.executable, "-m", "cdprid.cli"]


def timed(args, cwd):
    t0 = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(CDPRID + args, cwd=cwd, capture_output=True, text=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"command failed: {' '.join(args)}\n{proc.stderr}")
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return time.perf_counter() - t0, cpu, r1.ru_maxrss / 1024


def main() -> int:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        cases = [
            ("simulate paper-orbits (52 s, 100 Hz)", ["simulate", "--preset", "paper-orbits",
                                                       "--out", str(d / "po"), "--seed", "1"], "< 10 s"),
            ("identify (euler-filtfilt, 4 parameters)", ["identify", str(d / "po")], ""),
            ("identify (sihd2-cascade)", ["identify", str(d / "po"), "--differentiator",
                                          "sihd2-cascade"], ""),
            ("identify --online (SIHD + RLS scan)", ["identify", str(d / "po"), "--online",
                                                     "--out-csv", str(d / "on.csv")], ""),
            ("simulate rich + hidden tension_gain", ["simulate", "--preset", "rich", "--out",
                                                     str(d / "hid"), "--seed", "7", "--noise-rot",
                                                     "0.0002", "--effect", "tension_gain",
                                                     "--param", "cable=3", "--param", "gain=1.06"], ""),
            ("diagnose (52 s dataset, cold start)", ["diagnose", str(d / "hid"), "--quiet"], "<= 30 s"),
        ]
        for name, args, goal in cases:
            wall, cpu, rss = timed(args, ROOT)
            rows.append((name, wall, cpu, rss, goal))
            print(f"{name:45s} wall {wall:6.1f} s  cpu {cpu:6.1f} s  peak rss {rss:7.0f} MiB  {goal}",
                  flush=True)
    load = os.getloadavg()[0]
    lines = ["# Speed of the main commands", "",
             f"Command: `python benchmarks/speed.py`; machine: {platform.platform()}, "
             f"{os.cpu_count()} cores, load average {load:.1f} at the end of the run; "
             "each command in a fresh process (cold start: imports and JAX compilation included).",
             "", "| command | wall [s] | CPU [s] | peak RSS of children [MiB] | goal |",
             "|---|---:|---:|---:|---|"]
    lines += [f"| {n} | {w:.1f} | {c:.1f} | {r:.0f} | {g} |" for n, w, c, r, g in rows]
    lines += ["", "Differentiator speed ratios (scan vs Python loop vs scipy) are in "
              "[differentiators.md](differentiators.md); online latency per sample in "
              "[online.md](online.md); optimiser vs SLSQP in [excitation.md](excitation.md)."]
    out = ROOT / "results" / "benchmarks.md"
    out.write_text("\n".join(lines) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
