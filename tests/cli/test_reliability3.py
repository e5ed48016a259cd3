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


def test_lengths_csv_with_a_nan_is_refused_with_its_line(tmp_path, capsys):
    """#13: a lengths.csv with one `nan` was dropped silently (cable_elasticity never tested)."""
    out = tmp_path / "ds"
    assert main(["simulate", "--out", str(out), "--duration", "11", "--lengths"]) == 0
    lines = (out / "lengths.csv").read_text().splitlines()
    fields = lines[5].split(",")
    fields[3] = "nan"
    lines[5] = ",".join(fields)
    (out / "lengths.csv").write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    for cmd in (["identify", str(out)], ["diagnose", str(out), "--quiet"]):
        assert main(cmd) == 2
        err = capsys.readouterr().err
        assert "lengths.csv" in err and "line 6" in err and "l_3" in err, err


def _c3d(path):
    import ezc3d
    import numpy as np

    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(f"m{i}" for i in range(4))
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, 4, 50))
    pts[:3] = np.random.default_rng(0).normal(0, 100, (3, 4, 50))
    c["data"]["points"] = pts
    c.write(str(path))
    return path.read_bytes()


def test_c3d_cut_inside_its_parameters_is_called_truncated(sample_dataset, tmp_path, capsys):
    """#12: a C3D cut inside its parameter section was blamed on the markers."""
    import pytest

    pytest.importorskip("ezc3d")
    data = _c3d(tmp_path / "whole.c3d")
    start = (data[0] - 1) * 512
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[: start + 700])  # inside the parameter section
    rc = main(["import", "c3d", str(cut), "--robot", str(sample_dataset / "robot.toml"),
               "--out", str(tmp_path / "o"), "--tensions", str(sample_dataset / "tensions.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and "truncated" in err and "parameter section" in err, err
    assert "marker" not in err
