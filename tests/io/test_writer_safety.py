"""The dataset writer is whole or absent: an interrupted ``write_dataset`` leaves nothing
(moved from the reliability suite, issue 17, into the io tests: it patches io's private writer).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cdprid.io._writer as dsmod
from cdprid.io import write_dataset
from cdprid.model import robot_from_dict
from conftest import ROBOT_CRAFT


def _moving(t):
    return np.column_stack([0.2 * np.sin(0.7 * t), 0.15 * np.cos(0.5 * t), 1.2 + 0.05 * np.sin(t)])


def _tensions(t, m=8, seed=0):
    rng = np.random.default_rng(seed)
    return 30 + 5 * np.sin(np.outer(t, np.ones(m)) + np.arange(m)) + rng.normal(0, 0.1, (len(t), m))


def _write(root, t, pos=None, tau=None, tt=None, **kw):
    robot = robot_from_dict(ROBOT_CRAFT)
    pos = _moving(t) if pos is None else pos
    tt = t if tt is None else tt
    tau = _tensions(tt) if tau is None else tau
    return write_dataset(root, robot, t, pos, tt, tau, **kw)


def test_write_dataset_is_whole_or_absent(tmp_path, monkeypatch):
    calls = {"n": 0}
    real = dsmod._write_csv

    def interrupted(path, cols, vals):
        calls["n"] += 1
        if Path(path).name == "tensions.csv":
            with open(path, "w") as fh:
                fh.write("t,tau_1\n0,1\n")  # half a file, then Ctrl-C
            raise KeyboardInterrupt
        real(path, cols, vals)

    monkeypatch.setattr(dsmod, "_write_csv", interrupted)
    with pytest.raises(KeyboardInterrupt):
        _write(tmp_path / "ds", np.arange(0, 2, 0.01))
    assert calls["n"] == 2 and not (tmp_path / "ds").exists()
    assert list(tmp_path.iterdir()) == []  # no temporary folder left either
