"""How a command ends: the exit code and one line on stderr for a signal, a user's mistake
(exit 2) or an internal error (exit 1)."""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import sys
from pathlib import Path

from cdprid.base import UserError


def _is_user_error(exc: BaseException) -> bool:
    """Whether ``exc`` reports a problem in the user's input (exit 2) rather than a bug (exit 1).

    By type: :class:`~cdprid.base.UserError` and its subclasses (``InputError``, which every
    validation in the library raises, ``DatasetError``, ``RobotFileError``, ``OutputError``),
    OS errors on a named path (read-only or missing folder, a folder given as a file, ...), a
    full disk, and a ``LinAlgError`` (degenerate input). One safety net remains: a plain
    ``ValueError`` whose last frame is in cdprid's own code (a builtin conversion such as
    ``float(text)`` on user input); ``tests/test_architecture.py`` keeps ``raise ValueError``
    out of src. A ``ValueError`` from inside NumPy, SciPy or JAX is an internal error.
    """
    if isinstance(exc, UserError):
        return True
    geo = sys.modules.get("cdprid.model._geometry")
    if geo is not None and isinstance(exc, getattr(geo, "RobotFileError", ())):
        return True
    if isinstance(exc, FileExistsError):  # an output that exists (commands refuse to replace)
        return True
    if isinstance(exc, OSError) and getattr(exc, "filename", None) is not None:
        return True
    if isinstance(exc, OSError) and exc.errno in _DISK_ERRNOS:  # full disk, quota, read-only
        return True
    if type(exc).__name__ == "LinAlgError":  # SVD/QR without convergence: degenerate input
        return True
    if isinstance(exc, ValueError) and exc.__traceback__ is not None:
        tb = exc.__traceback__
        while tb.tb_next is not None:
            tb = tb.tb_next
        pkg = str(Path(__file__).resolve().parents[1])  # src/cdprid
        return str(Path(tb.tb_frame.f_code.co_filename).resolve()).startswith(pkg)
    return False


_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS}


def _user_message(exc: BaseException) -> str:
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


def _interrupted(signum: int) -> int:
    print(f"cdprid: {'interrupted' if signum == signal.SIGINT else 'terminated'}; no partial "
          "output was left", file=sys.stderr)
    return 128 + int(signum)


def _failed(exc: BaseException) -> int:
    """Exit code and message of an exception that ended a command (not a signal)."""
    try:
        raise exc
    except BrokenPipeError:  # stdout closed by the reader (``cdprid ... | head``)
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        print("cdprid: error: standard output was closed before the command finished printing.",
              file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: BLE001
        if _is_user_error(exc):
            print(f"cdprid: error: {_user_message(exc)}", file=sys.stderr)
            return 2
        if os.environ.get("CDPRID_DEBUG"):
            raise
        print(f"cdprid: internal error: {type(exc).__name__}: {exc} "
              "(set CDPRID_DEBUG=1 for a traceback and please report it)", file=sys.stderr)
        return 1
