"""Issue 40 #9: run_sweep refuses a worker count below 1 at once (a LocalCluster of -2
workers waited forever) and names an unreachable scheduler in one sentence."""

from __future__ import annotations

import socket
import time

import pytest

from cdprid.base import UserError, _sweep, run_sweep


def _run(spec):
    return {"x": spec["key"]}


@pytest.mark.parametrize("workers", [-2, 0, 1.5, True])
def test_bad_worker_count_is_refused_before_anything_starts(tmp_path, workers):
    t0 = time.perf_counter()
    with pytest.raises(UserError, match="positive number of local workers"):
        run_sweep([{"key": "a"}], _run, tmp_path / "log.jsonl", workers=workers)
    assert time.perf_counter() - t0 < 1.0 and not (tmp_path / "log.jsonl").exists()


def test_unreachable_scheduler_is_one_sentence(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.setattr(_sweep, "SCHEDULER_TIMEOUT_S", 2.0)
    with pytest.raises(UserError, match=f"tcp://127.0.0.1:{port}.*cannot connect"):
        run_sweep([{"key": "a"}], _run, tmp_path / "log.jsonl",
                  scheduler=f"tcp://127.0.0.1:{port}", progress=None)
