"""Dataset reader errors (spec v1 'Errors') and the `cdprid identify` command."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import tomllib

from cdprid.cli import main
from cdprid.io import DatasetError, align, read_dataset, sampling_report, write_dataset
from cdprid.model import robot_from_dict
from conftest import ROBOT_CRAFT


def _edit(path, fn):
    lines = path.read_text().splitlines()
    path.write_text("\n".join(fn(lines)) + "\n")


def _corrupt(kind, root):
    """Make one malformed copy; return the substring the error sentence must contain."""
    if kind == "missing-file":
        (root / "tensions.csv").unlink()
        return "tensions.csv"
    if kind == "missing-folder":
        shutil.rmtree(root)
        return "does not exist"
    if kind == "nan":
        _edit(root / "pose.csv",
              lambda L: L[:5] + [L[5].replace(L[5].split(",")[2], "nan", 1)] + L[6:])
        return "not finite"
    if kind == "text":
        _edit(root / "tensions.csv", lambda L: L[:7] + [L[7].rsplit(",", 1)[0] + ",abc"] + L[8:])
        return "line 8"
    if kind == "time-backwards":
        def f(L):
            a, b = L[10].split(",", 1), L[11].split(",", 1)
            L[10], L[11] = b[0] + "," + a[1], a[0] + "," + b[1]
            return L
        _edit(root / "pose.csv", f)
        return "strictly increasing"
    if kind == "tension-columns":
        _edit(root / "tensions.csv", lambda L: [",".join(s.split(",")[:-1]) for s in L])
        return "8 cables"
    if kind == "broken-toml":
        (root / "robot.toml").write_text("name = 'x'\n[[cable]\nexit = [1,2,3]\n")
        return "TOML"
    if kind == "empty-stream":
        _edit(root / "tensions.csv", lambda L: L[:1])
        return "empty"
    if kind == "quaternion-norm":
        _edit(root / "pose.csv",
              lambda L: L[:3] + [",".join(L[3].split(",")[:4] + ["1.1", "0", "0", "0"])]
              + L[4:])
        return "norm"
    if kind == "no-overlap":
        _edit(root / "tensions.csv", lambda L: L[:1] + [
            ",".join([f"{100 + float(s.split(',')[0]):.4f}"] + s.split(",")[1:]) for s in L[1:]])
        return "do not overlap"
    if kind == "missing-column":
        _edit(root / "pose.csv",
              lambda L: [",".join(s.split(",")[:3] + s.split(",")[4:]) for s in L])
        return "'z'"
    raise AssertionError(kind)


KINDS = ["missing-file", "missing-folder", "nan", "text", "time-backwards", "tension-columns",
         "broken-toml", "empty-stream", "quaternion-norm", "no-overlap", "missing-column"]


@pytest.mark.parametrize("kind", KINDS)
def test_reader_rejects_malformed_with_one_sentence(small_ds, kind):
    needle = _corrupt(kind, small_ds)
    with pytest.raises(DatasetError) as info:
        read_dataset(small_ds)
    msg = str(info.value)
    assert "\n" not in msg and needle in msg
    assert str(small_ds) in msg


@pytest.mark.parametrize("kind", KINDS)
def test_cli_exit_code_2_and_one_line(small_ds, kind, capsys):
    _corrupt(kind, small_ds)
    rc = main(["identify", str(small_ds)])
    err = capsys.readouterr().err.strip()
    assert rc == 2
    assert len(err.splitlines()) == 1 and err.startswith("cdprid: error:")
    assert "Traceback" not in err


def test_console_script_no_traceback(small_ds):
    _corrupt("text", small_ds)
    proc = subprocess.run([sys.executable, "-m", "cdprid.cli", "identify", str(small_ds)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_write_read_roundtrip_and_no_overwrite(small_ds):
    ds = read_dataset(small_ds)
    assert ds.position.shape == (500, 3) and ds.tension.shape == (500, 8)
    assert np.allclose(ds.quaternion[:, 0], 1.0)
    with pytest.raises(FileExistsError):
        write_dataset(small_ds, ds.robot, ds.pose_t, ds.position, ds.tension_t, ds.tension)


def test_alignment_interpolates_tensions_and_resamples_pose(tmp_path):
    robot = robot_from_dict(ROBOT_CRAFT)
    rng = np.random.default_rng(1)
    tp = np.cumsum(np.full(400, 0.01) + rng.uniform(-0.002, 0.002, 400))
    pos = np.column_stack([np.sin(tp), np.cos(tp), 1 + 0.1 * tp])
    tt = np.arange(0.0, 5.0, 0.001)
    tau = np.column_stack([10 + np.sin(3 * tt + i) for i in range(8)])
    write_dataset(tmp_path / "d", robot, tp, pos, tt, tau)
    ds = read_dataset(tmp_path / "d")
    assert not sampling_report(ds.pose_t)["uniform"]
    sig = align(ds)
    assert sig.resampled and any("not uniform" in n for n in sig.notes)
    assert sampling_report(sig.t)["uniform"]
    assert np.allclose(sig.position,
                       np.column_stack([np.sin(sig.t), np.cos(sig.t), 1 + 0.1 * sig.t]),
                       atol=1e-5)
    assert np.allclose(sig.tension[:, 2], 10 + np.sin(3 * sig.t + 2), atol=1e-5)


def test_identify_craft_orbits_against_truth(tmp_path, craft_orbits):
    root = craft_orbits
    out = tmp_path / "id.json"
    assert main(["identify", str(root), "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    truth = tomllib.loads((root / "meta.toml").read_text())["truth"]
    assert set(res) >= {"model", "parameters", "sigma_rho", "cond", "cond_scaled", "n_samples"}
    assert list(res["parameters"]) == ["m", "mxG", "myG", "mzG"]
    m = res["parameters"]["m"]["value"]
    mzG = res["parameters"]["mzG"]["value"]
    assert abs(m - truth["mass"]) / truth["mass"] < 0.005
    assert abs(mzG - truth["first_moment"][2]) / abs(truth["first_moment"][2]) < 0.05
    for p in res["parameters"].values():
        assert p["std"] > 0 and np.isclose(p["rel_std_percent"], 100 * p["std"] / abs(p["value"]))
    assert res["n_samples"] > 4000 and res["cond"] >= res["cond_scaled"] >= 1


def test_identify_bad_options_exit_2(small_ds, capsys):
    assert main(["identify", str(small_ds), "--differentiator", "nope"]) == 2
    assert "unknown differentiator" in capsys.readouterr().err
    assert main(["identify", str(small_ds), "--params", "{bad json"]) == 2
    assert "--params" in capsys.readouterr().err
    # the platform never rotates: the inertia is not identifiable, said in one sentence
    assert main(["identify", str(small_ds), "--model", "full"]) == 2
    err = capsys.readouterr().err
    assert "not identifiable" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("given", [None, "3"])
def test_console_main_blas_threads(monkeypatch, given):
    """The executable runs NumPy's OpenBLAS single-threaded unless the user set the variable
    (its spinning worker threads took the cores XLA needed on a shared machine)."""
    import cdprid.cli._main as cli_main

    if given is None:
        monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    else:
        monkeypatch.setenv("OPENBLAS_NUM_THREADS", given)
    seen = []

    def fake_main() -> int:
        seen.append(os.environ.get("OPENBLAS_NUM_THREADS"))
        return 0

    monkeypatch.setattr(cli_main, "main", fake_main)
    monkeypatch.setattr(cli_main, "_end_process", lambda rc: rc)  # not this pytest process
    assert cli_main.console_main() == 0
    assert seen == [given or "1"]
