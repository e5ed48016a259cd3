"""SIGTERM and SIGHUP unwind a command like Ctrl-C (its outputs' ``.part`` files removed)."""

from __future__ import annotations

import signal

__all__ = ["Terminated", "install_termination_handlers", "restore_handlers"]


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP during a command: unwinds like Ctrl-C, so every output transaction
    removes its temporary ``.part`` files; the exit code is 128 + the signal number."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _raise_terminated(signum, frame):
    raise Terminated(signum)


def install_termination_handlers() -> dict:
    """SIGTERM and SIGHUP raise :class:`Terminated` (main thread only); returns the old handlers."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            previous[sig] = signal.signal(sig, _raise_terminated)
    return previous


def restore_handlers(previous: dict) -> None:
    for sig, handler in previous.items():
        signal.signal(sig, handler)
