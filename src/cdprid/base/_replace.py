"""Atomic replacement of a folder: the old one or the complete new one, never a mix (issue 40).

:func:`replace_dir` is the ``--force`` path of :func:`cdprid.base.atomic_dir`. The new folder
is built whole under a temporary name beside the target; the entries of the old folder that the
command does not own (a user's notes, other runs) are hard-linked (or copied) into it; then the
two folders are exchanged in one step and the old one, now under the temporary name, is
removed. Ctrl-C, SIGTERM and SIGHUP are held (:func:`cdprid.base._interrupts.held`) from the
exchange to the end of the removal, so a signal is acted on only once the target is the
complete new folder and nothing is left beside it.

The exchange is Linux's ``renameat2(..., RENAME_EXCHANGE)`` (an atomic swap of two directory
entries, called through ctypes). Where it does not exist (another OS, an old kernel or C
library, a file system without it) a documented fallback of two renames is used: the target is
renamed to ``.NAME.XXXX.old``, the new folder onto the target, and the old one removed. Only a
crash (SIGKILL, power loss) between the two renames can leave the target missing; the next
:func:`recover_leftovers` of that target (called by every ``atomic_dir``) puts the old folder
back, and removes a leftover ``.old`` folder when the target exists.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
import tempfile
from pathlib import Path

from cdprid.base._interrupts import check_pending, held

__all__ = ["recover_leftovers", "replace_dir"]

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


def _exchange(a: Path, b: Path) -> None:
    """Swap the directory entries ``a`` and ``b`` atomically (Linux ``renameat2``).

    Raises
    ------
    OSError
        ``ENOSYS`` / ``EINVAL`` where the exchange is not supported (the caller falls back).
    """
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (AttributeError, OSError):
        raise OSError(errno.ENOSYS, "renameat2 is not available") from None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) != 0:
        err = ctypes.get_errno()
        raise OSError(err, os.strerror(err), str(a))


def _link_or_copy(src: str, dst: str) -> None:
    try:
        os.link(src, dst, follow_symlinks=False)
    except OSError:  # no hard links here (another device, protected links, FAT)
        shutil.copy2(src, dst, follow_symlinks=False)


def _keep_others(old: Path, new: Path, owned) -> None:
    """Hard-link (or copy) into ``new`` every entry of ``old`` the command does not own: the
    names it wrote and the ``owned`` names are the command's; everything else is the user's."""
    mine = {e.name for e in new.iterdir()} | set(owned)
    for e in old.iterdir():
        if e.name in mine:
            continue
        if e.is_symlink() or not e.is_dir():
            _link_or_copy(str(e), str(new / e.name))
        else:
            shutil.copytree(e, new / e.name, symlinks=True, copy_function=_link_or_copy)
    with contextlib.suppress(OSError):
        os.chmod(new, old.stat().st_mode & 0o7777)


def replace_dir(new: Path, target: Path, owned=()) -> None:
    """Replace the folder ``target`` by the finished folder ``new`` (a sibling) atomically.

    Parameters
    ----------
    new : Path
        The complete new folder, in the same parent folder as ``target``.
    target : Path
        The existing folder to replace (not a symbolic link).
    owned : iterable of str
        Entry names of ``target`` that belong to the command (e.g. a dataset's files): not
        carried over when the new folder lacks them.

    On return ``target`` is the new folder and ``new`` no longer exists; when this raises
    before the exchange, ``target`` is untouched and ``new`` is left for the caller to remove.
    """
    _keep_others(target, new, owned)
    check_pending()
    with held():  # a signal meanwhile is raised at the end, the new folder whole
        try:
            _exchange(new, target)
        except OSError as exc:
            if exc.errno not in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EPERM):
                raise
            _two_renames(new, target)
        else:
            shutil.rmtree(new, ignore_errors=True)  # the old folder, now under the temp name


def _two_renames(new: Path, target: Path) -> None:
    """The fallback without an atomic exchange: target -> .NAME.XXXX.old, new -> target."""
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
    os.rmdir(old)
    os.rename(target, old)
    try:
        os.rename(new, target)
    except BaseException:
        os.rename(old, target)
        raise
    shutil.rmtree(old, ignore_errors=True)


def recover_leftovers(target: Path) -> list[Path]:
    """Repair what a crash during :func:`replace_dir`'s fallback left beside ``target``.

    A ``.NAME.*.old`` folder and no ``target``: the old folder is renamed back (the crash came
    between the two renames). A ``.NAME.*.old`` folder beside an existing ``target``: removed
    (the crash came during the removal). Returns the leftovers found.
    """
    parent = target.parent
    try:
        found = sorted(parent.glob(f".{target.name}.*.old"), key=lambda q: q.stat().st_mtime)
    except OSError:
        return []
    found = [q for q in found if q.is_dir() and not q.is_symlink()]
    stale = list(found)
    if stale and not os.path.lexists(target):
        with contextlib.suppress(OSError):
            os.rename(stale.pop(), target)
    for q in stale:
        shutil.rmtree(q, ignore_errors=True)
    return found
