"""identify's episodes stage and the winches' lengths stream (issue 38): the energy
balance's gate and winch work get the dataset's stream."""

from __future__ import annotations

import numpy as np

from cdprid.episodes import find_episodes


def test_identify_hands_the_lengths_stream_to_the_episodes(tmp_path, monkeypatch):
    """identify's episodes stage gets the dataset's lengths.csv on the pose times (the
    energy balance's gate and winch work), and None without a stream."""
    from cdprid.cli import main
    from cdprid.identify import _episodes as stage
    from cdprid.io import align, read_dataset

    seen = []

    def spy(robot, sig, **kw):
        seen.append(kw.get("lengths"))
        return find_episodes(robot, sig, **kw)

    monkeypatch.setattr(stage, "find_episodes", spy)
    assert main(["simulate", "--out", str(tmp_path / "s"), "--duration", "12", "--lengths",
                 "--seed", "3"]) == 0
    ds = read_dataset(tmp_path / "s")
    sig = align(ds)
    stage.without_episodes(ds, sig, {}, 0.5, False, [])
    cols, vals = ds.extra["lengths"]
    want = np.column_stack([np.interp(sig.t, vals[:, 0], vals[:, i])
                            for i in range(1, ds.robot.n_cables + 1)])
    assert seen[-1] is not None and np.allclose(seen[-1], want)
    ds.extra.pop("lengths")
    stage.without_episodes(ds, sig, {}, 0.5, False, [])
    assert seen[-1] is None
