"""Import speed of long recordings: a 1-hour bag (goal < 60 s), and the C3D and table importers.

Usage: python -m benchmarks.importers [--minutes 60]  -> prints a table, writes
results/importers.md.

The recording is the package sample dataset (cdprid.data, a simulated 8-cable robot with
rotation) tiled in time to the requested length, pose and tensions at 100 Hz each (the
sample's motion repeated: speed does not depend on the values). Each import runs as a user
would run it: ``cdprid import ...`` in a fresh process (Python and JAX start-up included).
The bags are written with rosbags' own writers (not timed).
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CDPRID = [sys.executable, "-m", "cdprid.cli"]


def _long_dataset(minutes: float, rate: float = 100.0):
    from cdprid import read_dataset
    from cdprid.data import write_sample
    from cdprid.io import Dataset

    with tempfile.TemporaryDirectory() as tmp:
        ds = read_dataset(write_sample(Path(tmp) / "s"))
    n = int(minutes * 60 * rate)
    t = np.arange(n) / rate
    reps = n // len(ds.pose_t) + 1
    pos = np.tile(ds.position, (reps, 1))[:n]
    q = np.tile(ds.quaternion, (reps, 1))[:n]
    tau = np.tile(ds.tension, (n // len(ds.tension_t) + 1, 1))[:n]
    return Dataset(None, ds.robot, t, pos, q, t.copy(), tau), ds


def timed(args):
    t0 = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(CDPRID + args, capture_output=True, text=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"command failed: {' '.join(args)}\n{proc.stderr}")
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return time.perf_counter() - t0, cpu, r1.ru_maxrss / 1024


def _write_c3d(ds, path):
    import ezc3d
    from scipy.spatial.transform import Rotation

    layout = np.array([[0.1, 0.08, 0.06], [-0.1, 0.08, 0.06], [-0.1, -0.08, 0.06],
                       [0.1, -0.08, -0.06], [0.0, 0.0, 0.09]])
    R = Rotation.from_quat(np.column_stack([ds.quaternion[:, 1:], ds.quaternion[:, :1]]))
    V = np.einsum("nab,kb->nka", R.as_matrix(), layout) + ds.position[:, None, :]
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(f"m{i}" for i in range(5))
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, 5, len(ds.pose_t)))
    pts[:3] = np.transpose(V * 1e3, (2, 1, 0))
    c["data"]["points"] = pts
    c["parameters"]["ANALOG"]["RATE"]["value"] = [100.0]
    c["parameters"]["ANALOG"]["LABELS"]["value"] = tuple(f"lc{i}" for i in range(1, 9))
    c["parameters"]["ANALOG"]["UNITS"]["value"] = ["N"] * 8
    c["data"]["analogs"] = ds.tension.T[None]
    c.write(str(path))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=60.0)
    ap.add_argument("--quick", action="store_true", help="a 10-minute recording")
    args = ap.parse_args()
    minutes = 10.0 if args.quick else args.minutes
    from cdprid.io import write_rosbag

    ds, sample = _long_dataset(minutes)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        from cdprid.data import write_sample

        write_sample(d / "sample")
        robot = d / "sample" / "robot.toml"
        cases = []
        for kind, ext in (("ros2-mcap", ""), ("ros2-sqlite", ""), ("ros1", ".bag")):
            bag = d / f"{kind}{ext}"
            t0 = time.perf_counter()
            write_rosbag(ds, bag, kind=kind)
            print(f"wrote {bag.name} in {time.perf_counter() - t0:.1f} s", flush=True)
            cases.append((f"rosbag {kind}: PoseStamped + JointState",
                           ["import", "rosbag", str(bag), "--robot", str(robot), "--pose-topic",
                            "/platform/pose", "--tension-topic", "/cable/tensions"]))
        bag = d / "tf.bag"
        write_rosbag(ds, bag, kind="ros1", pose_type="tf2_msgs/msg/TFMessage",
                     tension_type="std_msgs/msg/Float64MultiArray")
        cases.append(("rosbag ros1: TFMessage + Float64MultiArray (generic deserialiser)",
                      ["import", "rosbag", str(bag), "--robot", str(robot), "--pose-topic", "/tf",
                       "--frames", "base,platform", "--tension-topic", "/cable/tensions"]))
        _write_c3d(ds, d / "rec.c3d")
        cases.append(("c3d: 5 markers (estimated layout) + 8 analog channels",
                      ["import", "c3d", str(d / "rec.c3d"), "--robot", str(robot),
                       "--analog-tensions", ",".join(f"lc{i}" for i in range(1, 9))]))
        for label, argv in cases:
            out = d / f"out{len(rows)}"
            wall, cpu, rss = timed(argv + ["--out", str(out)])
            size = sum(f.stat().st_size for f in Path(argv[2]).rglob("*")) \
                if Path(argv[2]).is_dir() else Path(argv[2]).stat().st_size
            rows.append((label, size / 2**20, wall, cpu, rss))
            print(f"{label}: {wall:.1f} s", flush=True)
    n = len(ds.pose_t)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    lines = [
        "# Importer speed",
        "",
        f"Command: `python -m benchmarks.importers{' --quick' if args.quick else ''}` at commit "
        f"{commit}; machine: {platform.platform()}, {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.1f} at the end of the run. Recording: {minutes:g} min, pose and "
        f"tensions at 100 Hz ({n} + {n} messages; the package sample dataset tiled in time). "
        "Each import is `cdprid import ...` in a fresh process (start-up included), writing a "
        "spec-v1 dataset.",
        "",
        "| importer | input [MiB] | wall [s] | CPU [s] | peak RSS so far [MiB] | goal |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for label, size, wall, cpu, rss in rows:
        goal = "< 60 s for 1 h" if label.startswith("rosbag") and "generic" not in label else ""
        lines.append(f"| {label} | {size:.0f} | {wall:.1f} | {cpu:.1f} | {rss:.0f} | {goal} |")
    lines += ["", "PoseStamped and JointState messages are decoded from their bytes in bulk "
              "(checked against rosbags' deserialiser on the first messages of each topic); "
              "other types go through rosbags' generic deserialiser, about 5x slower per "
              "message. Writing the dataset's CSVs (17 significant digits) is part of every "
              "row. CPU is the import process's own time; wall time also counts the waiting "
              "when other jobs load the machine (see the load average). Peak RSS is the "
              "largest child process so far in the run (getrusage), so it is a running "
              "maximum (JAX start-up alone is about 400 MiB); the bag importers hold the raw "
              "messages in memory."]
    text = "\n".join(lines) + "\n"
    print(text)
    out = ROOT / "results" / "importers.md"
    from cdprid.base import write_text

    write_text(out, text)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
