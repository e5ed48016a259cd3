"""Outputs never touch what the command did not write (issue 25, data loss).

``--force`` replaces the named file or this command's own files, never a folder's other
contents or an input; an output that is or holds an input is refused; two runs racing for one
output: one wins, the other gets exit 2. Every case here was a reported data loss.
"""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.base import OutputError, OutputExistsError, atomic_dir, check_distinct
from cdprid.cli import main


def _snapshot(folder):
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _err(capsys):
    return capsys.readouterr().err.strip()


# ---------------------------------------------------------------- outputs that are inputs


def test_diagnose_report_into_its_own_dataset_is_refused(small_ds, capsys):
    before = _snapshot(small_ds)
    assert main(["diagnose", str(small_ds), "--report", str(small_ds), "--force"]) == 2
    err = _err(capsys)
    assert "--report" in err and "input" in err and len(err.splitlines()) == 1
    assert _snapshot(small_ds) == before


def test_identify_json_onto_an_input_file_is_refused(small_ds, capsys):
    before = _snapshot(small_ds)
    assert main(["identify", str(small_ds), "--json", str(small_ds / "pose.csv"),
                 "--force"]) == 2
    assert "--json" in _err(capsys)
    assert _snapshot(small_ds) == before


def test_differentiate_onto_its_input_is_refused(tmp_path, capsys):
    src = tmp_path / "x.csv"
    src.write_text("t,a\n" + "".join(f"{0.01 * i},{np.sin(0.01 * i)}\n" for i in range(300)))
    before = src.read_bytes()
    assert main(["differentiate", str(src), "--out", str(src), "--force"]) == 2
    assert "is the input" in _err(capsys)
    assert src.read_bytes() == before


def test_import_table_into_the_folder_of_its_tables_is_refused(tmp_path, capsys):
    folder = tmp_path / "lab"
    folder.mkdir()
    (folder / "pose.csv").write_text("t,x,y,z\n0,0,0,1\n0.01,0,0,1\n")
    (folder / "tau.csv").write_text("t,tau_1\n0,1\n0.01,1\n")
    (folder / "robot.toml").write_text("")
    before = _snapshot(folder)
    rc = main(["import", "table", "--pose", str(folder / "pose.csv"), "--tensions",
               str(folder / "tau.csv"), "--robot", str(folder / "robot.toml"), "--out",
               str(folder), "--force"])
    assert rc == 2 and "holds the input" in _err(capsys)
    assert _snapshot(folder) == before


@pytest.mark.parametrize("csv_name, json_name", [("p.csv", "p.csv"), ("p.png", None)])
def test_online_outputs_that_collide_are_refused(small_ds, tmp_path, capsys, csv_name, json_name):
    argv = ["identify", str(small_ds), "--online", "--out-csv", str(tmp_path / csv_name)]
    if json_name:
        argv += ["--json", str(tmp_path / json_name)]
    assert main(argv) == 2
    assert "same file" in _err(capsys)
    assert not (tmp_path / csv_name).exists()


def test_calibrate_json_needs_force_before_any_work(tmp_path, capsys):
    for name in ("vicon.csv", "log.txt", "config.json"):
        (tmp_path / name).write_text("not read: the output check comes first\n")
    existing = tmp_path / "existing.json"
    existing.write_text('{"keep": true}\n')
    rc = main(["calibrate", "--vicon", str(tmp_path / "vicon.csv"), "--robot-log",
               str(tmp_path / "log.txt"), "--config", str(tmp_path / "config.json"), "--json",
               str(existing)])
    assert rc == 2 and "already exists" in _err(capsys)
    assert existing.read_text() == '{"keep": true}\n'


# ---------------------------------------------------------------- --force keeps others' files


def test_simulate_force_keeps_the_folders_other_contents(tmp_path):
    proj = tmp_path / "proj"
    (proj / "run1").mkdir(parents=True)
    (proj / "thesis.tex").write_text("\\chapter{results}\n")
    (proj / "run1" / "pose.csv").write_text("t,x,y,z\n")
    (proj / "lengths.csv").write_text("t,l_1\n0,1\n")  # a stale file of the dataset kind
    rc = main(["simulate", "--out", str(proj), "--preset", "paper-orbits", "--duration", "12",
               "--force"])
    assert rc == 0
    assert (proj / "thesis.tex").read_text() == "\\chapter{results}\n"
    assert (proj / "run1" / "pose.csv").read_text() == "t,x,y,z\n"
    assert (proj / "pose.csv").exists() and (proj / "robot.toml").exists()
    assert not (proj / "lengths.csv").exists()  # a dataset file this run did not write
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith((".part", ".old"))]


def test_atomic_dir_force_replaces_only_its_own_entries(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("old")
    (out / "notes.txt").write_text("user's")
    (out / "figures").mkdir()
    (out / "figures" / "old.png").write_text("old figure")
    with atomic_dir(out, force=True, owned=("stale.txt",)) as tmp:
        (tmp / "mine.txt").write_text("new")
        (tmp / "figures").mkdir()
        (tmp / "figures" / "a.png").write_text("a")
    assert (out / "mine.txt").read_text() == "new"
    assert (out / "notes.txt").read_text() == "user's"
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["a.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_atomic_dir_failure_leaves_the_folder_as_it_was(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_dir(out, force=True) as tmp:
        (tmp / "mine.txt").write_text("half")
        raise RuntimeError("interrupted")
    assert (out / "mine.txt").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_racing_runs_one_wins_the_other_is_refused(tmp_path):
    """Two runs to one new output (interleaved deterministically): the second rename fails."""
    out = tmp_path / "S"
    first, second = atomic_dir(out), atomic_dir(out)
    t1, t2 = first.__enter__(), second.__enter__()
    (t1 / "a.txt").write_text("first")
    (t2 / "a.txt").write_text("second")
    first.__exit__(None, None, None)
    with pytest.raises(OutputExistsError):
        second.__exit__(None, None, None)
    assert (out / "a.txt").read_text() == "first"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["S"]


def test_check_distinct_names_both_flags(tmp_path):
    with pytest.raises(OutputError, match="--json .* same file as --out-csv"):
        check_distinct({"--out-csv": tmp_path / "a.csv", "--json": tmp_path / "a.csv"})
    check_distinct({"--out-csv": tmp_path / "a.csv", "--json": None})


def test_interrupted_online_run_leaves_none_of_its_files(sample_dataset, tmp_path, monkeypatch,
                                                         capsys):
    """Ctrl-C after the CSV and the PNG were written (during the JSON): all three are gone."""
    import cdprid.cli._online as online_cli

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(online_cli, "write_json", interrupted)
    csv = tmp_path / "run.csv"
    rc = main(["identify", str(sample_dataset), "--online", "--out-csv", str(csv), "--json",
               str(tmp_path / "run.json")])
    assert rc == 130 and "no partial output" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == []
