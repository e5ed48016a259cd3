"""Reliability regression suite (issue 17): bad and edge inputs across the commands.

Each case asserts what the outside reliability run counts: no overwritten file (checksums),
no half-written output that parses, no invented sample, no traceback, exit code 2 with one
sentence for a user mistake (before any work), rc 1 only for internal errors.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cdprid.base import OutputError, UserError, atomic_dir, atomic_file, check_output
from cdprid.cli import main
from cdprid.cli._exits import is_user_error
from cdprid.core import estimate_motion, segment_mask
from cdprid.io import DatasetError, align, read_csv_stream, read_dataset
from conftest import moving_position, smooth_tensions, write_moving_dataset

SRC = str(Path(__file__).resolve().parents[2] / "src")


def _sha(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


_moving, _tensions, _write = moving_position, smooth_tensions, write_moving_dataset


@pytest.fixture
def ds_path(tmp_path):
    return _write(tmp_path / "ds", np.arange(0, 20, 0.01))


def _one_sentence_rc2(capsys, argv):
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert "Traceback" not in err and "internal error" not in err
    assert len(err.splitlines()) >= 1 and "error" in err.splitlines()[-1]
    return err.splitlines()[-1]


# ----------------------------------------------------------------------------- options

BAD_OPTIONS = [
    (["identify", "{ds}", "--trim", "-5"], "--trim"),
    (["identify", "{ds}", "--t-start", "nan"], "--t-start"),
    (["identify", "{ds}", "--t-end", "inf"], "--t-end"),
    (["identify", "{ds}", "--forgetting", "0", "--online"], "--forgetting"),
    (["identify", "{ds}", "--forgetting", "1.5", "--online"], "--forgetting"),
    (["identify", "{ds}", "--params", "{tmp}/nofile.json"], "does not exist"),
    (["diagnose", "{ds}", "--alpha", "0"], "--alpha"),
    (["diagnose", "{ds}", "--alpha", "2"], "--alpha"),
    (["diagnose", "{ds}", "--n-null", "0"], "--n-null"),
    (["diagnose", "{ds}", "--max-effects", "-1"], "--max-effects"),
    (["diagnose", "{ds}", "--train-until", "nan"], "--train-until"),
    (["simulate", "--out", "{tmp}/s", "--rate-pose", "0.01"], "--rate-pose"),
    (["simulate", "--out", "{tmp}/s", "--duration", "-1"], "--duration"),
    (["simulate", "--out", "{tmp}/s", "--noise-pos", "-1e-3"], "--noise-pos"),
    (["simulate", "--out", "{tmp}/s", "--trajectory", "{tmp}/none.csv"], "does not exist"),
    (["import", "uacdpr", "--vicon", "{tmp}/v.txt", "--robot-log", "{tmp}/l.mat", "--config",
      "{tmp}/c.mat", "--out", "{tmp}/o"], "does not exist"),
    (["calibrate", "--vicon", "{csv}", "--robot-log", "{csv}", "--config", "{csv}",
      "--yaw-starts", "0"], "--yaw-starts"),
    (["calibrate", "--vicon", "{csv}", "--robot-log", "{csv}", "--config", "{csv}",
      "--subsample", "-3"], "--subsample"),
    (["tune", "--seeds", "0"], "--seeds"),
    (["tune", "--max-steps", "-2"], "--max-steps"),
    (["tune", "--noise-std", "nan"], "--noise-std"),
    (["excite", "{tmp}/none.toml"], "missing"),
    (["excite", "{ds}/robot.toml", "--starts", "0"], "--starts"),
    (["differentiate", "{tmp}/none.csv", "--out", "{tmp}/o.csv"], "does not exist"),
    (["differentiate", "{csv}", "--out", "{tmp}/o.csv", "--params", "{tmp}/no.json"],
     "does not exist"),
]


@pytest.mark.parametrize("argv,needle", BAD_OPTIONS, ids=[" ".join(a[:3]) for a, _ in BAD_OPTIONS])
def test_invalid_options_exit_2_one_sentence(tmp_path, ds_path, capsys, argv, needle):
    csv = tmp_path / "in.csv"
    csv.write_text("t,p\n0,1\n")
    argv = [a.format(ds=ds_path, tmp=tmp_path, csv=csv) for a in argv]
    t0 = time.perf_counter()
    line = _one_sentence_rc2(capsys, argv)
    assert needle in line
    assert time.perf_counter() - t0 < 20  # refused at parse time, before any work
    assert not (tmp_path / "s").exists() and not (tmp_path / "o.csv").exists()


def test_invalid_environment_variable(monkeypatch, capsys, ds_path):
    monkeypatch.setenv("CDPRID_SCAN_UNROLL", "abc")
    line = _one_sentence_rc2(capsys, ["identify", str(ds_path)])
    assert "CDPRID_SCAN_UNROLL" in line


def test_bad_json_and_non_object(tmp_path, capsys):
    (tmp_path / "p.json").write_text("{oops")
    csv = tmp_path / "in.csv"
    np.savetxt(csv, np.column_stack([np.arange(50) * 0.01, np.arange(50)]), delimiter=",",
               header="t,p", comments="")
    line = _one_sentence_rc2(capsys, ["differentiate", str(csv), "--out", str(tmp_path / "o"),
                                      "--params", str(tmp_path / "p.json")])
    assert "not valid JSON" in line and not (tmp_path / "o").exists()


def test_user_vs_internal_error_classification():
    assert is_user_error(UserError("x")) and is_user_error(DatasetError("x"))
    assert is_user_error(OutputError("x"))
    try:
        np.stack([])  # a ValueError raised inside numpy: internal, not the user's fault
    except ValueError as exc:
        assert not is_user_error(exc)
    assert not is_user_error(RuntimeError("x")) and not is_user_error(TypeError("x"))
    assert is_user_error(PermissionError(13, "Permission denied", "/x"))


# ----------------------------------------------------------------------------- outputs


def test_differentiate_refuses_existing_and_bad_out_paths(tmp_path, capsys):
    csv = tmp_path / "in.csv"
    t = np.arange(0, 2, 0.01)
    np.savetxt(csv, np.column_stack([t, t**2]), delimiter=",", header="t,p", comments="")
    out = tmp_path / "o.csv"
    out.write_text("precious\n")
    sha = _sha(out)
    assert "already exists" in _one_sentence_rc2(capsys, ["differentiate", str(csv), "--out",
                                                          str(out)])
    assert _sha(out) == sha
    assert "does not exist" in _one_sentence_rc2(
        capsys, ["differentiate", str(csv), "--out", str(tmp_path / "no" / "o.csv")])
    assert "folder" in _one_sentence_rc2(capsys, ["differentiate", str(csv), "--out",
                                                  str(tmp_path)])
    assert main(["differentiate", str(csv), "--out", str(out), "--force"]) == 0
    assert np.loadtxt(out, delimiter=",", skiprows=1).shape == (len(t), 3)
    assert not list(tmp_path.glob(".*part"))


def test_simulate_out_existing_file_refused(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("keep")
    line = _one_sentence_rc2(capsys, ["simulate", "--out", str(f), "--duration", "11"])
    assert str(f) in line and f.read_text() == "keep"


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="root can write into read-only folders")
def test_read_only_folder_is_a_user_error(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        with pytest.raises(OutputError, match="not writable"):
            check_output(ro / "x.json", flag="--json")
    finally:
        ro.chmod(0o700)


def test_write_dataset_refuses_then_replaces_with_force(tmp_path):
    root = _write(tmp_path / "ds", np.arange(0, 2, 0.01))
    sha = _sha(root / "pose.csv")
    with pytest.raises(FileExistsError):
        _write(root, np.arange(0, 3, 0.01))
    assert _sha(root / "pose.csv") == sha
    _write(root, np.arange(0, 3, 0.01), overwrite=True)
    assert read_dataset(root).pose_t.size == 300
    with pytest.raises(OutputError, match="is a file"):
        _write(root / "pose.csv", np.arange(0, 2, 0.01), overwrite=True)


def test_atomic_file_and_dir_leave_nothing_on_failure(tmp_path):
    target = tmp_path / "a.txt"
    with pytest.raises(RuntimeError), atomic_file(target) as fh:
        fh.write("half")
        raise RuntimeError("boom")
    assert not target.exists()
    with pytest.raises(RuntimeError), atomic_dir(tmp_path / "d") as d:
        (d / "x").write_text("1")
        raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- reading


def test_bom_and_quoted_header_are_read(tmp_path, ds_path):
    ref_cols, ref = read_csv_stream(ds_path / "pose.csv")
    text = (ds_path / "pose.csv").read_text()
    head, rest = text.split("\n", 1)
    quoted = ",".join(f'"{c}"' for c in head.split(","))
    (ds_path / "pose.csv").write_bytes(b"\xef\xbb\xbf" + (quoted + "\n" + rest).encode())
    cols, vals = read_csv_stream(ds_path / "pose.csv")
    assert cols == ref_cols and np.array_equal(vals, ref)
    assert read_dataset(ds_path).position.shape == (2000, 3)


def test_slow_path_names_line_after_fast_reader_fails(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("t,x\n0,1\n0.1,2\n0.2,inf\n")
    with pytest.raises(DatasetError, match="line 4, column 'x'"):
        read_csv_stream(p)


# ----------------------------------------------------------------------------- plausibility

IMPOSSIBLE = {
    "negated": (lambda tau: -tau, "negative"),
    "zero": (lambda tau: 0 * tau, "zero"),
    "huge": (lambda tau: np.where(np.arange(tau.size).reshape(tau.shape) == 77, 1e308, tau),
             "not plausible"),
}


@pytest.mark.parametrize("kind", list(IMPOSSIBLE))
def test_impossible_tensions_refused(tmp_path, capsys, kind):
    fn, needle = IMPOSSIBLE[kind]
    t = np.arange(0, 20, 0.01)
    root = _write(tmp_path / "ds", t, tau=fn(_tensions(t)))
    line = _one_sentence_rc2(capsys, ["identify", str(root)])
    assert needle in line and "tensions.csv" in line


def test_stationary_platform_refused(tmp_path, capsys):
    t = np.arange(0, 20, 0.01)
    root = _write(tmp_path / "ds", t, pos=np.tile([0.1, 0.2, 1.2], (len(t), 1)))
    assert "does not move" in _one_sentence_rc2(capsys, ["identify", str(root)])


def test_one_dead_load_cell_is_a_warning(tmp_path):
    t = np.arange(0, 20, 0.01)
    tau = _tensions(t)
    tau[:, 3] = 0
    sig = align(read_dataset(_write(tmp_path / "ds", t, tau=tau)))
    assert any("cable(s) 4" in n for n in sig.notes)


# ----------------------------------------------------------------------------- gaps

GAPS = {"20s": 20.0, "5min": 300.0}


@pytest.mark.parametrize("gap", list(GAPS))
def test_pose_gap_is_never_bridged(tmp_path, gap):
    dt = 0.01
    t1 = np.arange(0, 30, dt)
    t2 = t1[-1] + GAPS[gap] + np.arange(0, 40, dt)
    t = np.concatenate([t1, t2])
    tt = np.arange(0, t[-1] + dt / 2, dt)
    ds = read_dataset(_write(tmp_path / "ds", t, tt=tt))
    whole = set(np.round(t / dt).astype(int))
    # default: the longest segment only, reported with its share
    sig = align(ds)
    assert sig.n_segments == 1 and np.isclose(sig.t[0], t2[0]) and len(sig.t) == len(t2)
    assert any("gap" in n for n in sig.notes) and any("longest" in n for n in sig.notes)
    # split: both segments, no sample inside the gap (no invented sample)
    sig = align(ds, split_gaps=True)
    assert sig.segments == ((0, len(t1)), (len(t1), len(t)))
    assert set(np.round(sig.t / dt).astype(int)) <= whole
    assert not np.any((sig.t > t1[-1] + 1e-9) & (sig.t < t2[0] - 1e-9))
    # each segment differentiated alone: exact velocity of the smooth motion away from edges
    mo = estimate_motion(sig, "savgol", angular=False)
    keep = segment_mask(sig.t, sig.segments, 1.0)
    assert abs(keep.sum() - (len(t) - 4 * 100)) <= 4 and np.array_equal(keep, mo.keep(1.0))
    v_true = np.column_stack([0.14 * np.cos(0.7 * sig.t), -0.075 * np.sin(0.5 * sig.t),
                              0.05 * np.cos(sig.t)])
    assert np.max(np.abs(mo.velocity[keep] - v_true[keep])) < 1e-4


def test_tension_gap_and_partial_coverage_reported(tmp_path):
    dt = 0.01
    t = np.arange(0, 60, dt)
    tt = np.concatenate([np.arange(10, 25, dt), np.arange(35, 60, dt)])  # 10 s hole, late start
    sig = align(read_dataset(_write(tmp_path / "ds", t, tt=tt)), split_gaps=True)
    assert any("16.7 % of the pose samples dropped" in n for n in sig.notes)
    assert any("tension stream has 1 gap" in n for n in sig.notes)
    assert not np.any((sig.t > 25 + 1e-9) & (sig.t < 35 - 1e-9)) and sig.n_segments == 2


def test_short_jitter_resampled_and_reported(tmp_path):
    rng = np.random.default_rng(3)
    t = np.cumsum(np.full(2000, 0.01) + rng.uniform(-0.002, 0.002, 2000))
    sig = align(read_dataset(_write(tmp_path / "ds", t, tt=np.arange(0, 21, 0.001))))
    assert sig.resampled and sig.n_segments == 1 and any("jitter" in n for n in sig.notes)
    assert np.allclose(np.diff(sig.t), sig.dt)


# ----------------------------------------------------------------------------- Ctrl-C


def _big_csv(path: Path, n: int) -> None:
    t = np.arange(n) * 0.01
    np.savetxt(path, np.column_stack([t, np.sin(t), np.cos(t), t % 3]), delimiter=",",
               header="t,a,b,c", comments="", fmt="%.10g")


def _wait_for_part_file(proc, folder: Path, timeout: float = 300.0) -> bool:
    """Wait until the command has started writing (a ``.part`` file exists): deterministic,
    unlike a sleep, since the interpreter and its signal handlers are up by then. False if the
    process ended first."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if any(p.name.endswith(".part") for p in folder.iterdir()):
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.005)
    raise AssertionError("the command neither started writing nor ended")


@pytest.mark.parametrize("signame, code", [("SIGINT", 130), ("SIGTERM", 143), ("SIGHUP", 129)])
def test_signal_during_write_leaves_nothing_that_parses(tmp_path, signame, code):
    """Ctrl-C, kill and a closed terminal: exit 128 + signal, no output, no ``.part`` left."""
    src = tmp_path / "in.csv"
    _big_csv(src, 300_000)
    out = tmp_path / "out.csv"
    env = {**os.environ, "PYTHONPATH": SRC, "CDPRID_QUIET": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "cdprid", "differentiate", str(src), "--method",
                             "savgol", "--out", str(out)], env=env, stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    if _wait_for_part_file(proc, tmp_path):
        proc.send_signal(getattr(signal, signame))
    _, err = proc.communicate(timeout=600)  # a hang guard, generous for a loaded machine
    assert "Traceback" not in err
    if proc.returncode == 0:  # finished between the check and the signal: output complete
        assert np.loadtxt(out, delimiter=",", skiprows=1).shape == (300_000, 7)
    else:
        assert proc.returncode == code and not out.exists(), (proc.returncode, err)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def test_identify_json_after_gap_keeps_truth_like_result(tmp_path):
    """identify on a recording with a 20 s gap: the gap is reported in the notes and JSON."""
    dt = 0.01
    t = np.concatenate([np.arange(0, 30, dt), 50 + np.arange(0, 30, dt)])
    root = _write(tmp_path / "ds", t, tt=np.arange(0, 80, dt))
    out = tmp_path / "id.json"
    assert main(["identify", str(root), "--json", str(out)]) == 0
    notes = json.loads(out.read_text())["notes"]
    assert any("gap" in n for n in notes)


# ------------------------------------------------------------- outputs of every command


CROSS_OUTPUTS = [
    (["identify", "{ds}", "--json", "{keep}"], "already exists"),
    (["identify", "{ds}", "--json", "{tmp}/no/x.json"], "does not exist"),
    (["identify", "{ds}", "--json", "{tmp}"], "folder"),
    (["diagnose", "{ds}", "--json", "{keep}"], "already exists"),
    (["tune", "--noise-std", "1e-3", "--json", "{keep}"], "already exists"),
    (["simulate", "--out", "{keep}", "--duration", "11"], "is a file"),
]


@pytest.mark.parametrize("argv,needle", CROSS_OUTPUTS,
                         ids=[" ".join(a[:1] + a[-2:-1]) + str(i) for i, (a, _) in
                              enumerate(CROSS_OUTPUTS)])
def test_every_command_checks_outputs_before_work(tmp_path, ds_path, capsys, argv, needle):
    keep = tmp_path / "keep.json"
    keep.write_text("{}\n")
    sha = _sha(keep)
    argv = [a.format(ds=ds_path, tmp=tmp_path, keep=keep) for a in argv]
    t0 = time.perf_counter()
    assert needle in _one_sentence_rc2(capsys, argv)
    assert time.perf_counter() - t0 < 30 and _sha(keep) == sha
