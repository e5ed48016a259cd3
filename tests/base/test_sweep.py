"""Monte-Carlo sweeps as tasks (issue 26): resumable JSONL log, the same records serially and on
a 2-worker local Dask cluster, a killed sweep completes only its missing runs."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from cdprid.base import load_log, run_sweep


def identify_run(spec: dict) -> dict:
    """One Monte-Carlo run: a short noisy simulation (seed from the spec), identified."""
    import tempfile

    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset
    from cdprid.model import SIX_SUSPENDED, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    rob = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(rob, preset("rich", rob, duration=20.0), None,
                   noise=SensorNoise(position_m=3e-4, tension_N=0.5), seed=spec["seed"])
    with tempfile.TemporaryDirectory() as tmp:
        rep = identify_dataset(read_dataset(write_simulation(sim, Path(tmp) / "d")),
                               bound=False)
    return {"seed": spec["seed"], "x": [float(v) for v in rep.result.x]}


def counted_run(spec: dict) -> dict:
    """A cheap run that leaves a mark per call (to count what a sweep executed)."""
    Path(spec["marks"], f"{spec['key']}.{os.getpid()}.{time.monotonic_ns()}").touch()
    return {"value": spec["seed"] ** 2}


def _specs(n, **extra):
    return [{"key": f"run-{k}", "seed": k, **extra} for k in range(n)]


def test_sweep_skips_what_the_log_holds(tmp_path):
    marks = tmp_path / "marks"
    marks.mkdir()
    log = tmp_path / "log.jsonl"
    specs = _specs(6, marks=str(marks))
    first = run_sweep(specs[:3], counted_run, log, progress=None)
    assert [r["value"] for r in first] == [0, 1, 4]
    with open(log, "a") as fh:
        fh.write('{"key": "run-5", "val')  # a line cut by a kill: ignored, run again
    out = run_sweep(specs, counted_run, log, progress=None)
    assert [r["value"] for r in out] == [k * k for k in range(6)]
    runs = sorted(p.name.split(".")[0] for p in marks.iterdir())
    assert runs == [f"run-{k}" for k in range(6)]  # each run executed once
    assert set(load_log(log)) == {s["key"] for s in specs}
    with pytest.raises(ValueError, match="unique"):
        run_sweep(specs + specs[:1], counted_run, log, progress=None)


def test_a_killed_sweep_completes_only_its_missing_runs(tmp_path):
    """Kill a running sweep (SIGKILL, after its second record), start it again. The first
    run blocks from its third spec on, so the kill always finds 2 records, however loaded
    the machine (no race between the poll and the runs)."""
    marks = tmp_path / "marks"
    marks.mkdir()
    log = tmp_path / "log.jsonl"
    script = tmp_path / "sweep.py"
    script.write_text(textwrap.dedent(f"""
        import os, time
        from tests.base.test_sweep import counted_run, _specs
        from cdprid.base import run_sweep

        def slow(spec):
            if os.environ.get("BLOCK_FROM_THIRD") and int(spec["key"].split("-")[1]) >= 2:
                time.sleep(3600)  # killed here
            return counted_run(spec)

        run_sweep(_specs(8, marks={str(marks)!r}), slow, {str(log)!r}, progress=None)
    """))
    # the repository root on the path: the script imports this file as tests.base.test_sweep
    root = str(Path(__file__).resolve().parents[2])
    path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
    proc = subprocess.Popen([sys.executable, str(script)],
                            env={**os.environ, "PYTHONPATH": path, "BLOCK_FROM_THIRD": "1"})
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if log.exists() and len(load_log(log)) >= 2:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    before = set(load_log(log))
    assert before == {"run-0", "run-1"}
    env = {k: v for k, v in os.environ.items() if k != "BLOCK_FROM_THIRD"}
    env["PYTHONPATH"] = path
    subprocess.run([sys.executable, str(script)], check=True, timeout=120, env=env)
    after = load_log(log)
    assert set(after) == {f"run-{k}" for k in range(8)}
    executed = [p.name.split(".")[0] for p in marks.iterdir()]
    # the killed run was blocked before it started its work: every run executed once
    assert sorted(executed) == [f"run-{k}" for k in range(8)]
    assert len([line for line in log.read_text().splitlines() if line.strip()]) >= 8


@pytest.mark.slow
def test_local_cluster_gives_the_serial_records(tmp_path):
    pytest.importorskip("distributed")
    specs = _specs(4)
    serial = run_sweep(specs, identify_run, tmp_path / "serial.jsonl", progress=None)
    dask = run_sweep(specs, identify_run, tmp_path / "dask.jsonl", workers=2, progress=None)
    assert [r["key"] for r in dask] == [s["key"] for s in specs]
    for a, b in zip(serial, dask, strict=True):
        assert a["x"] == pytest.approx(b["x"], rel=1e-12, abs=1e-15), (a, b)
    lines = [json.loads(x) for x in (tmp_path / "dask.jsonl").read_text().splitlines()]
    assert sorted(r["key"] for r in lines) == sorted(s["key"] for s in specs)
