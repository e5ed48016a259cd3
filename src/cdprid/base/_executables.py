"""Compiled programs kept across processes: a command's start without tracing.

JAX's persistent compilation cache (``jax_compilation_cache_dir``) keeps the XLA compile of a
program, not its tracing and lowering: a fresh process still traces every jitted function it
calls (for ``cdprid identify`` 12 programs, 0.45 s of its ~2.5 s, most of it the
errors-in-variables Jacobians). :func:`cached_executable` keeps the compiled executable
itself (``jax.experimental.serialize_executable``), one file per function, static
arguments, argument structure and shapes, so a later process loads it in milliseconds.

It is off unless an entry point turns it on (:func:`enable_executables`, done by the CLI
beside JAX's own cache): a library call or a test always traces, and the decorated function
behaves exactly as the jitted one. A stored executable is used only when everything it was
built from is the same: the function (module, name), its static arguments, the pytree
structure of the others (static fields included) and their shapes, dtypes and weak types,
the source of every cdprid module, the JAX and jaxlib versions, float64 on or off, the
backend and the processor (its model and instruction-set flags: an executable holds
machine code). Anything else compiles anew; a file that cannot be read is replaced; inside
a JAX trace the function is simply inlined.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle

__all__ = ["cached_executable", "enable_executables", "executables_folder"]

#: Bytes the folder may hold: after a write the least recently used executables are deleted
#: beyond it (one per function and shape, ~0.1-0.5 MB each: a few hundred recordings of
#: different lengths)
MAX_BYTES = 256 * 2**20

_FOLDER = None
_MEMO: dict = {}
_STAMP = None
_NAMES: set = set()


def enable_executables(folder) -> None:
    """Keep compiled executables in ``folder`` (created when needed); None turns it off.

    Parameters
    ----------
    folder : str or os.PathLike or None
        The folder (the CLI uses ``executables/`` inside its JAX cache folder).
    """
    global _FOLDER
    _FOLDER = None if folder is None else os.fspath(folder)


def executables_folder():
    """The folder in use, or None when executables are not kept.

    Returns
    -------
    str or None
    """
    return _FOLDER


def _stamp() -> str:
    """What every key shares: cdprid's sources, JAX's versions, x64, backend, processor."""
    global _STAMP
    import jax
    import jaxlib

    if _STAMP is None:
        root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
        h = hashlib.sha256()
        for d, dirs, files in sorted(os.walk(root)):
            dirs.sort()
            for f in sorted(files):
                if f.endswith(".py"):
                    p = os.path.join(d, f)
                    h.update(os.path.relpath(p, root).encode())
                    with open(p, "rb") as fh:
                        h.update(fh.read())
        cpu = ""
        try:
            with open("/proc/cpuinfo") as fh:
                cpu = "".join(sorted({ln for ln in fh if ln.startswith(("model name", "flags"))}))
        except OSError:
            import platform

            cpu = platform.machine() + platform.processor()
        dev = jax.devices()[0]
        _STAMP = repr((h.hexdigest(), jax.__version__, jaxlib.__version__, dev.platform,
                       dev.device_kind, cpu))
    return _STAMP + repr((bool(_flag("jax_enable_x64")),
                          bool(_flag("jax_disable_most_optimizations"))))


def _flag(name: str):
    """A JAX configuration value (flags with a context manager read as attributes)."""
    import jax

    try:
        return getattr(jax.config, name)
    except AttributeError:
        return jax.config.read(name)


def cached_executable(fn=None, *, name: str, static_argnums=()):
    """Decorate a jitted function: when :func:`enable_executables` is on, call a compiled
    executable stored on disk for these arguments instead of tracing (see the module
    docstring); otherwise call ``fn`` itself.

    Parameters
    ----------
    fn : callable
        A jitted function (``jax.jit``), called with positional arguments only.
    name : str
        A name no other decorated function has (it enters the key: ``jax.jit(jax.vmap(f))``
        and ``jax.jit(f)`` share ``f``'s name but are different programs).
    static_argnums : tuple of int
        Its static arguments (hashable; their ``repr`` enters the key).

    Returns
    -------
    callable
        Same signature and results as ``fn``; ``__wrapped__`` is ``fn``.
    """
    if fn is None:
        return functools.partial(cached_executable, name=name, static_argnums=static_argnums)
    if name in _NAMES:
        raise RuntimeError(f"cached_executable: the name {name!r} is already in use")
    _NAMES.add(name)
    static = tuple(static_argnums)

    @functools.wraps(fn)
    def call(*args):
        if _FOLDER is None:
            return fn(*args)
        try:
            found = _executable(fn, name, static, args)
        except Exception as e:  # noqa: BLE001  a cache that fails only costs the trace
            if os.environ.get("CDPRID_DEBUG"):
                import sys

                print(f"cdprid: executable cache of {name}: {e!r}", file=sys.stderr)
            found = None
        if found is None:
            return fn(*args)
        exe, leaves, key = found
        try:  # an executable that cannot run is dropped (file included), never trusted
            import jax

            return jax.block_until_ready(exe(*leaves))
        except Exception as e:  # noqa: BLE001
            _drop(key, name, e)
            return fn(*args)

    return call


def _executable(fn, name, static, args):
    """``(executable, leaves)`` for these arguments, or None (trace instead)."""
    import jax

    stat = tuple(args[i] for i in static)
    dyn = tuple(a for i, a in enumerate(args) if i not in static)
    leaves, tree = jax.tree_util.tree_flatten(dyn)
    if any(isinstance(x, jax.core.Tracer) for x in leaves):
        return None
    tree_s, stat_s = str(tree), repr(stat)
    if any("..." in x or " at 0x" in x for x in (tree_s, stat_s)):
        return None  # a static value whose repr does not say all it holds
    avals = [jax.typeof(x) for x in leaves]
    spec = repr((name, stat_s, tree_s,
                 [(a.shape, str(a.dtype), a.weak_type) for a in avals]))
    key = hashlib.sha256((spec + _stamp()).encode()).hexdigest()[:40]
    exe = _MEMO.get(key)
    if exe is None:
        _MEMO[key] = False  # a failure below is not retried in this process
        exe = _load(key) or _build(fn, static, args, tree, leaves, key)
        _MEMO[key] = exe
    return (exe, leaves, key) if exe else None


def _drop(key, name, err):
    """Forget the executable ``key`` (in this process and on disk) after it failed."""
    _MEMO[key] = False
    try:
        os.remove(os.path.join(_FOLDER, key + ".exe"))
    except OSError:
        pass
    if os.environ.get("CDPRID_DEBUG"):
        import sys

        print(f"cdprid: executable of {name} dropped: {err!r}", file=sys.stderr)


def _load(key):
    from jax.experimental import serialize_executable

    path = os.path.join(_FOLDER, key + ".exe")
    if not os.path.exists(path):
        return None
    try:
        with open(path, "rb") as fh:
            exe = serialize_executable.deserialize_and_load(*pickle.load(fh))
    except Exception:  # noqa: BLE001  unreadable (an older format, a torn write): rebuilt
        return None
    try:
        os.utime(path)  # used now: the last to go (_evict)
    except OSError:
        pass
    return exe


def _build(fn, static, args, tree, leaves, key):
    import jax
    from jax.experimental import serialize_executable

    def flat(*lv):
        it = iter(jax.tree_util.tree_unflatten(tree, lv))
        return fn(*(args[i] if i in static else next(it) for i in range(len(args))))

    # compiled here, never taken from JAX's persistent cache: an executable loaded from it
    # serializes without the code of its fusions on CPU (a later process then fails with
    # "Function ... not found"); a stored one that fails to run is dropped (``_drop``)
    was = _flag("jax_enable_compilation_cache")
    jax.config.update("jax_enable_compilation_cache", False)
    try:
        exe = jax.jit(flat).lower(*leaves).compile()
    finally:
        jax.config.update("jax_enable_compilation_cache", was)
    tmp = os.path.join(_FOLDER, f".{key}.{os.getpid()}.tmp")
    try:
        blob = pickle.dumps(serialize_executable.serialize(exe))
        os.makedirs(_FOLDER, exist_ok=True)
        with open(tmp, "wb") as fh:
            fh.write(blob)
        os.replace(tmp, os.path.join(_FOLDER, key + ".exe"))
        _evict(MAX_BYTES)
    except Exception:  # noqa: BLE001  an output tree pickle cannot hold, a read-only folder
        if os.path.exists(tmp):
            os.remove(tmp)
    return exe


def _evict(limit: int) -> None:
    """Delete the least recently used executables until the folder holds ``limit`` bytes."""
    files = []
    for e in os.scandir(_FOLDER):
        if e.name.endswith(".exe"):
            st = e.stat()
            files.append((st.st_mtime, st.st_size, e.path))
    total = sum(f[1] for f in files)
    for _, size, path in sorted(files):
        if total <= limit:
            break
        try:
            os.remove(path)
            total -= size
        except OSError:
            pass
