"""How a command ends: the exit code and one line on stderr for a signal, a user's mistake
(exit 2) or an internal error (exit 1)."""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import sys

from cdprid.base import UserError

__all__ = ["failed", "interrupted", "is_user_error", "user_message"]


def is_user_error(exc: BaseException) -> bool:
    """Whether ``exc`` reports a problem in the user's input (exit 2) rather than a bug (exit 1).

    Decided by the exception's type alone: :class:`~cdprid.base.UserError` and its subclasses
    (``InputError``, which every validation in the library raises, ``DatasetError``,
    ``RobotFileError``, ``OutputError``), an output that exists (``FileExistsError``), OS errors
    on a named path (read-only or missing folder, a folder given as a file, ...), a full disk,
    a ``LinAlgError`` (degenerate input), and the library's input errors that are not
    ``UserError`` subclasses (:data:`LIBRARY_INPUT_ERRORS`: a trajectory the robot cannot hold
    with admissible tensions, too few usable samples). Any other exception -- a plain ``ValueError``
    included, wherever it was raised -- is an internal error: validation raises typed errors
    (``tests/test_architecture.py`` keeps ``raise ValueError`` out of src), so input that
    slipped past it is a bug to report, not the user's mistake.

    Parameters
    ----------
    exc : BaseException
        The exception that ended the command.

    Returns
    -------
    bool
    """
    if isinstance(exc, UserError) or isinstance(exc, _library_input_errors()):
        return True
    if isinstance(exc, FileExistsError):  # an output that exists (commands refuse to replace)
        return True
    if isinstance(exc, OSError) and getattr(exc, "filename", None) is not None:
        return True
    if isinstance(exc, OSError) and exc.errno in _DISK_ERRNOS:  # full disk, quota, read-only
        return True
    return type(exc).__name__ == "LinAlgError"  # SVD/QR without convergence: degenerate input


_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS}

# Errors of the library that report the user's input without being UserError subclasses, as
# (package face, class name). They are looked up in ``sys.modules``, so that deciding an exit
# code imports nothing: an exception of a package not yet imported cannot be one of them.
LIBRARY_INPUT_ERRORS = (("cdprid.model", "InfeasibleTensionsError"),
                        ("cdprid.core", "InsufficientDataError"))


def _library_input_errors() -> tuple[type, ...]:
    found = []
    for face, name in LIBRARY_INPUT_ERRORS:
        cls = getattr(sys.modules.get(face), name, None)
        if cls is not None:
            found.append(cls)
    return tuple(found)


def user_message(exc: BaseException) -> str:
    """The one sentence printed for a user error (after ``cdprid: error: ``).

    Parameters
    ----------
    exc : BaseException
        An exception for which :func:`is_user_error` holds.

    Returns
    -------
    str
    """
    if type(exc).__name__ == "LinAlgError":
        return (f"a linear-algebra step failed on these data ({exc}): the regression is "
                "degenerate; check the units, the axes (z up?) and the geometry in robot.toml.")
    if isinstance(exc, OSError) and exc.errno in _DISK_ERRNOS \
            and getattr(exc, "filename", None) is None:
        return (f"could not write the output: {exc.strerror or os.strerror(exc.errno)} (free "
                "some space or choose another folder; nothing partial was left).")
    if isinstance(exc, OSError) and getattr(exc, "filename", None) is not None \
            and not isinstance(exc, UserError):
        return f"{exc.filename}: {exc.strerror or type(exc).__name__}."
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def interrupted(signum: int) -> int:
    """Say that the command was interrupted (nothing partial left) and return 128 + ``signum``.

    Parameters
    ----------
    signum : int
        The signal that ended the command (SIGINT: "interrupted", else "terminated").

    Returns
    -------
    int
        The exit code.
    """
    print(f"cdprid: {'interrupted' if signum == signal.SIGINT else 'terminated'}; no partial "
          "output was left", file=sys.stderr)
    return 128 + int(signum)


def failed(exc: BaseException) -> int:
    """Print the message of an exception that ended a command (not a signal); its exit code.

    Parameters
    ----------
    exc : BaseException
        The exception.

    Returns
    -------
    int
        2 for a user error or a closed standard output, 1 for an internal error (re-raised
        with ``CDPRID_DEBUG`` set).
    """
    try:
        raise exc
    except BrokenPipeError:  # stdout closed by the reader (``cdprid ... | head``)
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        print("cdprid: error: standard output was closed before the command finished printing.",
              file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001
        if is_user_error(exc):
            print(f"cdprid: error: {user_message(exc)}", file=sys.stderr)
            return 2
        if os.environ.get("CDPRID_DEBUG"):
            raise
        print(f"cdprid: internal error: {type(exc).__name__}: {exc} "
              "(set CDPRID_DEBUG=1 for a traceback and please report it)", file=sys.stderr)
        return 1
