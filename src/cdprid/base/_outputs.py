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
import errno
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from cdprid.base._errors import OutputError, OutputExistsError
from cdprid.base._interrupts import check_pending, held
from cdprid.base._replace import recover_leftovers, replace_dir

__all__ = [
    "atomic_dir",
    "atomic_file",
    "check_distinct",
    "check_output",
    "input_clash",
    "save_figure",
    "write_json",
    "write_text",
]


def check_output(path: str | os.PathLike, force: bool = False, flag: str = "--out",
                 kind: str = "file", inputs=()) -> Path:
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
    inputs : iterable of path-like
        The files and folders the command reads. An output that is one of them or contains one
        is refused, with or without ``force`` (``--force`` never replaces an input).

    Returns
    -------
    Path
        ``path`` as a :class:`~pathlib.Path`.

    Raises
    ------
    OutputError
        One sentence naming ``flag`` and the path: it is or contains an input, it exists (without
        ``force``), it is a folder where a file is expected (or the reverse), or its parent
        folder is missing or not writable.
    """
    p = Path(path)
    if p.exists():
        if kind == "file" and p.is_dir():
            raise OutputError(f"{flag} {p}: is a folder, expected a file name.")
        if kind == "dir" and not p.is_dir():
            raise OutputError(f"{flag} {p}: is a file, expected a folder name.")
    clash = input_clash(p, inputs)
    if clash is not None:
        raise OutputError(f"{flag} {p}: {clash}; choose another output path.")
    if p.exists():
        if not force:
            raise OutputExistsError(f"{flag} {p}: already exists; refusing to overwrite it "
                              "(use --force to replace it).")
    parent = p.resolve().parent
    if not parent.is_dir():
        raise OutputError(f"{flag} {p}: its folder {parent} does not exist.")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{flag} {p}: its folder {parent} is not writable.")
    return p


def input_clash(path: str | os.PathLike, inputs) -> str | None:
    """Why ``path`` may not be written by a command reading ``inputs`` (None if it may).

    An output may not be an input, nor a folder that holds an input (a report written into
    the dataset it reports on, a table import into the folder of its tables).

    Parameters
    ----------
    path : path-like
        The output file or folder.
    inputs : iterable of path-like or None
        The files and folders the command reads (None entries are skipped).

    Returns
    -------
    str or None
        ``"is the input X"`` or ``"holds the input X"``, None when there is no clash.
    """
    out = Path(path).resolve()
    for item in inputs or ():
        if item is None:
            continue
        src = Path(item).resolve()
        if out == src:
            return f"is the input {item}"
        if out in src.parents:
            return f"holds the input {item}"
    return None


def check_distinct(outputs: dict) -> None:
    """Refuse two outputs of one command that are the same file.

    Parameters
    ----------
    outputs : dict
        ``{flag: path}`` of every output the command writes; None paths are skipped.

    Raises
    ------
    OutputError
        Two flags resolve to the same path (the sentence names both).
    """
    seen: dict[Path, str] = {}
    for flag, path in outputs.items():
        if path is None:
            continue
        key = Path(path).resolve()
        if key in seen:
            raise OutputError(f"{flag} {path}: is the same file as {seen[key]}; give each output "
                              "its own path.")
        seen[key] = f"{flag} {path}"


@contextlib.contextmanager
def atomic_file(path: str | os.PathLike, mode: str = "w", force: bool = True) -> Iterator:
    """Open a temporary file beside ``path``; renamed onto ``path`` only if the block completes.

    Parameters
    ----------
    path : path-like
        The target file.
    mode : str
        The open mode (``"w"`` text as UTF-8, ``"wb"`` binary).
    force : bool
        False refuses an existing ``path`` (checked again at the rename).

    Yields
    ------
    file
        The open temporary file; it is flushed, synced and renamed into place when the block
        ends without an exception or pending signal, removed otherwise.

    Raises
    ------
    OutputExistsError
        ``path`` exists and ``force`` is False.
    OutputError
        ``path`` is a folder, or its folder cannot be written.
    """
    p = Path(path)
    if not force and p.exists():
        raise OutputExistsError(f"{p}: already exists; refusing to overwrite it (use --force).")
    if p.is_dir():
        raise OutputError(f"{p}: is a folder, expected a file name.")
    tmp = None
    try:
        with held():  # a signal held meanwhile is raised at its end, the name known
            try:
                fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part",
                                           dir=p.resolve().parent)
            except OSError as exc:
                raise OutputError(f"{p}: cannot write in its folder ({exc.strerror}).") from None
        with os.fdopen(fd, mode, **({} if "b" in mode else {"encoding": "utf-8"})) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual permissions
        check_pending()  # never commit an output after a signal (one swallowed elsewhere)
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
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
        raise


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text(path: str | os.PathLike, text: str, force: bool = True) -> Path:
    """Write ``text`` to ``path`` atomically.

    Parameters
    ----------
    path : path-like
        The target file.
    text : str
        The content, written as UTF-8.
    force : bool
        Replace an existing file (False refuses it).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    OutputExistsError, OutputError
        As :func:`atomic_file`.
    """
    with atomic_file(path, "w", force=force) as fh:
        fh.write(text)
    return Path(path)


def write_json(path: str | os.PathLike, data: dict, force: bool = True) -> Path:
    """Write ``data`` as indented JSON to ``path`` atomically.

    Parameters
    ----------
    path : path-like
        The target file.
    data : dict
        JSON-able data (NaN and infinity are written as ``NaN``/``Infinity``).
    force : bool
        Replace an existing file (False refuses it).

    Returns
    -------
    Path
        ``path``.
    """
    return write_text(path, json.dumps(data, indent=2, allow_nan=True) + "\n", force=force)


def save_figure(fig, path: str | os.PathLike, force: bool = True, **kwargs) -> Path:
    """``fig.savefig`` to a temporary name beside ``path``, renamed into place when complete.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    path : path-like
        The target file; its suffix gives the format unless ``format`` is passed.
    force : bool
        Replace an existing file (False refuses it).
    **kwargs
        Passed to ``fig.savefig`` (e.g. ``dpi``, ``format``).

    Returns
    -------
    Path
        ``path``.
    """
    p = Path(path)
    fmt = kwargs.pop("format", None) or (p.suffix.lstrip(".") or "png")
    with atomic_file(p, "wb", force=force) as fh:
        fig.savefig(fh, format=fmt, **kwargs)
    return p


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike, force: bool = False, owned=()) -> Iterator[Path]:
    """Build a folder under a temporary name beside ``path``; it appears whole or not at all.

    When the block completes:

    * ``path`` did not exist (or was an empty folder): the temporary folder is renamed onto it;
      if another run created it meanwhile, :class:`~cdprid.base.OutputExistsError` (one run wins,
      the other exits 2).
    * ``path`` is a non-empty folder (allowed only with ``force``): each entry this command
      wrote replaces the entry of the same name, and the entries named in ``owned`` that this
      run did not write are removed. **Nothing else in the folder is touched**: ``--force``
      replaces this command's own files, never a folder's other contents. The replacement is
      atomic: the folder is the old one or the complete new one, never a mix.
    * ``path`` is a symbolic link to a folder: the folder it points to is written.

    When the block fails or is interrupted, the temporary folder is removed and ``path`` is
    left as it was.

    Parameters
    ----------
    path : path-like
        The target folder.
    force : bool
        Allow writing into an existing non-empty folder.
    owned : iterable of str
        Names of the files this kind of command writes (e.g. a dataset's ``lengths.csv``).

    Yields
    ------
    Path
        The temporary folder to write into.

    Raises
    ------
    OutputExistsError
        ``path`` is a non-empty folder without ``force``, or appeared meanwhile.
    OutputError
        ``path`` is a file, or its parent folder cannot be written.
    """
    p = Path(path)
    if p.name in ("", ".", "..") or p.is_symlink():  # ".", "..", a link: the folder itself
        p = p.resolve()
    recover_leftovers(p)  # a crash inside an earlier replacement of p (see _replace.py)
    if p.exists() and not p.is_dir():
        raise OutputError(f"{p}: is a file, expected a folder name.")
    existed = p.exists() and any(p.iterdir())
    if existed and not force:
        raise OutputExistsError(f"{p}: already exists; refusing to overwrite it (use --force).")
    parent = p.resolve().parent
    tmp = None
    try:
        with held():
            try:
                parent.mkdir(parents=True, exist_ok=True)
                tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", suffix=".part", dir=parent))
            except OSError as exc:
                raise OutputError(f"{p}: cannot write in its folder {parent} ({exc.strerror})."
                                  ) from None
        yield tmp
        check_pending()  # never commit an output after a signal
        if existed:
            replace_dir(tmp, p, owned)
        else:
            _rename_new(tmp, p)
    except BaseException:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise


def _rename_new(tmp: Path, p: Path) -> None:
    """Rename the finished folder onto a path that was free at the start (re-checked now)."""
    try:
        os.rename(tmp, p)  # onto a missing or empty folder only
    except OSError as exc:
        if exc.errno in (errno.ENOTEMPTY, errno.EEXIST) or p.exists():
            raise OutputExistsError(f"{p}: was created by another run meanwhile; refusing to "
                                    "overwrite it (use --force).") from None
        raise
