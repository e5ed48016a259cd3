"""Issue 40 #1 and #10: ``--force`` over a folder is atomic (the old folder or the complete new
one, nothing beside it), even when SIGTERM arrives mid-way; a link to an empty folder is
written through.

The signal is sent at a chosen point (a wrapped step of the replacement), so each case is
deterministic: before the exchange (the old folder must stay), at the exchange (held until the
new folder is complete and the old one removed), and in the two-rename fallback.
"""

from __future__ import annotations

import errno
import os
import signal

import pytest

from cdprid.base import Terminated, _replace, atomic_dir
from cdprid.cli import install_termination_handlers, main, restore_handlers


def _old(tmp_path):
    out = tmp_path / "DS"
    out.mkdir()
    for name in ("meta.toml", "pose.csv", "tensions.csv", "lengths.csv"):
        (out / name).write_text(f"old {name}")
    (out / "notes.txt").write_text("the user's")
    (out / "sub").mkdir()
    (out / "sub" / "a.txt").write_text("the user's too")
    return out


def _write_new(tmp):
    for name in ("meta.toml", "pose.csv", "tensions.csv"):
        (tmp / name).write_text(f"new {name}")


def _state(out):
    return {p.relative_to(out).as_posix(): p.read_text() for p in out.rglob("*") if p.is_file()}


NEW = {"meta.toml": "new meta.toml", "pose.csv": "new pose.csv",
       "tensions.csv": "new tensions.csv", "notes.txt": "the user's",
       "sub/a.txt": "the user's too"}
OWNED = ("meta.toml", "pose.csv", "tensions.csv", "lengths.csv")


def _signal_at(monkeypatch, name, sig=signal.SIGTERM):
    """Send ``sig`` to this process when ``_replace.<name>`` is first called."""
    real = getattr(_replace, name)
    sent = []

    def wrapped(*a, **k):
        if not sent:
            sent.append(1)
            os.kill(os.getpid(), sig)
        return real(*a, **k)

    monkeypatch.setattr(_replace, name, wrapped)
    return sent


@pytest.fixture
def handlers():
    prev = install_termination_handlers()
    yield
    restore_handlers(prev)


def _siblings(tmp_path):
    return sorted(p.name for p in tmp_path.iterdir())


@pytest.mark.parametrize("exchange", ["renameat2", "two renames"])
def test_force_replaces_whole_and_keeps_the_users_entries(tmp_path, monkeypatch, exchange):
    out = _old(tmp_path)
    inode = (out / "notes.txt").stat().st_ino
    if exchange == "two renames":
        monkeypatch.setattr(_replace, "_exchange", _unsupported)
    with atomic_dir(out, force=True, owned=OWNED) as tmp:
        _write_new(tmp)
    assert _state(out) == NEW
    assert (out / "notes.txt").stat().st_ino == inode  # linked, not rewritten
    assert _siblings(tmp_path) == ["DS"]


def _unsupported(a, b):
    raise OSError(errno.EINVAL, "no RENAME_EXCHANGE here")


@pytest.mark.parametrize("exchange", ["renameat2", "two renames"])
def test_sigterm_at_the_swap_is_held_until_the_new_folder_is_whole(tmp_path, monkeypatch,
                                                                   handlers, exchange):
    out = _old(tmp_path)
    if exchange == "two renames":
        monkeypatch.setattr(_replace, "_exchange", _unsupported)
        sent = _signal_at(monkeypatch, "_two_renames")
    else:
        sent = _signal_at(monkeypatch, "_exchange")
    with pytest.raises(Terminated), atomic_dir(out, force=True, owned=OWNED) as tmp:
        _write_new(tmp)
    assert sent and _state(out) == NEW
    assert _siblings(tmp_path) == ["DS"]


def test_sigterm_before_the_swap_leaves_the_old_folder(tmp_path, monkeypatch, handlers):
    out = _old(tmp_path)
    before = _state(out)
    sent = _signal_at(monkeypatch, "_link_or_copy")  # while the user's entries are linked
    with pytest.raises(Terminated), atomic_dir(out, force=True, owned=OWNED) as tmp:
        _write_new(tmp)
    assert sent and _state(out) == before
    assert _siblings(tmp_path) == ["DS"]


def test_crash_between_the_two_renames_is_repaired_on_the_next_run(tmp_path):
    out = _old(tmp_path)
    before = _state(out)
    os.rename(out, tmp_path / ".DS.x1y2.old")  # SIGKILL after the first rename
    (tmp_path / ".DS.q.part").mkdir()  # and the new folder it was about to rename
    assert _replace.recover_leftovers(out) and _state(out) == before
    # a crash during the removal of the old folder: the leftover is removed next time
    (tmp_path / ".DS.z9.old").mkdir()
    ((tmp_path / ".DS.z9.old") / "pose.csv").write_text("old")
    with atomic_dir(out, force=True, owned=OWNED) as tmp:
        _write_new(tmp)
    assert _state(out) == NEW
    assert not (tmp_path / ".DS.z9.old").exists()


def test_cli_simulate_force_sigterm_at_the_swap(tmp_path, monkeypatch, capsys):
    out = tmp_path / "DS"
    assert main(["simulate", "--out", str(out), "--duration", "11", "--seed", "1"]) == 0
    (out / "notes.txt").write_text("mine")
    sent = _signal_at(monkeypatch, "_exchange")
    rc = main(["simulate", "--out", str(out), "--duration", "12", "--seed", "2", "--force"])
    assert sent and rc == 143, capsys.readouterr().err
    names = sorted(p.name for p in out.iterdir())
    assert names == ["meta.toml", "notes.txt", "pose.csv", "robot.toml", "tensions.csv",
                     "truth_motion.csv"]
    pose = (out / "pose.csv").read_text().splitlines()
    tens = (out / "tensions.csv").read_text().splitlines()
    assert len(pose) == len(tens) == 1202  # header + 12 s at 100 Hz + 1: all the new run's
    assert _siblings(tmp_path) == ["DS"]


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_out_link_to_an_empty_folder_is_written_through(tmp_path, capsys, force):
    target = tmp_path / "empty"
    target.mkdir()
    link = tmp_path / "link"
    link.symlink_to(target, target_is_directory=True)
    rc = main(["simulate", "--out", str(link), "--duration", "11", *force])
    assert rc == 0, capsys.readouterr().err
    assert link.is_symlink() and (target / "pose.csv").exists()
    assert _siblings(tmp_path) == ["empty", "link"]
