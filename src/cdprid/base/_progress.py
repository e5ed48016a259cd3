"""Progress lines on stderr for commands that can take more than a few seconds.

``Progress("identify").say("differentiating")`` prints ``cdprid identify: differentiating
(2.1 s)`` to stderr. Set ``CDPRID_QUIET=1`` to silence them (errors are still printed).
"""

from __future__ import annotations

import os
import sys
import time

from cdprid.base._interrupts import check_pending

__all__ = ["Progress"]


class Progress:
    """Timed progress messages of one command on stderr.

    Parameters
    ----------
    command : str
        The command name shown in each line.
    stream : file, optional
        Where to write (default ``sys.stderr``).
    """

    def __init__(self, command: str, stream=None):
        self.command = command
        self.stream = stream
        self.t0 = time.perf_counter()
        self.quiet = os.environ.get("CDPRID_QUIET", "").strip() not in ("", "0")

    def elapsed(self) -> float:
        """Seconds since the command started.

        Returns
        -------
        float
            Wall-clock time since construction, in s.
        """
        return time.perf_counter() - self.t0

    def say(self, message: str) -> None:
        """Print one progress line with the elapsed time.

        A safe point: a signal recorded where it could not be raised ends the command here.

        Parameters
        ----------
        message : str
            The text after ``cdprid <command>:``; nothing is printed when ``CDPRID_QUIET`` is set.

        Raises
        ------
        Terminated
            A termination signal is pending.
        """
        check_pending()
        if self.quiet:
            return
        stream = self.stream if self.stream is not None else sys.stderr
        print(f"cdprid {self.command}: {message} ({self.elapsed():.1f} s)", file=stream,
              flush=True)
