"""The dataset writer is whole or absent: an interrupted ``write_dataset`` leaves nothing
(moved from the reliability suite, issue 17, into the io tests: it patches io's private writer).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import cdprid.io._writer as dsmod
from conftest import write_moving_dataset as _write


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
