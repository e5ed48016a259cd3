"""`cdprid identify` with a filled compilation cache, per stage, at this tree and a baseline.

Usage: ``python -m benchmarks.speed --only identify [--baseline REV] [--rounds N]
[--dataset DIR]`` (default: the shared ``craft-sim-orbits`` recording, issue 36's goal
< 2 s). Each run is a fresh process, as a user runs the command, byte-compiled modules
included (``PYTHONDONTWRITEBYTECODE`` is dropped from the child's environment: an installed
package has its ``.pyc`` files; without them every run re-compiles ~150 modules' source,
~0.35 s here). Two kinds of process per tree and round, the trees alternated (ABAB: the load
of a shared machine falls on both alike), each tree with its own JAX cache filled by a first
round that is dropped:

* ``cdprid identify DIR --json F --force`` (``python -m cdprid.cli``): the wall and CPU
  figures of the goal;
* the same command run in-process by :func:`child` with the identify pipeline's stages timed
  (the stage functions of ``cdprid.identify._batch`` wrapped by name; a stage a tree lacks is
  left out): imports, the episodes stage, the errors-in-variables fit, the checks and the
  Cramer-Rao bound, and the rest.

The JSON outputs of the two trees are compared number by number (largest relative
difference).
"""

from __future__ import annotations

import json
import math
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT.parent / "shared" / "datasets" / "craft-sim-orbits"

#: (label, functions of cdprid.identify._batch whose time counts for it)
STAGES = [("align, noise model, motion", ("align", "resolve_params", "_choose_model",
                                           "estimate_motion", "_wrench_filter")),
          ("episodes", ("without_episodes",)),
          ("regression", ("_regression",)),
          ("errors-in-variables fit", ("_fit",)),
          ("checks + Cramer-Rao bound", ("_checks",))]


def child(dataset: str, out: str) -> None:
    """Run ``cdprid identify dataset --json out --force`` in this process with its stages
    timed; print one JSON line of stage times (s) on stderr."""
    t0, c0 = time.perf_counter(), time.process_time()
    import cdprid.identify  # noqa: F401  (the face the command imports)
    from cdprid.cli import main

    # the pipeline's module as the face loaded it: its stage functions are wrapped by name
    # (instrumentation, not an API; a stage a tree lacks is left out)
    batch = sys.modules["cdprid.identify._batch"]

    times = {"imports": (time.perf_counter() - t0, time.process_time() - c0)}

    def wrap(name):
        f = getattr(batch, name)

        def g(*a, **k):
            s, c = time.perf_counter(), time.process_time()
            try:
                return f(*a, **k)
            finally:
                w0, c1 = times.get(name, (0.0, 0.0))
                times[name] = (w0 + time.perf_counter() - s, c1 + time.process_time() - c)
        setattr(batch, name, g)

    for _, names in STAGES:
        for n in names:
            if hasattr(batch, n):
                wrap(n)
    t1, c1 = time.perf_counter(), time.process_time()
    try:
        main(["identify", dataset, "--json", out, "--force"])
    except SystemExit as e:
        if e.code not in (0, None):
            raise
    times["command"] = (time.perf_counter() - t1, time.process_time() - c1)
    times["total"] = (time.perf_counter() - t0, time.process_time() - c0)
    print("STAGES " + json.dumps(times), file=sys.stderr, flush=True)


def _env(src: Path, cache: Path) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env.update(PYTHONPATH=f"{src}{os.pathsep}{ROOT}", CDPRID_CACHE_DIR=str(cache),
               CDPRID_QUIET="1", OPENBLAS_NUM_THREADS=env.get("OPENBLAS_NUM_THREADS", "1"))
    return env


def _run(argv, env) -> tuple[float, float, str]:
    """(wall, CPU = user + system of the child, stderr) of one fresh process."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    s = time.perf_counter()
    p = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - s
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"failed: {' '.join(map(str, argv))}\n{p.stderr[-2000:]}")
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime), p.stderr


def _stage_times(raw: dict) -> dict:
    """Exclusive stage times (wall, CPU) in s from a child's raw record."""
    out = {"imports": tuple(raw["imports"])}
    acc = [0.0, 0.0]
    for label, names in STAGES:
        v = tuple(sum(raw.get(n, (0.0, 0.0))[i] for n in names) for i in (0, 1))
        out[label] = v
        acc = [acc[0] + v[0], acc[1] + v[1]]
    out["read, output, rest"] = (raw["command"][0] - acc[0], raw["command"][1] - acc[1])
    out["in-process total"] = tuple(raw["total"])
    return out


def largest_difference(a, b) -> float:
    """Largest relative difference between the numbers of two JSON documents (inf when
    their structure or a non-numeric value differs)."""
    if isinstance(a, dict):
        if set(a) != set(b):
            return math.inf
        return max((largest_difference(a[k], b[k]) for k in a), default=0.0)
    if isinstance(a, list):
        if len(a) != len(b):
            return math.inf
        return max((largest_difference(x, y) for x, y in zip(a, b, strict=True)), default=0.0)
    if isinstance(a, bool) or not isinstance(a, (int, float)):
        return 0.0 if a == b else math.inf
    if a == b or (a != a and b != b):
        return 0.0
    return abs(a - b) / max(abs(a), abs(b))


def run_trees(d: Path, trees: dict, dataset: Path, rounds: int) -> dict:
    """Alternate the trees ``rounds`` + 1 times (the first round fills the caches, dropped).
    Returns {tree: {"cli": [(wall, cpu)], "stages": [dict], "json": path}}."""
    res = {t: {"cli": [], "stages": [], "json": d / f"{t}.json"} for t in trees}
    for k in range(rounds + 1):
        for name, src in trees.items():
            env = _env(src, d / f"cache-{name}")
            w, c, _ = _run([sys.executable, "-m", "cdprid.cli", "identify", str(dataset),
                            "--json", str(res[name]["json"]), "--force"], env)
            _, _, err = _run([sys.executable, "-m", "benchmarks.speed_identify", "--child",
                              str(dataset), str(d / f"{name}-child.json")], env)
            raw = json.loads(next(ln for ln in err.splitlines()
                                  if ln.startswith("STAGES "))[7:])
            if k:
                res[name]["cli"].append((w, c))
                res[name]["stages"].append(_stage_times(raw))
            print(f"round {k} {name}: identify {w:.2f} s wall / {c:.2f} s CPU; in-process "
                  f"{raw['total'][0]:.2f} s wall", flush=True)
    return res


def table(res: dict, trees: list) -> list[str]:
    """Markdown rows: wall and CPU of the command and of each stage, least and median."""
    head = "| | " + " | ".join(f"{t}: wall least / median | {t}: CPU least / median"
                               for t in trees) + " |"
    lines = [head, "|---|" + "---:|---:|" * len(trees)]

    def row(label, per_tree):
        cells = []
        for v in per_tree:
            for i in (0, 1):
                x = [e[i] for e in v]
                cells.append(f"{min(x):.2f} / {statistics.median(x):.2f}")
        lines.append(f"| {label} | " + " | ".join(cells) + " |")

    row("**`cdprid identify`** (fresh process)", [res[t]["cli"] for t in trees])
    for label in res[trees[0]]["stages"][0]:
        row(f"in-process: {label}", [[s[label] for s in res[t]["stages"]] for t in trees])
    return lines


def main_identify(d: Path, rev: str | None, rounds: int, dataset: Path,
                  baseline_tree) -> list[str]:
    """The section of results/speed.md (``baseline_tree(rev, d)`` makes the worktree)."""
    load0 = os.getloadavg()
    wt = baseline_tree(rev, d) if rev else None
    trees = {"this": ROOT / "src", **({rev: wt / "src"} if wt else {})}
    try:
        res = run_trees(d, trees, dataset, rounds)
    finally:
        if wt:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)],
                           capture_output=True)
    load1 = os.getloadavg()
    names = list(trees)
    diff = (largest_difference(json.loads(res[names[0]]["json"].read_text()),
                               json.loads(res[names[1]]["json"].read_text()))
            if len(names) > 1 else 0.0)
    head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True).stdout.strip()
    lines = ["## identify with a filled compilation cache" + (f" ({rev})" if rev else ""), "",
             "Command: `python -m benchmarks.speed --only identify"
             + (f" --baseline {rev}" if rev else "") + f" --rounds {rounds}` at commit "
             f"{head}, {time.strftime('%Y-%m-%d %H:%M')} UTC, on `{dataset.name}`; load "
             f"average (1, 5, 15 min) {load0[0]:.1f} / {load0[1]:.1f} / {load0[2]:.1f} "
             f"before and {load1[0]:.1f} / {load1[1]:.1f} / {load1[2]:.1f} after (2 cores, "
             "shared with other sessions: wall seconds are the loaded machine's, CPU seconds "
             "less so). Each figure from a fresh process with the tree's JAX cache filled by a "
             "first round (dropped) and byte-compiled modules; the trees alternated, "
             f"{rounds} runs each (benchmarks/speed_identify.py). The stages: the command run "
             "in-process with the pipeline's stage functions timed (exclusive; "
             "'imports' from the first line of the script, the interpreter's own start not "
             "included; CPU = the process's user + system time, all its threads).", "",
             *table(res, names), ""]
    if len(names) > 1:
        lines.append(f"JSON outputs of the two trees: largest relative difference {diff:.2g}.")
    print("\n".join(lines), flush=True)
    return lines


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--child":
        child(sys.argv[2], sys.argv[3])
    else:
        raise SystemExit("use: python -m benchmarks.speed --only identify [--baseline REV]")
