"""Error types that separate a user's mistake (exit code 2) from an internal failure (exit 1).

Library code raises :class:`UserError` (or a subclass) only for a problem in what the user
gave: a file, a field, an option. Everything else is an internal error that the CLI reports
as such ("please report it"), never as bad input.
"""

from __future__ import annotations

__all__ = ["ConvergenceError", "InputError", "OutputError", "OutputExistsError", "UserError"]


class UserError(Exception):
    """A problem in what the user gave; the CLI prints it as one sentence and exits with 2."""


class InputError(UserError, ValueError):
    """An invalid value the user gave (an option, a parameter, a field of a file).

    Also a :class:`ValueError`, so that callers catching that keep working. Every validation in
    the library raises it (or another :class:`UserError`): the CLI decides exit 2 vs 1 by type,
    never by where the exception was raised.
    """


class OutputError(UserError):
    """An output path that cannot be written (exists without --force, missing folder, ...)."""


class OutputExistsError(OutputError, FileExistsError):
    """An output that exists already and may not be replaced (no --force).

    Also a :class:`FileExistsError`, so that callers catching that keep working.
    """

    def __init__(self, message: str):
        Exception.__init__(self, message)

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class ConvergenceError(RuntimeError):
    """A numerical solver did not converge; the message says which solver and what to try."""
