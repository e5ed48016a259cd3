"""Termination signals acted on at safe points only (issue 40 #1, #7).

The CLI's handlers of SIGINT, SIGTERM and SIGHUP (:mod:`cdprid.cli._signals`) call
:func:`deliver`. It records the signal and raises :class:`Terminated` where that is safe.
It does **not** raise

* inside :func:`held` (an output's critical step: the exchange of a dataset folder and the
  removal of the old one, the creation of a temporary file whose name is not yet known): the
  signal is raised when the outermost :func:`held` block ends;
* inside a garbage-collection callback (JAX registers one): an exception raised there is
  printed and swallowed by the interpreter, and the command went on to exit 0 with every
  output written.

A recorded signal stays pending until it is raised and reaches the command's end; the output
helpers call :func:`check_pending` before they rename anything into place, so an output is
never committed after a signal, and :func:`cdprid.cli.main` ends with 128 + the signal number
when a signal is still pending after the command returned.

Signal masks (``pthread_sigmask``) alone do not hold a signal in a process with other threads
(XLA's): the kernel delivers it to a thread that does not block it and Python runs the handler
in the main thread at once. :func:`held` also blocks the signals in the calling thread, which
holds them for library callers without the CLI's handlers in a single-threaded process.
"""

from __future__ import annotations

import contextlib
import gc
import signal
from collections.abc import Iterator

__all__ = ["Terminated", "check_pending", "clear_pending", "deliver", "held", "pending"]


class Terminated(KeyboardInterrupt):
    """SIGINT, SIGTERM or SIGHUP during a command: unwinds like Ctrl-C, so every output
    transaction removes its temporary files; the exit code is 128 + the signal number."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


_STATE = {"depth": 0, "pending": None}
_HELD = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


def pending() -> int | None:
    """The signal number recorded and not yet acted on, or None.

    Returns
    -------
    int or None
        The pending signal's number (e.g. 15 for SIGTERM), None when none is pending.
    """
    return _STATE["pending"]


def clear_pending() -> None:
    """Forget a recorded signal (the command has ended on it)."""
    _STATE["pending"] = None


def check_pending() -> None:
    """A safe point: raise :class:`Terminated` for a recorded signal (outside :func:`held`)."""
    sig = _STATE["pending"]
    if sig is not None and _STATE["depth"] == 0:
        raise Terminated(sig)


def _in_gc_callback(frame) -> bool:
    codes = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    codes.discard(None)
    while frame is not None and codes:
        if frame.f_code in codes:
            return True
        frame = frame.f_back
    return False


def deliver(signum: int, frame=None) -> None:
    """The body of a termination handler: record ``signum`` and raise unless it is unsafe.

    Parameters
    ----------
    signum : int
        The signal number; the first one recorded stays pending.
    frame : frame, optional
        The interrupted frame (as given to a signal handler); used to detect a
        garbage-collection callback.

    Raises
    ------
    Terminated
        Outside :func:`held` and outside a garbage-collection callback (otherwise the signal
        is raised at the next safe point).
    """
    if _STATE["pending"] is None:
        _STATE["pending"] = int(signum)
    if _STATE["depth"] > 0 or _in_gc_callback(frame):
        return
    raise Terminated(_STATE["pending"])


@contextlib.contextmanager
def held() -> Iterator[None]:
    """Hold termination signals for the block; one that arrived meanwhile is raised at its end."""
    mask = (signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
            if hasattr(signal, "pthread_sigmask") else None)
    _STATE["depth"] += 1
    try:
        yield
    finally:
        _STATE["depth"] -= 1
        if mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a blocked signal arrives here
    check_pending()
