"""SIGINT, SIGTERM and SIGHUP unwind a command at a safe point (its outputs' temporary files
removed, no output committed after the signal); see :mod:`cdprid.base._interrupts`."""

from __future__ import annotations

import signal
import sys

from cdprid.base import Terminated, clear_pending, deliver

__all__ = ["Terminated", "install_termination_handlers", "restore_handlers"]


def _on_signal(signum, frame):
    deliver(signum, frame)


def _quiet_terminated(hook):
    """An unraisable-exception hook that prints nothing for :class:`Terminated` (raised where
    the interpreter cannot propagate it, e.g. a ``__del__``): the signal stays pending and ends
    the command at the next safe point."""

    def unraisable(info):
        if isinstance(info.exc_value, Terminated):
            return
        hook(info)

    unraisable.previous = hook
    return unraisable


def install_termination_handlers() -> dict:
    """SIGINT, SIGTERM and SIGHUP handled by :func:`cdprid.base._interrupts.deliver`.

    Main thread only; also installs an unraisable-exception hook that prints nothing for a
    :class:`Terminated` raised where it cannot propagate (it stays pending).

    Returns
    -------
    dict
        The replaced handlers by signal (and ``"unraisablehook"``), for
        :func:`restore_handlers`; empty outside the main thread.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    clear_pending()
    previous = {}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            previous[sig] = signal.signal(sig, _on_signal)
    previous["unraisablehook"] = sys.unraisablehook
    sys.unraisablehook = _quiet_terminated(sys.unraisablehook)
    return previous


def restore_handlers(previous: dict) -> None:
    """Put back the handlers :func:`install_termination_handlers` replaced.

    Parameters
    ----------
    previous : dict
        What :func:`install_termination_handlers` returned; a pending signal is forgotten.
    """
    for sig, handler in previous.items():
        if sig == "unraisablehook":
            sys.unraisablehook = handler
        else:
            signal.signal(sig, handler)
    clear_pending()
