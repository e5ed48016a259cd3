"""Outputs as transactions: written whole or not at all, never over an existing file without force.

Every file and folder a command writes goes through this module:

* :func:`check_output` is called **before any long work** for every path a command will write
  (including files the user did not name, such as a PNG beside a CSV). It refuses an existing
  path without ``force`` and an unwritable or missing parent folder, with one sentence naming
  the option and the path (:class:`~cdprid.base.OutputError`, exit code 2 in the CLI).
* :func:`atomic_file` / :func:`write_text` / :func:`write_json` / :func:`save_figure` write to a
  temporary name beside the target and rename it into place when complete, so an interrupted
  run leaves no partial file that parses.
* :func:`atomic_dir` builds a whole folder (a dataset, a report) under a temporary name and
  renames it into place at the end: the folder appears whole or not at all.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from cdprid.base._errors import OutputError, OutputExistsError

__all__ = [
    "atomic_dir",
    "atomic_file",
    "check_output",
    "save_figure",
    "write_json",
    "write_text",
]


def check_output(path: str | os.PathLike, force: bool = False, flag: str = "--out",
                 kind: str = "file") -> Path:
    """Check, before any work, that ``path`` can be written; returns it as a Path.

    Parameters
    ----------
    path : path-like
        The file or folder a command will write.
    force : bool
        Allow replacing an existing file or folder.
    flag : str
        The option that named it (used in the message), e.g. ``"--json"``.
    kind : {"file", "dir"}
        What will be written there.

    Raises
    ------
    OutputError
        One sentence naming ``flag`` and the path: it exists (without ``force``), it is a folder
        where a file is expected (or the reverse), or its parent folder is missing or not writable.
    """
    p = Path(path)
    if p.exists():
        if kind == "file" and p.is_dir():
            raise OutputError(f"{flag} {p}: is a folder, expected a file name.")
        if kind == "dir" and not p.is_dir():
            raise OutputError(f"{flag} {p}: is a file, expected a folder name.")
        if not force:
            raise OutputExistsError(f"{flag} {p}: already exists; refusing to overwrite it "
                              "(use --force to replace it).")
    parent = p.resolve().parent
    if not parent.is_dir():
        raise OutputError(f"{flag} {p}: its folder {parent} does not exist.")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{flag} {p}: its folder {parent} is not writable.")
    return p


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike, mode: str = "w", force: bool = True) -> Iterator:
    """Open a temporary file beside ``path``; renamed onto ``path`` only if the block completes.

    ``force`` False refuses an existing ``path`` (checked again at the rename).
    """
    p = Path(path)
    if not force and p.exists():
        raise OutputExistsError(f"{p}: already exists; refusing to overwrite it (use --force).")
    if p.is_dir():
        raise OutputError(f"{p}: is a folder, expected a file name.")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.resolve().parent)
    except OSError as exc:
        raise OutputError(f"{p}: cannot write in its folder ({exc.strerror}).") from None
    try:
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        if force:
            os.replace(tmp, p)
        else:  # refuse a file that appeared meanwhile (a link fails if the name exists)
            try:
                os.link(tmp, p)
            except FileExistsError:
                raise OutputExistsError(f"{p}: already exists; refusing to overwrite it "
                                        "(use --force).") from None
            except OSError:  # no hard links on this file system
                os.replace(tmp, p)
            else:
                os.unlink(tmp)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: str | os.PathLike, text: str, force: bool = True) -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_file(path, "w", force=force) as fh:
        fh.write(text)
    return Path(path)


def write_json(path: str | os.PathLike, data: dict, force: bool = True) -> Path:
    """Write ``data`` as indented JSON to ``path`` atomically; returns the path."""
    return write_text(path, json.dumps(data, indent=2, allow_nan=True) + "\n", force=force)


def save_figure(fig, path: str | os.PathLike, force: bool = True, **kwargs) -> Path:
    """``fig.savefig`` to a temporary name beside ``path``, renamed into place when complete."""
    p = Path(path)
    fmt = kwargs.pop("format", None) or (p.suffix.lstrip(".") or "png")
    with atomic_file(p, "wb", force=force) as fh:
        fig.savefig(fh, format=fmt, **kwargs)
    return p


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike, force: bool = False) -> Iterator[Path]:
    """Build a folder under a temporary name beside ``path``; it appears whole or not at all.

    Yields the temporary folder to write into. When the block completes, an existing ``path``
    (allowed only with ``force``) is replaced by it; when the block fails or is interrupted,
    the temporary folder is removed and ``path`` is left as it was.
    """
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{p}: is a file, expected a folder name.")
    if p.exists() and not force and any(p.iterdir()):
        raise OutputExistsError(f"{p}: already exists; refusing to overwrite it (use --force).")
    parent = p.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".part", dir=parent))
    except OSError as exc:
        raise OutputError(f"{p}: cannot write in its folder {parent} ({exc.strerror}).") from None
    try:
        yield tmp
        if p.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".old", dir=parent))
            os.replace(p, old / p.name)
            os.replace(tmp, p)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, p)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
