"""Peak memory and time of identify, identify --online and diagnose on long recordings.

Builds 100 Hz recordings of 10 min, 30 min and 2 h (a simulated noisy 10 min recording of the
built-in robot, extended by mirrored copies: a time-reversed translation record is again a
valid record, since the tensions depend on the acceleration, not on the velocity sign), runs
each command in a subprocess and reads its peak resident memory (``os.wait4`` rusage,
``ru_maxrss``) and wall time. A watchdog kills a run above ``--mem-cap`` GB or ``--timeout`` s
(reported as such). Writes ``results/benchmarks.md`` (memory section) and prints the table.

Usage::

    PYTHONPATH=src python -m benchmarks.memory [--lengths 10,30,120] [--commands ...]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _rotating_trajectory(work: Path) -> Path:
    """A 10 min paper-orbits trajectory of the built-in robot with a 0.1 rad rotation (the
    full model's recording: a time-reversed rotating record is valid too, since omega x I omega
    and the angular acceleration keep their sign)."""
    from cdprid.io import save_trajectory_csv
    from cdprid.model import craft_like_robot, preset

    out = work / "rotating-10min.csv"
    if not out.exists():
        save_trajectory_csv(preset("paper-orbits", craft_like_robot(), duration=600.0,
                                   rotation_amplitude=0.1), out)
    return out


def _build(base: Path, minutes: int, work: Path, tag: str = "") -> Path:
    from cdprid.io import read_dataset, write_dataset

    out = work / f"rec{tag}-{minutes}min"
    if out.exists():
        return out
    ds = read_dataset(base)
    n = len(ds.pose_t)
    dt = float(np.median(np.diff(ds.pose_t)))
    need = int(round(minutes * 60 / dt))
    reps = int(np.ceil(need / n))
    idx = np.concatenate([np.arange(n) if k % 2 == 0 else np.arange(n)[::-1] for k in range(reps)])
    idx = idx[:need]
    t = np.arange(need) * dt
    q = None if ds.quaternion is None else ds.quaternion[idx]
    rng = np.random.default_rng(minutes)
    tau = ds.tension[idx] + rng.normal(0, 0.05, (need, ds.tension.shape[1]))
    write_dataset(out, ds.robot, t, ds.position[idx], t, tau, quaternion=q, meta=ds.meta)
    return out


def _run(argv: list[str], cap_gb: float, timeout: float) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "CDPRID_QUIET": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "cdprid", *argv], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    state = {"killed": None}

    def watch():
        while proc.poll() is None:
            try:
                with open(f"/proc/{proc.pid}/status") as fh:
                    rss = next(int(line.split()[1]) for line in fh if line.startswith("VmRSS"))
            except (OSError, StopIteration):
                break
            if state["killed"] is None and rss > cap_gb * 1024**2:
                state["killed"] = f"killed above {cap_gb:g} GB"
                proc.kill()
            if state["killed"] is None and time.perf_counter() - t0 > timeout:
                state["killed"] = f"killed after {timeout:g} s"
                proc.kill()
            time.sleep(0.2)

    th = threading.Thread(target=watch, daemon=True)
    th.start()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace").strip()
    th.join(1)
    return {"rc": proc.returncode, "s": time.perf_counter() - t0,
            "peak_gb": usage.ru_maxrss / 1024**2, "note": state["killed"] or
            (err.splitlines()[-1][:120] if proc.returncode else "")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lengths", default="10,30,120", help="minutes, comma-separated")
    ap.add_argument("--commands", default="identify,online,diagnose")
    ap.add_argument("--models", default="translation",
                    help="recordings: translation (paper-orbits), full (the same orbits with a "
                    "0.1 rad rotation: identify picks the 10-parameter model), comma-separated")
    ap.add_argument("--mem-cap", type=float, default=6.0, help="GB; a run above is killed")
    ap.add_argument("--timeout", type=float, default=900.0, help="s; a run longer is killed")
    ap.add_argument("--work", default=None, help="folder for the recordings (default: a temp)")
    ap.add_argument("--out", default=str(ROOT / "results" / "benchmarks.md"))
    ap.add_argument("--heading", default="Memory and time on long recordings (issue 17)",
                    help="the '## ' section of --out this run replaces")
    args = ap.parse_args()
    import jax

    jax.config.update("jax_enable_x64", True)
    work = Path(args.work or tempfile.mkdtemp(prefix="cdprid-mem-"))
    work.mkdir(parents=True, exist_ok=True)
    bases = {}
    for model in args.models.split(","):
        base = work / ("base-10min" if model == "translation" else f"base-{model}-10min")
        src = (["--preset", "paper-orbits"] if model == "translation" else
               ["--trajectory", str(_rotating_trajectory(work))])
        if not base.exists():
            r = _run(["simulate", "--out", str(base), "--duration", "600", *src],
                     args.mem_cap, args.timeout)
            if r["rc"] != 0:
                print(f"simulate failed: {r['note']}")
                return 1
        bases[model] = base
    cmds = {
        "identify": lambda p: ["identify", str(p)],
        "online": lambda p: ["identify", str(p), "--online", "--out-csv",
                             str(work / f"{p.name}-online.csv")],
        "diagnose": lambda p: ["diagnose", str(p), "--quiet"],
    }
    rows = []
    for model, base in bases.items():
        for minutes in (int(x) for x in args.lengths.split(",")):
            rec = _build(base, minutes, work, "" if model == "translation" else f"-{model}")
            for name in args.commands.split(","):
                for f in work.glob(f"{rec.name}-online*"):
                    f.unlink()
                r = _run(cmds[name](rec), args.mem_cap, args.timeout)
                label = f"{name} ({model})" if args.models != "translation" else name
                rows.append((minutes, label, r))
                print(f"{minutes:>5} min  {label:<22} rc={r['rc']:<4} {r['s']:8.1f} s "
                      f"{r['peak_gb']:6.2f} GB  {r['note']}", flush=True)
    commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                            capture_output=True, text=True).stdout.strip()
    lines = [f"## {args.heading}", "",
             f"Command: `PYTHONPATH=src python -m benchmarks.memory --lengths {args.lengths} "
             f"--commands {args.commands} --models {args.models} --heading '{args.heading}'` at "
             f"commit {commit}, {time.strftime('%Y-%m-%d')}, `nice -n 10`, on a 2-core machine "
             "shared with other jobs (times are upper bounds). 100 Hz pose and "
             "tensions; peak = maximum resident set size of the command's process.", "",
             "| recording | command | exit | time (s) | peak memory (GB) | note |",
             "|---|---|---|---|---|---|"]
    for minutes, name, r in rows:
        lines.append(f"| {minutes} min | {name} | {r['rc']} | {r['s']:.1f} | "
                     f"{r['peak_gb']:.2f} | {r['note']} |")
    lines += ["", "Goals (issue 17): identify on 2 h within 1 GB; diagnose on 2 h within 4 GB.", ""]
    _merge(Path(args.out), f"## {args.heading}", "\n".join(lines))
    print(f"wrote {args.out}")
    return 0


def _merge(path: Path, heading: str, section: str) -> None:
    """Replace (or append) one '## ' section of a Markdown file, keeping the others."""
    text = path.read_text() if path.exists() else "# Benchmarks\n"
    parts = text.split("\n## ")
    kept = [parts[0]] + ["## " + p for p in parts[1:] if not ("## " + p).startswith(heading)]
    path.write_text("\n".join(s.rstrip("\n") + "\n" for s in kept) + "\n" + section)


if __name__ == "__main__":
    sys.exit(main())
