"""Issue 40 #7: a SIGTERM that arrives inside a garbage-collection callback (JAX registers
one; an exception raised there is printed and swallowed) still ends the command with 143 and
commits no output. The signal is sent from a GC callback of the test, so the handler runs
inside that callback every time (no race)."""

from __future__ import annotations

import gc
import os
import signal
import sys

import pytest

from cdprid.base import atomic_file, pending
from cdprid.cli import _signals
from cdprid.cli._main import main


def _arm(sig=signal.SIGTERM):
    """A GC callback that sends ``sig`` once, at the first collection after the CLI's handler
    is installed, and runs a few bytecodes after it (where Python runs the handler)."""
    fired = []

    def cb(phase, info):
        if fired or phase != "start" or signal.getsignal(sig) is not _signals._on_signal:
            return
        fired.append(sig)
        os.kill(os.getpid(), sig)
        k = 0
        for _ in range(1000):  # the handler runs in here, inside the GC callback
            k += 1

    gc.callbacks.append(cb)
    return cb, fired


def test_signal_in_gc_callback_is_held_to_the_next_safe_point(tmp_path):
    prev = _signals.install_termination_handlers()
    cb, fired = _arm()
    try:
        gc.collect()  # no exception escapes the callback (none is printed and lost)
        assert fired and pending() == signal.SIGTERM
        with pytest.raises(_signals.Terminated), atomic_file(tmp_path / "out.txt") as fh:
            fh.write("complete")
    finally:
        gc.callbacks.remove(cb)
        _signals.restore_handlers(prev)
    assert list(tmp_path.iterdir()) == []  # no output committed after the signal
    assert pending() is None


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_cli_ends_with_128_plus_signal_when_it_arrives_in_gc(tmp_path, capsys, monkeypatch,
                                                             sig):
    from cdprid.io import write_dataset

    writer = sys.modules[write_dataset.__module__]  # the writer's module, patched below

    real = writer._write_csv

    def collect_then_write(*a, **k):  # a collection while the dataset is being written
        gc.collect()
        return real(*a, **k)

    monkeypatch.setattr(writer, "_write_csv", collect_then_write)
    out = tmp_path / "DS"
    cb, fired = _arm(sig)
    try:
        rc = main(["simulate", "--out", str(out), "--duration", "11"])
    finally:
        gc.callbacks.remove(cb)
    err = capsys.readouterr().err
    assert fired and rc == 128 + sig, err
    assert "Exception ignored" not in err and "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_progress_line_is_a_safe_point(capsys):
    from cdprid.base import Progress

    prev = _signals.install_termination_handlers()
    cb, fired = _arm()
    try:
        gc.collect()
        assert fired and pending() == signal.SIGTERM
        with pytest.raises(_signals.Terminated):
            Progress("test").say("next stage")
    finally:
        gc.callbacks.remove(cb)
        _signals.restore_handlers(prev)
    assert "next stage" not in capsys.readouterr().err
