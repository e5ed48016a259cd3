"""Issue 40 #3 and #8: table rows shifted by a decimal comma, and files beyond the parsers'
limits, are one sentence and exit 2 (not a shifted row, not an internal error)."""

from __future__ import annotations

import pytest

from cdprid.cli import main


def _import(sample_dataset, pose, out):
    return main(["import", "table", "--pose", str(pose), "--tensions",
                 str(sample_dataset / "tensions.csv"), "--robot",
                 str(sample_dataset / "robot.toml"), "--out", str(out)])


def _pose_rows(sample_dataset):
    return (sample_dataset / "pose.csv").read_text().splitlines()


def test_decimal_comma_in_comma_separated_file_names_its_line(sample_dataset, tmp_path, capsys):
    lines = _pose_rows(sample_dataset)
    head = lines[0].split(",")[:4]  # t,x,y,z
    rows = [",".join(r.split(",")[:4]) for r in lines[1:]]
    t, x, y, z = rows[7].split(",")
    rows[7] = ",".join([t, x, y.replace(".", ","), z])  # "0,869" where "0.869" was meant
    pose = tmp_path / "pose.csv"
    pose.write_text(",".join(head) + "\n" + "\n".join(rows) + "\n")
    out = tmp_path / "o"
    assert _import(sample_dataset, pose, out) == 2
    err = capsys.readouterr().err
    assert "line 9" in err and "decimal comma" in err and str(pose) in err
    assert not out.exists()


def test_huge_header_cell_is_exit_2(sample_dataset, tmp_path, capsys):
    pose = tmp_path / "pose.csv"
    pose.write_text("t,x,y," + "z" * 140_000 + "\n0,1,2,3\n0.01,1,2,3\n")
    assert _import(sample_dataset, pose, tmp_path / "o") == 2
    err = capsys.readouterr().err
    assert "line 1" in err and "internal error" not in err


@pytest.mark.parametrize("value, words", [("1" * 5000, "limits"),
                                          ("[" * 3000 + "]" * 3000, "nested")])
def test_hostile_robot_toml_is_exit_2(sample_dataset, tmp_path, capsys, value, words):
    ds = tmp_path / "ds"
    ds.mkdir()
    for f in sample_dataset.iterdir():
        (ds / f.name).write_bytes(f.read_bytes())
    robot = ds / "robot.toml"
    robot.write_text(f"extra = {value}\n" + robot.read_text())
    assert main(["identify", str(ds)]) == 2
    err = capsys.readouterr().err
    assert "robot.toml" in err and words in err and "internal error" not in err


def test_bool_is_not_a_cutoff(sample_dataset, capsys):
    assert main(["identify", str(sample_dataset), "--params", '{"cutoff_hz": true}']) == 2
    err = capsys.readouterr().err
    assert "cutoff_hz" in err and "number" in err
