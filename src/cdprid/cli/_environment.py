"""The environment variables ``cdprid`` reads, and JAX's set-up before a command runs.

* ``CDPRID_DEBUG`` -- any non-empty value: tracebacks of internal errors.
* ``CDPRID_CACHE_DIR`` -- folder of the persistent JAX compilation cache (default
  ``$XDG_CACHE_HOME/cdprid/jax`` or ``~/.cache/cdprid/jax``) and, in its ``executables/``
  folder, of the compiled programs a command's start needs, tracing included
  (:func:`cdprid.base.cached_executable`); ``off`` disables both.
* ``CDPRID_SCAN_UNROLL`` -- integer >= 1, unroll factor of the SIHD scans.

Nothing here imports JAX until :func:`enable_x64` runs (after the command line is parsed).
"""

from __future__ import annotations

import os

__all__ = ["environment_error", "enable_x64", "jax_cache_dir"]


def environment_error() -> str | None:
    """The sentence saying which environment variable has a bad value, or None when all are
    valid (checked before any work; the command then ends with exit code 2).

    Returns
    -------
    str or None
    """
    unroll = os.environ.get("CDPRID_SCAN_UNROLL")
    if unroll is not None:
        try:
            ok = int(unroll.strip()) >= 1
        except ValueError:
            ok = False
        if not ok:
            return (f"environment variable CDPRID_SCAN_UNROLL={unroll!r} must be an integer of "
                    "at least 1 (unset it for the default 1).")
    cache = os.environ.get("CDPRID_CACHE_DIR")
    if cache is not None and cache.strip().lower() not in ("off", "0", "none", ""):
        p = os.path.expanduser(cache)  # os.path: pathlib costs ~7 ms of `cdprid --help`
        if os.path.exists(p) and not os.path.isdir(p):
            return (f"environment variable CDPRID_CACHE_DIR={cache!r} names a file, not a "
                    "folder (use a folder, or 'off' to disable the cache).")
    return None


def jax_cache_dir():
    """The folder of the persistent JAX compilation cache, or None when disabled.

    ``CDPRID_CACHE_DIR`` overrides the default ``$XDG_CACHE_HOME/cdprid/jax`` (or
    ``~/.cache/cdprid/jax``); ``CDPRID_CACHE_DIR=off`` disables the cache.

    Returns
    -------
    pathlib.Path or None
    """
    from pathlib import Path

    env = os.environ.get("CDPRID_CACHE_DIR")
    if env is not None:
        if env.strip().lower() in ("off", "0", "none", ""):
            return None
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cdprid" / "jax"


def enable_x64() -> None:
    """Float64 in JAX and its persistent compilation cache (:func:`jax_cache_dir`), for the
    command about to run; an unusable cache folder is skipped, never an error."""
    import jax

    jax.config.update("jax_enable_x64", True)
    cache = jax_cache_dir()
    if cache is None:
        return
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:
        return  # an unwritable cache only costs compile time; never fail a command for it
    if not os.access(cache, os.W_OK | os.X_OK):
        return
    jax.config.update("jax_compilation_cache_dir", str(cache))
    # every compiled kernel is kept: loading one costs ~10 ms, compiling the small ones ~40 ms
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    from cdprid.base import enable_executables

    # the few large programs of a command's start kept whole, tracing included
    # (cdprid.base._executables; the folder beside the XLA entries)
    enable_executables(cache / "executables")
