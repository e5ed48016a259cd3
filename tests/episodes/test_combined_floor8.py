"""Everything at once on the floor-winch 8-cable robot of the independent test simulator (issue
38): load-cell and clock effects, AR(1) noise, two hand pushes and four marker glitches that
move and turn the platform (28 s). The episodes stage as ``identify`` calls it locates every
push (start and end within 0.5 s) and every glitch, and finds nothing on the clean twin (the
same recording, the same noise, without them), and nothing beside the glitches' excluded
stretches (a false 1 N episode at 23.48-23.78 s before the persistent columns were anchored,
results/episodes-combined.md).
The whole benchmark, with identify's and diagnose's estimates, is
``benchmarks/episodes_combined.py``."""

from __future__ import annotations

import numpy as np
import pytest


def _episodes(rec, tmp_path, name):
    from tests._testbench import write

    from cdprid.episodes import find_episodes, winch_lengths
    from cdprid.io import align, read_dataset

    ds = read_dataset(write(rec, tmp_path / name))
    sig = align(ds)
    return find_episodes(ds.robot, sig, lengths=winch_lengths(ds, sig.t)).episodes


@pytest.fixture(scope="module")
def combined(tmp_path_factory):
    from tests._testbench import floor8_combined

    rec = floor8_combined(0, n_pushes=2, duration_s=28.0)
    return rec, _episodes(rec, tmp_path_factory.mktemp("combined"), "combined")


def _near(rec, e):
    """Whether episode ``e`` overlaps a push (within 0.5 s) or a glitch's samples."""
    dt = 1.0 / rec.sensors.pose_rate_hz
    spans = [(p.start_s - 0.5, p.end_s + 0.5) for p in rec.pushes]
    spans += [(g.time_s - dt, g.time_s + (g.n_samples + 1) * dt) for g in rec.glitches]
    return any(e.start_s <= b and e.end_s >= a for a, b in spans)


@pytest.mark.slow
def test_pushes_and_glitches_located_and_clean_twin_quiet(combined, tmp_path):
    from tests._testbench import floor8_combined

    rec, eps = combined
    assert len(rec.pushes) == 2 and len(rec.glitches) == 4
    for p in rec.pushes:
        over = [e for e in eps if e.kind == "external_wrench" and e.start_s <= p.end_s
                and e.end_s >= p.start_s]
        assert len(over) == 1
        e = over[0]
        assert abs(e.start_s - p.start_s) <= 0.5 and abs(e.end_s - p.end_s) <= 0.5
        # the located wrench is the push's mean over the window: its direction
        assert np.dot(e.force_N, p.force_N) > 0.95 * e.size_N * np.linalg.norm(p.force_N)
    gl = [e for e in eps if e.kind == "pose_glitches"]
    dt = 1.0 / rec.sensors.pose_rate_hz
    assert [round(e.start_s / dt) for e in gl] == [int(np.ceil(g.time_s / dt - 1e-9))
                                                   for g in rec.glitches]
    assert [e.detail["n_samples"] for e in gl] == [g.n_samples for g in rec.glitches]
    clean = floor8_combined(0, clean=True, n_pushes=2, duration_s=28.0)
    assert _episodes(clean, tmp_path, "clean") == ()


@pytest.mark.slow
def test_no_false_episode_beside_the_glitches(combined):
    """Before the persistent columns were anchored (``PERSISTENT_RIDGE``): a false 1 N
    episode at 23.48-23.78 s, next to the last glitch's excluded stretch."""
    rec, eps = combined
    assert [e.describe() for e in eps if not _near(rec, e)] == []
