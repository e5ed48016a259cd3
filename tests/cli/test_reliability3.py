"""Issue 40, the smaller defects: each reproduced through the CLI (exit 2 and one sentence
before any long work, or the honest report)."""

from __future__ import annotations

import time

from cdprid.cli._main import main


def test_simulate_bounds_samples_not_duration(tmp_path, capsys):
    """#6: 4 h at 100 kHz passed the duration bound and ended in a MemoryError."""
    t0 = time.perf_counter()
    rc = main(["simulate", "--out", str(tmp_path / "o"), "--duration", "14400",
               "--rate-pose", "100000", "--rate-tension", "100000"])
    err = capsys.readouterr().err
    assert rc == 2 and "--rate-pose" in err and "samples" in err, err
    assert time.perf_counter() - t0 < 5.0 and not (tmp_path / "o").exists()
