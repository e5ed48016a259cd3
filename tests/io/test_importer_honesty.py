"""Importers say what they drop and never write what their reader rejects (issue 25)."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.base import UserError
from cdprid.cli import main
from cdprid.io._table import parse_mapping, write_imported
from cdprid.model import CRAFT_LIKE, robot_from_dict
from conftest import ROBOT_CRAFT


def _robot_toml(path, n_cables=8):
    import tomli_w

    d = dict(CRAFT_LIKE, cable=CRAFT_LIKE["cable"][:n_cables])
    with open(path, "wb") as fh:
        tomli_w.dump(d, fh)
    return path


def _tables(tmp_path, n_tau=8, quaternion=True):
    t = np.arange(0, 3, 0.01)
    pose = tmp_path / "pose.csv"
    cols = "t,x,y,z" + (",qw,qx,qy,qz" if quaternion else "")
    rows = [[ti, 0.1 * np.sin(ti), 0.0, 1.2] + ([1.0, 0.0, 0.0, 0.0] if quaternion else [])
            for ti in t]
    np.savetxt(pose, rows, delimiter=",", header=cols, comments="", fmt="%.10g")
    tens = tmp_path / "tau.csv"
    np.savetxt(tens, np.column_stack([t, 20 + 0 * np.outer(t, np.ones(n_tau))]), delimiter=",",
               header="t," + ",".join(f"tau_{i}" for i in range(1, n_tau + 1)), comments="",
               fmt="%.10g")
    return pose, tens


def test_one_column_mapped_to_two_keys_is_refused():
    with pytest.raises(UserError, match="mapped to both 'x' and 'y'"):
        parse_mapping("t=time,x=X,y=X,z=Z", "--pose-columns")


def test_more_tension_columns_than_cables_is_refused(tmp_path, capsys):
    pose, tens = _tables(tmp_path, n_tau=8)
    robot = _robot_toml(tmp_path / "robot.toml", n_cables=7)
    rc = main(["import", "table", "--pose", str(pose), "--tensions", str(tens), "--robot",
               str(robot), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert rc == 2 and "tau_8" in err and "7 cables" in err
    assert not (tmp_path / "out").exists()


def test_unmapped_quaternion_columns_are_named(tmp_path, capsys):
    pose, tens = _tables(tmp_path)
    robot = _robot_toml(tmp_path / "robot.toml")
    rc = main(["import", "table", "--pose", str(pose), "--tensions", str(tens), "--robot",
               str(robot), "--out", str(tmp_path / "out"), "--pose-columns", "t=t,x=x,y=y,z=z"])
    out = capsys.readouterr().out
    assert rc == 0 and "qw, qx, qy, qz were not imported" in out


def test_importer_never_writes_what_the_reader_rejects(tmp_path):
    robot = robot_from_dict(ROBOT_CRAFT)
    t = np.arange(0, 2, 0.01)
    pos = np.column_stack([0 * t, 0 * t, 1.2 + 0 * t])
    tau = np.full((len(t), 8), 20.0)
    tau[50, 3] = np.nan  # a NaN that a bag or a C3D can carry
    with pytest.raises(UserError, match="not finite|not a number"):
        write_imported(tmp_path / "out", robot, t, pos, t, tau)
    assert not (tmp_path / "out").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def test_batch_only_options_are_refused_with_online(sample_dataset, capsys):
    rc = main(["identify", str(sample_dataset), "--online", "--physical"])
    err = capsys.readouterr().err
    assert rc == 2 and "--physical" in err and "batch" in err


def test_written_robot_toml_keeps_vectors_on_one_line(small_ds):
    """An import wrote robot.toml one number a line; now as the spec shows it, and it reads
    back to the same robot."""
    from cdprid.io import read_dataset
    from cdprid.model import robot_from_dict, robot_to_dict

    text = (small_ds / "robot.toml").read_text()
    assert any(line.startswith("exit = [") and line.endswith("]") for line in text.splitlines())
    robot = read_dataset(small_ds).robot
    again = robot_from_dict(robot_to_dict(robot))
    np.testing.assert_array_equal(np.asarray(again.B_A), np.asarray(robot.B_A))
    np.testing.assert_array_equal(np.asarray(again.P_b), np.asarray(robot.P_b))
