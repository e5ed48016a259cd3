"""Issue 40 #2, #4, #11: the plausibility guards live in cdprid.core and apply to identify
and diagnose alike; diagnose refuses (exit 2, before any long work) on data identify warns
about, and names why too few samples are usable (the tension unit, the gaps).

Each case is the package sample recording (8 cables, rotation, 50 Hz poses) with one mistake
made by hand: swapped tension columns, gravity pointing up, constant tensions, quaternions
stored scalar-last, a copied exit line, tensions in kN, many short gaps.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import tomli_w
import tomllib

from cdprid.cli import main


def _read(path):
    lines = path.read_text().splitlines()
    return lines[0].split(","), np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])


def _write(path, head, a):
    path.write_text(",".join(head) + "\n" + "\n".join(",".join(repr(float(v)) for v in r)
                                                      for r in a) + "\n")


def _copy(sample_dataset, tmp_path, name):
    out = tmp_path / name
    shutil.copytree(sample_dataset, out)
    return out


def _swap(ds):
    h, a = _read(ds / "tensions.csv")
    a[:, [1, 2]] = a[:, [2, 1]]
    _write(ds / "tensions.csv", h, a)


def _gravity_up(ds):
    robot = tomllib.loads((ds / "robot.toml").read_text())
    robot["gravity"] = [0.0, 0.0, 9.81]
    (ds / "robot.toml").write_text(tomli_w.dumps(robot))


def _constant(ds):
    h, a = _read(ds / "tensions.csv")
    a[:, 1:] = a[:, 1:].mean(0)
    _write(ds / "tensions.csv", h, a)


def _scalar_last(ds):
    h, a = _read(ds / "pose.csv")
    cols = [h.index(c) for c in ("qw", "qx", "qy", "qz")]
    a[:, cols] = np.roll(a[:, cols], -1, axis=1)  # (qx, qy, qz, qw) under qw..qz labels
    _write(ds / "pose.csv", h, a)


def _copied_exit(ds):
    robot = tomllib.loads((ds / "robot.toml").read_text())
    robot["cable"][1]["exit"] = list(robot["cable"][0]["exit"])
    (ds / "robot.toml").write_text(tomli_w.dumps(robot))


MISTAKES = {  # mistake -> words of the guard that must fire
    "swapped": (_swap, "tau_1 and tau_2 look swapped"),
    "gravity up": (_gravity_up, "far from robot.toml's [platform] mass"),
    "constant": (_constant, "does not vary"),
    "scalar last": (_scalar_last, "scalar-first"),
    "copied exit": (_copied_exit, "cables 1 and 2 have the same exit point"),
}


@pytest.mark.parametrize("name", sorted(MISTAKES))
def test_diagnose_refuses_what_identify_flags(sample_dataset, tmp_path, capsys, name):
    make, words = MISTAKES[name]
    ds = _copy(sample_dataset, tmp_path, "ds")
    make(ds)
    assert main(["identify", str(ds)]) == 0
    out = capsys.readouterr()
    assert words in out.err, out.err  # identify warns ...
    assert main(["diagnose", str(ds), "--quiet"]) == 2  # ... and diagnose refuses
    err = capsys.readouterr().err
    assert words in err and "no effect is named" in err, err


def test_clean_recording_passes_every_guard(sample_dataset):
    from cdprid.core import plausibility_warnings, refusals, refuse_implausible
    from cdprid.io import align, read_dataset

    ds = read_dataset(sample_dataset)
    refuse_implausible(ds)  # no exception
    assert refusals(plausibility_warnings(ds, align(ds))) == []


def test_same_exit_and_attachment_is_refused(sample_dataset, tmp_path, capsys):
    ds = _copy(sample_dataset, tmp_path, "ds")
    robot = tomllib.loads((ds / "robot.toml").read_text())
    robot["cable"][1] = dict(robot["cable"][0])
    (ds / "robot.toml").write_text(tomli_w.dumps(robot))
    for cmd in ("identify", "diagnose"):
        assert main([cmd, str(ds)]) == 2
        err = capsys.readouterr().err
        assert "cables 1 and 2 have the same exit and the same attachment" in err, err


def test_diagnose_names_tensions_in_kn(sample_dataset, tmp_path, capsys):
    ds = _copy(sample_dataset, tmp_path, "ds")
    h, a = _read(ds / "tensions.csv")
    a[:, 1:] /= 1000.0
    _write(ds / "tensions.csv", h, a)
    assert main(["diagnose", str(ds), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "kN" in err and "rows for" not in err, err


def test_diagnose_names_the_gaps_and_the_longest_segment(sample_dataset, tmp_path, capsys):
    ds = _copy(sample_dataset, tmp_path, "ds")
    h, a = _read(ds / "pose.csv")
    keep = np.arange(len(a)) % 60 >= 3  # 3 of every 60 pose samples missing: 1.14 s segments
    _write(ds / "pose.csv", h, a[keep])
    assert main(["diagnose", str(ds), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "gaps" in err and "longest gap-free segment is 1.14 s" in err, err
