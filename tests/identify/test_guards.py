"""Plausibility guards (issue 25): a mistaken input gives a relevant warning or exit 2, never a
confident number in silence. Each case is a reported mistake, made on a copy of the package's
sample dataset (simulated, 8 cables, truth known), and checked through ``cdprid identify``."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest

from cdprid.cli import main


def _csv_edit(path, fn):
    header = path.read_text().splitlines()[0].split(",")
    a = np.loadtxt(path, delimiter=",", skiprows=1)
    np.savetxt(path, fn(a), delimiter=",", header=",".join(header), comments="", fmt="%.12g")


def _kn(d):
    _csv_edit(d / "tensions.csv", lambda a: np.column_stack([a[:, 0], a[:, 1:] / 1000]))


def _mm(d):
    _csv_edit(d / "pose.csv", lambda a: np.column_stack([a[:, 0], a[:, 1:4] * 1000, a[:, 4:]]))


def _z_down(d):
    _csv_edit(d / "pose.csv", lambda a: np.column_stack([a[:, 0], a[:, 1], -a[:, 2], -a[:, 3],
                                                         a[:, 4:]]))


def _gravity(d):
    p = d / "robot.toml"
    text = p.read_text()
    new = re.sub(r"gravity = \[[^\]]*\]", "gravity = [0.0, 0.0, -98.1]", text)
    p.write_text(new if new != text else "gravity = [0.0, 0.0, -98.1]\n" + text)


def _late(d):
    _csv_edit(d / "tensions.csv", lambda a: np.column_stack([a[:, 0] + 1.0, a[:, 1:]]))


def _swap12(d):
    _csv_edit(d / "tensions.csv", lambda a: a[:, [0, 2, 1] + list(range(3, a.shape[1]))])


def _ms(d):
    _csv_edit(d / "tensions.csv", lambda a: np.column_stack([a[:, 0] * 1000, a[:, 1:]]))


@pytest.mark.parametrize("edit, words", [
    (_kn, ["mass", "tension unit"]),
    (_mm, ["outside the box", "position unit"]),
    (_z_down, ["outside the box", "z pointing down"]),
    (_gravity, ["|gravity| is 98.1"]),
    (_late, ["residual", "clock"]),
    (_ms, ["ms vs s"]),
    (_swap12, ["tau_1 and tau_2 look swapped"]),
], ids=["kN", "mm", "z-down", "gravity", "clock-1s-late", "time-in-ms", "swapped-columns"])
def test_mistaken_input_is_named(sample_dataset, tmp_path, edit, words, capsys):
    d = tmp_path / "ds"
    shutil.copytree(sample_dataset, d)
    edit(d)
    out = tmp_path / "id.json"
    rc = main(["identify", str(d), "--json", str(out)])
    capsys.readouterr()
    assert rc == 0
    warnings = " ".join(json.loads(out.read_text())["warnings"])
    for w in words:
        assert w in warnings, (w, warnings)


def test_clean_data_raise_no_guard(sample_dataset, tmp_path, capsys):
    out = tmp_path / "id.json"
    assert main(["identify", str(sample_dataset), "--json", str(out)]) == 0
    capsys.readouterr()
    guards = ("outside the box", "far from robot.toml", "|gravity|", "too small for the position",
              "ms vs s", "times what the tension noise", "look swapped")
    warnings = json.loads(out.read_text())["warnings"]
    assert not [w for w in warnings if any(g in w for g in guards)], warnings


def test_tiny_motion_is_called_too_weak_and_diagnose_refuses(tmp_path, capsys):
    """A 5 mm circle with 0.2 mm noise: mzG came out 17 sigma off with no warning."""
    from cdprid.model import Orbit, craft_like_robot, orbit_sequence
    from cdprid.simulation import simulate, write_simulation

    traj = orbit_sequence([Orbit(radius=0.005, frequency=0.25, duration=16.0, azimuth=0.0,
                                 tilt=0.0)], rest=np.array([0.0, 0.0, 1.2]))
    d = write_simulation(simulate(craft_like_robot(), traj, seed=0), tmp_path / "circle")
    out = tmp_path / "id.json"
    assert main(["identify", str(d), "--json", str(out)]) == 0
    assert any("too small for the position noise" in w
               for w in json.loads(out.read_text())["warnings"])
    capsys.readouterr()
    assert main(["diagnose", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert "no effect is named" in err and len(err.splitlines()) == 1


def test_degenerate_geometry_exits_2(sample_dataset, tmp_path, capsys):
    d = tmp_path / "ds"
    shutil.copytree(sample_dataset, d)
    toml = (d / "robot.toml").read_text()
    toml = re.sub(r"exit = \[[^\]]*\]", "exit = [0.0, 0.0, 3.0]", toml)
    (d / "robot.toml").write_text(toml)
    assert main(["identify", str(d)]) == 2
    err = capsys.readouterr().err
    assert "exits" in err and "nan" not in err.lower()


def _typo_limit(d):
    p = d / "robot.toml"
    text = p.read_text()
    p.write_text(text.replace("tension_max", "tension_mx", 1) if "tension_max" in text
                 else text + "\n[limits]\ntension_mx = 400.0\n")


def _semicolons(d):
    p = d / "pose.csv"
    p.write_text(p.read_text().replace(",", ";"))


def _underscore(d):
    p = d / "pose.csv"
    lines = p.read_text().splitlines()
    f = lines[4].split(",")
    f[1] = "1_" + f[1].lstrip("-")
    lines[4] = ",".join(f)
    p.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("edit, words", [
    (_typo_limit, ["tension_mx", "did you mean 'tension_max'"]),
    (_semicolons, ["semicolons"]),
    (_underscore, ["line 5", "is not a number"]),
], ids=["robot-toml-typo", "semicolon-csv", "underscore-number"])
def test_input_typos_are_one_sentence_exit_2(sample_dataset, tmp_path, edit, words, capsys):
    d = tmp_path / "ds"
    shutil.copytree(sample_dataset, d)
    edit(d)
    assert main(["identify", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(w in err for w in words), err


def test_robot_toml_with_a_byte_order_mark_is_read(sample_dataset, tmp_path, capsys):
    d = tmp_path / "ds"
    shutil.copytree(sample_dataset, d)
    (d / "robot.toml").write_bytes(b"\xef\xbb\xbf" + (d / "robot.toml").read_bytes())
    assert main(["identify", str(d)]) == 0
    capsys.readouterr()


@pytest.mark.parametrize("argv", [["excite", "{robot}", "--duration", "1e6"],
                                  ["tune", "--duration", "1e6"],
                                  ["simulate", "--out", "{tmp}/s", "--duration", "1e6"]],
                         ids=["excite", "tune", "simulate"])
def test_durations_that_cannot_fit_in_memory_are_refused(argv, craft_robot_toml, tmp_path, capsys):
    """``excite --duration 1e6`` was killed by the OOM killer at 24 GB: now one sentence."""
    argv = [a.format(robot=craft_robot_toml, tmp=tmp_path) for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "longer than" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "s").exists()


def test_a_cutoff_that_removes_all_motion_is_one_sentence(sample_dataset, capsys):
    assert main(["identify", str(sample_dataset), "--params", '{"cutoff_hz": 1e-9}']) == 2
    err = capsys.readouterr().err.strip()
    assert "cutoff_hz" in err and "below" in err and len(err.splitlines()) == 1
