"""Wall-clock figures of the main commands (cold start included), side by side in one run.

Usage: python -m benchmarks.speed [--only commands|startup|diagnose|stages|identify]
[--baseline REV] [--load K] [--seed S] [--rounds N] [--dataset DIR]
prints tables and updates results/benchmarks.md (each section replaced, the others kept).
``--only stages`` times `diagnose` per stage on the floor-winch 8-cable case of issue 37
(``tests._testbench.floor8_case(S)``, default S = 4), twice in one process (the first run
with its JIT compile time), at this tree and with ``--baseline REV`` at REV alternated
(``benchmarks/speed_stages.py``); it writes results/speed.md.
``--only identify`` times `cdprid identify` with a filled compilation cache and per stage on
``--dataset`` (default the shared craft-sim-orbits, issue 36's goal < 2 s), ``--rounds`` runs
of each tree alternated with ``--baseline REV`` (``benchmarks/speed_identify.py``); it
writes results/speed.md.
``--only diagnose`` times `cdprid diagnose` on two CRAFT-like recordings (the second start of
the search runs), with ``--baseline REV`` at this tree and at REV alternated in one run, with
``--load K`` beside K busy processes (a shared machine; its own section).
The start-up section times `cdprid --help` and `cdprid identify` in fresh processes, with an
empty persistent JAX compilation cache (cold) and with the cache filled by a first run (warm);
issue 13 goals: --help < 0.5 s, identify < 2 s cold (1.8 s and 3.0 s before the lazy imports).
Each command runs in a fresh process (JAX import and compilation included), as a user
would run it. Goals from the issues: simulate 52 s @ 100 Hz < 10 s; diagnose a 52 s dataset
<= 30 s; excitation optimiser <= 30 s (see results/excitation.md for its own breakdown).
"""

from __future__ import annotations

import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CDPRID = [sys.executable, "-m", "cdprid.cli"]


def _wall_cpu(argv, env=None, cwd=ROOT) -> tuple[float, float]:
    """Run ``argv`` in a fresh process: (wall, CPU = user + system of the child) in s."""
    t0 = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(argv, cwd=cwd, capture_output=True, text=True, env=env)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"command failed: {' '.join(map(str, argv))}\n{proc.stderr}")
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return time.perf_counter() - t0, cpu


def timed(args, cwd):
    wall, cpu = _wall_cpu(CDPRID + args, cwd=cwd)
    return wall, cpu, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024


def _baseline_tree(rev: str, d: Path) -> Path:
    """A detached worktree of ``rev`` (its ``src`` is timed beside this one's)."""
    tree = d / f"baseline-{rev}"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), rev],
                   capture_output=True, check=True)
    return tree


def _alternate(d: Path, rev: str | None, cases: dict, n: int) -> dict:
    """Each command of ``cases`` (label -> cdprid arguments) at this tree and at ``rev`` (a
    detached worktree; None: this tree only), alternated in one run (ABAB: the machine's load
    falls on both alike), each in a fresh process with the tree's ``src`` and its own JAX
    cache; the first round fills the caches and is dropped. {(label, tree): [(wall, CPU)]}."""
    trees = {"this": ROOT / "src"}
    wt = _baseline_tree(rev, d) if rev else None
    if wt:
        trees[rev] = wt / "src"
    res: dict = {}
    try:
        for k in range(n + 1):
            for label, args in cases.items():
                for name, src in trees.items():
                    env = {**os.environ, "PYTHONPATH": str(src), "CDPRID_QUIET": "1",
                           "CDPRID_CACHE_DIR": str(d / f"cache-{name}")}
                    wc = _wall_cpu(CDPRID + args, env)
                    if k:
                        res.setdefault((label, name), []).append(wc)
    finally:
        if wt:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)],
                           capture_output=True)
    return res


def _side_by_side(d: Path, rev: str, n: int = 5) -> list[str]:
    """``cdprid identify`` with a filled cache at this tree and at ``rev``, alternated in one
    run; least wall and CPU of ``n`` each."""
    res = _alternate(d, rev, {"identify": ["identify", str(d / "st")]}, n)
    this, base = ([min(wc[i] for wc in res[("identify", t)]) for i in (0, 1)]
                  for t in ("this", rev))
    print(f"side by side: identify (filled cache) this {this[0]:.2f} s wall / {this[1]:.2f} s "
          f"CPU, {rev} {base[0]:.2f} / {base[1]:.2f}", flush=True)
    return ["", f"Side by side in the same run (`--baseline {rev}`; `cdprid identify` with a "
            f"filled cache, the two trees alternated, least of {n} each):", "",
            "| tree | wall [s] | CPU [s] |", "|---|---:|---:|",
            f"| this commit | {this[0]:.2f} | {this[1]:.2f} |",
            f"| {rev} | {base[0]:.2f} | {base[1]:.2f} |",
            f"| ratio | {this[0] / base[0]:.2f} | {this[1] / base[1]:.2f} |"]


def _diagnose(d: Path, rev: str | None, n: int = 3, load: int = 0) -> list[str]:
    """``cdprid diagnose DIR --quiet`` on two CRAFT-like recordings where the search's second
    start runs, at this tree and at ``rev`` alternated (see :func:`_alternate`); least and
    median wall and CPU of ``n`` each after a first round that fills the caches. ``load``:
    that many busy Python processes run beside it (a machine shared with other jobs)."""
    import numpy as np

    from benchmarks.diagnosis import PAIRS, simulate_case
    from benchmarks.many_effects import craft_case

    pair = PAIRS["anchor+gain"](np.random.default_rng([3, 8, len("anchor+gain")]), 8)
    recs = {"many effects, case 1": simulate_case(craft_case(1), 1, d),
            "anchor + gain, seed 3": simulate_case(pair, 3, d)}
    load0 = os.getloadavg()[0]
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(load)]
    try:
        res = _alternate(d, rev, {k: ["diagnose", str(v), "--quiet"] for k, v in recs.items()},
                         n)
    finally:
        for b in busy:
            b.kill()
            b.wait()
    trees = ["this", rev] if rev else ["this"]
    stats = {key: [f(wc[i] for wc in v) for i in (0, 1) for f in (min, statistics.median)]
             for key, v in res.items()}
    lines = [_diagnose_heading(load, rev), "",
             "Command: `python -m benchmarks.speed --only diagnose"
             + (f" --baseline {rev}" if rev else "") + (f" --load {load}" if load else "")
             + f"` at commit {_head()}, "
             f"{time.strftime('%Y-%m-%d')}; load average {load0:.1f} before and "
             f"{os.getloadavg()[0]:.1f} after the runs (2 cores"
             + (f"; {load} busy Python processes ran beside every command" if load else "")
             + "). `cdprid diagnose DIR --quiet`"
             " in a fresh process (CLI wall and CPU = user + system), "
             + ("the two trees alternated in one run, " if rev else "")
             + f"each tree with its own JAX cache filled by a first round (dropped); least and "
             f"median of {n}. Recordings (52 s, `rich`, noise 0.3 mm / 0.7 N / 0.2 mrad): the "
             "CRAFT-like many-effects case 1 of benchmarks/many_effects.py (delay, friction on "
             "all pulleys, offset, gain, exit-point error, rotations) and the anchor + gain pair "
             "of benchmarks/diagnosis.py, seed 3 (tests/diagnosis/test_restart.py).", "",
             "| recording | tree | wall least [s] | wall median [s] | CPU least [s] | "
             "CPU median [s] |", "|---|---|---:|---:|---:|---:|"]
    for label in recs:
        for t in trees:
            v = stats[(label, t)]
            name = "this commit" if t == "this" else t
            lines.append(f"| {label} | {name} | " + " | ".join(f"{x:.1f}" for x in v) + " |")
            print(f"{label:24s} {name:12s} wall {v[0]:6.1f} / {v[1]:6.1f} s  "
                  f"CPU {v[2]:6.1f} / {v[3]:6.1f} s (least / median)", flush=True)
        if rev:
            r = [a / b for a, b in zip(stats[(label, "this")], stats[(label, rev)], strict=True)]
            lines.append(f"| {label} | ratio | " + " | ".join(f"{x:.2f}" for x in r) + " |")
    return lines


def _diagnose_heading(load: int, rev: str | None) -> str:
    """One section per load and baseline (so a run against another baseline keeps this one)."""
    return ((f"## diagnose beside {load} busy processes" if load else "## diagnose side by side")
            + (f" ({rev})" if rev else ""))


def _head() -> str:
    return subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True).stdout.strip()


def _startup(d: Path, baseline: str | None = None) -> list[str]:
    """`cdprid --help`, `import cdprid` and `cdprid identify` (empty vs filled JAX cache);
    with ``baseline`` (a git revision) identify is also timed at that revision, alternated."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "CDPRID_QUIET": "1"}

    def run(argv, extra=None):
        return _wall_cpu(argv, {**env, **(extra or {})})

    def best(argv, extra=None, n=3):
        return min((run(argv, extra) for _ in range(n)), key=lambda wc: wc[1])

    subprocess.run(CDPRID + ["simulate", "--preset", "paper-orbits", "--out", str(d / "st"),
                             "--seed", "1"], cwd=ROOT, capture_output=True, env=env, check=True)
    cache = d / "jax-cache"
    rows = [
        ("cdprid --help", best(CDPRID + ["--help"]), "< 0.5 s (was 1.8 s)"),
        ("python -c 'import cdprid'", best([sys.executable, "-c", "import cdprid"]), ""),
        ("cdprid identify, empty JAX cache (first run)",
         run(CDPRID + ["identify", str(d / "st")], {"CDPRID_CACHE_DIR": str(cache)}),
         "< 2 s (was 3.0 s)"),
        ("cdprid identify, JAX cache filled (later runs)",
         best(CDPRID + ["identify", str(d / "st")], {"CDPRID_CACHE_DIR": str(cache)}),
         "< 2 s (was 3.0 s)"),
        ("cdprid identify, cache off", best(CDPRID + ["identify", str(d / "st")],
                                             {"CDPRID_CACHE_DIR": "off"}, n=1), ""),
    ]
    for n, (w, c), g in rows:
        print(f"{n:50s} wall {w:6.2f} s  CPU {c:6.2f} s  {g}", flush=True)
    load = os.getloadavg()[0]
    lines = ["## Start-up time (issue 13)", "",
             "Command: `python -m benchmarks.speed --only startup"
             + (f" --baseline {baseline}" if baseline else "") + "`; least CPU of 3 fresh "
             f"processes (identify with an empty cache: one run); load average {load:.1f} at "
             "the end of the run (2 cores shared: wall times on a busy machine are upper "
             "bounds; CPU = user + system time of the process, less sensitive to the load).",
             "", "| command | wall [s] | CPU [s] | goal |", "|---|---:|---:|---|"]
    lines += [f"| {n} | {w:.2f} | {c:.2f} | {g} |" for n, (w, c), g in rows]
    imp = _importtime(env)
    for n, v in imp:
        print(f"import time of {n:10s} {v:6.2f} s", flush=True)
    lines += ["", "Import time on identify's path (`python -X importtime -c \"import "
              "cdprid.cli._main, cdprid.identify._batch, cdprid.io._dataset\"`, cumulative time of "
              "each top-level package the first time it is imported, least of 3; scipy 0 means "
              "it is not imported):", "",
              "| package | import time [s] |", "|---|---:|"]
    lines += [f"| {n} | {v:.2f} |" for n, v in imp]
    if baseline:
        lines += _side_by_side(d, baseline)
    return lines


def _importtime(env: dict) -> list[tuple[str, float]]:
    """Cumulative import time (s) of jax, scipy and cdprid on identify's import path.

    From ``python -X importtime`` of the modules ``cdprid identify`` imports (the CLI, the
    pipeline, the dataset reader); a package's entries count unless nested in one of its own
    (jax imported inside cdprid counts for jax and inside cdprid's time too).
    """
    code = "import cdprid.cli._main, cdprid.identify._batch, cdprid.io._dataset"
    best = None
    for _ in range(3):
        p = subprocess.run([sys.executable, "-X", "importtime", "-c", code], cwd=ROOT,
                           capture_output=True, text=True, env=env, check=True)
        tot = {"jax": 0.0, "scipy": 0.0, "cdprid": 0.0}
        rows = [ln.split("|") for ln in p.stderr.splitlines()
                if ln.startswith("import time:") and "|" in ln]
        stack: list[tuple[int, str]] = []  # ancestors, walking parents-first (reverse order)
        for _, cum, name in reversed(rows):
            depth = len(name) - len(name.lstrip())
            top = name.strip().split(".")[0]
            while stack and stack[-1][0] >= depth:
                stack.pop()
            # count a package's entry unless it is nested inside an entry of the same package
            if top in tot and all(t != top for _, t in stack):
                tot[top] += int(cum) / 1e6
            stack.append((depth, top))
        best = tot if best is None else {k: min(v, tot[k]) for k, v in best.items()}
    return list(best.items())


def _merge(path: Path, heading: str, section: str) -> None:
    """Replace (or append) one '## ' section of a Markdown file, keeping the others."""
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    parts = text.split("\n## ")
    kept = [parts[0]] + ["## " + p for p in parts[1:] if not ("## " + p).startswith(heading)]
    path.write_text("\n".join(x.rstrip("\n") + "\n" for x in kept) + "\n" + section + "\n")


def _stages(d: Path, rev: str | None, seed: int, rounds: int) -> list[str]:
    """Per-stage table of ``diagnose`` on floor8 (:mod:`benchmarks.speed_stages`)."""
    from benchmarks.speed_stages import run_trees, same_findings, table

    load0 = os.getloadavg()[0]
    wt = _baseline_tree(rev, d) if rev else None
    trees = {"this": ROOT / "src", **({rev: wt / "src"} if wt else {})}
    try:
        res = run_trees(d, trees, seed, rounds)
    finally:
        if wt:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(wt)],
                           capture_output=True)
    diff = same_findings(res)
    lines = [f"## diagnose per stage, floor8 seed {seed}" + (f" ({rev})" if rev else ""), "",
             "Command: `python -m benchmarks.speed --only stages"
             + (f" --baseline {rev}" if rev else "") + f" --seed {seed} --rounds {rounds}` at "
             f"commit {_head()}, {time.strftime('%Y-%m-%d %H:%M')}; load average {load0:.1f} "
             f"before and {os.getloadavg()[0]:.1f} after (2 cores, shared). The 8-cable "
             "floor-winch recording of issue 37 (`tests._testbench.floor8_case`, 52 s) "
             "diagnosed by `cdprid.diagnosis.diagnose` twice in one fresh process per tree "
             + ("(the trees alternated, " if rev else "(")
             + f"{rounds} round(s), least total kept): run 1 pays the JIT compilation (in "
             "brackets: JAX's trace, lowering and compile events in that stage; the "
             "persistent cache of each tree filled by its first process), run 2 does not. "
             "Stage times are exclusive (a stage nested in another counts for the inner "
             "one).", "", *table(res), "",
             "Findings (effects, sizes, intervals, held-out rms, unexplained sizes) of every "
             f"run of every tree: largest relative difference {diff:.2g}."]
    print("\n".join(lines), flush=True)
    return lines


def main() -> int:
    import argparse

    ap = argparse.ArgumentParser(description="Speed of the main commands.")
    ap.add_argument("--only", choices=["commands", "startup", "diagnose", "stages", "identify"],
                    default=None)
    ap.add_argument("--seed", type=int, default=4, help="--only stages: floor8 case seed")
    ap.add_argument("--rounds", type=int, default=1,
                    help="--only stages / identify: alternations (identify: default 5)")
    ap.add_argument("--dataset", type=Path, default=None,
                    help="--only identify: the recording (default: ../shared's orbits)")
    ap.add_argument("--baseline", default=None, metavar="REV",
                    help="also time identify (startup) or diagnose (--only diagnose) at this "
                         "git revision, alternated with this tree")
    ap.add_argument("--load", type=int, default=0, metavar="K",
                    help="--only diagnose: K busy processes run beside it (a shared machine)")
    args = ap.parse_args()
    if args.load < 0:
        ap.error("--load must be >= 0")
    out = ROOT / "results" / "benchmarks.md"
    if args.only == "identify":
        from benchmarks.speed_identify import DEFAULT, main_identify

        out = ROOT / "results" / "speed.md"
        ds = (args.dataset or DEFAULT).resolve()
        if not ds.is_dir():
            ap.error(f"--dataset {ds}: not a folder (the shared datasets sit beside the repo)")
        rounds = 5 if args.rounds == 1 and "--rounds" not in sys.argv else args.rounds
        with tempfile.TemporaryDirectory() as tmp:
            lines = main_identify(Path(tmp), args.baseline, rounds, ds, _baseline_tree)
            _merge(out, lines[0], "\n".join(lines))
        print(f"wrote {out}")
        return 0
    if args.only == "stages":
        out = ROOT / "results" / "speed.md"
        with tempfile.TemporaryDirectory() as tmp:
            lines = _stages(Path(tmp), args.baseline, args.seed, args.rounds)
            _merge(out, lines[0], "\n".join(lines))
        print(f"wrote {out}")
        return 0
    if args.only == "diagnose":
        with tempfile.TemporaryDirectory() as tmp:
            _merge(out, _diagnose_heading(args.load, args.baseline),
                   "\n".join(_diagnose(Path(tmp), args.baseline, load=args.load)))
        print(f"wrote {out}")
        return 0
    if args.only in (None, "startup"):
        with tempfile.TemporaryDirectory() as tmp:
            _merge(out, "## Start-up time", "\n".join(_startup(Path(tmp), args.baseline)))
        if args.only == "startup":
            print(f"wrote {out}")
            return 0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        cases = [
            ("simulate paper-orbits (52 s, 100 Hz)",
             ["simulate", "--preset", "paper-orbits", "--out", str(d / "po"), "--seed", "1"],
             "< 10 s"),
            ("identify (euler-filtfilt, 4 parameters)", ["identify", str(d / "po")], ""),
            ("identify (sihd2-cascade)", ["identify", str(d / "po"), "--differentiator",
                                          "sihd2-cascade"], ""),
            ("identify --online (SIHD + RLS scan)", ["identify", str(d / "po"), "--online",
                                                     "--out-csv", str(d / "on.csv")], ""),
            ("simulate rich + hidden tension_gain",
             ["simulate", "--preset", "rich", "--out", str(d / "hid"), "--seed", "7",
              "--noise-rot", "0.0002", "--effect", "tension_gain", "--param", "cable=3",
              "--param", "gain=1.06"], ""),
            ("diagnose (52 s dataset, cold start)", ["diagnose", str(d / "hid"), "--quiet"],
             "<= 30 s"),
        ]
        for name, args, goal in cases:
            wall, cpu, rss = timed(args, ROOT)
            rows.append((name, wall, cpu, rss, goal))
            print(f"{name:45s} wall {wall:6.1f} s  cpu {cpu:6.1f} s  peak rss {rss:7.0f} MiB  "
                  f"{goal}", flush=True)
    load = os.getloadavg()[0]
    lines = ["# Speed of the main commands", "",
             f"Command: `python -m benchmarks.speed`; machine: {platform.platform()}, "
             f"{os.cpu_count()} cores, load average {load:.1f} at the end of the run; "
             "each command in a fresh process (cold start: imports and JAX compilation included).",
             "", "| command | wall [s] | CPU [s] | peak RSS of children [MiB] | goal |",
             "|---|---:|---:|---:|---|"]
    lines += [f"| {n} | {w:.1f} | {c:.1f} | {r:.0f} | {g} |" for n, w, c, r, g in rows]
    lines += ["", "Differentiator speed ratios (scan vs Python loop vs scipy) are in "
              "[differentiators.md](differentiators.md); online latency per sample in "
              "[online.md](online.md); optimiser vs SLSQP in [excitation.md](excitation.md)."]
    text = out.read_text() if out.exists() else ""
    rest = text.split("\n## ", 1)[1] if "\n## " in text else ""
    out.write_text("\n".join(lines) + "\n" + ("\n## " + rest if rest else ""))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
