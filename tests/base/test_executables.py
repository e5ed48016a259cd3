"""Compiled executables kept across processes (cdprid.base.cached_executable, issue 36).

Oracles: the jitted function itself (bit for bit), a fresh process loading what another
stored, and a stored file that is damaged or incomplete.
"""

from __future__ import annotations

import functools
import os
import subprocess
import sys
import textwrap

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import cdprid.base._executables as ex
from cdprid.base import cached_executable, enable_executables, executables_folder


@functools.partial(jax.jit, static_argnums=(1,))
def _poly(x, power, scale):
    return scale * jnp.concatenate([x ** power, jnp.sin(x)], axis=-1)


_poly_cached = cached_executable(_poly, name="tests.base.poly", static_argnums=(1,))


@pytest.fixture
def folder(tmp_path):
    before = executables_folder()
    enable_executables(tmp_path / "exe")
    ex._MEMO.clear()
    yield tmp_path / "exe"
    enable_executables(before)
    ex._MEMO.clear()


def _files(folder):
    return sorted(p.name for p in folder.glob("*.exe")) if folder.exists() else []


def test_off_calls_the_function_and_writes_nothing(tmp_path):
    assert executables_folder() is None  # the suite never turns it on
    x = np.linspace(0.0, 1.0, 12).reshape(4, 3)
    np.testing.assert_array_equal(_poly_cached(x, 2, 1.5), _poly(x, 2, 1.5))
    assert not any(tmp_path.iterdir())


def test_stored_loaded_and_bit_identical(folder):
    x = np.random.default_rng(0).normal(size=(50, 3))
    want = np.asarray(_poly(x, 3, 2.0))
    np.testing.assert_array_equal(np.asarray(_poly_cached(x, 3, 2.0)), want)
    assert len(_files(folder)) == 1
    ex._MEMO.clear()  # as a new process: loaded from the file
    inode = os.stat(folder / _files(folder)[0]).st_ino  # a rebuilt file replaces it
    np.testing.assert_array_equal(np.asarray(_poly_cached(x, 3, 2.0)), want)
    assert os.stat(folder / _files(folder)[0]).st_ino == inode
    # another static argument, another shape, another dtype: other executables
    _poly_cached(x, 2, 2.0)
    _poly_cached(x[:10], 3, 2.0)
    _poly_cached(x.astype(np.float32), 3, 2.0)
    assert len(_files(folder)) == 4
    np.testing.assert_array_equal(np.asarray(_poly_cached(x[:10], 3, 2.0)),
                                  np.asarray(_poly(x[:10], 3, 2.0)))


def test_damaged_file_is_rebuilt(folder):
    x = np.ones((5, 2))
    _poly_cached(x, 2, 1.0)
    (path,) = folder.glob("*.exe")
    path.write_bytes(b"not an executable")
    ex._MEMO.clear()
    np.testing.assert_array_equal(np.asarray(_poly_cached(x, 2, 1.0)),
                                  np.asarray(_poly(x, 2, 1.0)))
    assert path.read_bytes() != b"not an executable"


def test_inside_a_trace_the_function_is_inlined(folder):
    x = np.random.default_rng(1).normal(size=(7, 3))
    g = jax.jit(lambda y: _poly_cached(y, 2, 0.5).sum())
    assert float(g(x)) == pytest.approx(float(np.asarray(_poly(x, 2, 0.5)).sum()), rel=1e-12)
    assert _files(folder) == []  # nothing stored for tracers
    grad = jax.grad(lambda y: _poly_cached(y, 2, 0.5).sum())(x)
    np.testing.assert_allclose(grad, 2 * 0.5 * x + 0.5 * np.cos(x), rtol=1e-12)


def test_names_are_unique():
    with pytest.raises(RuntimeError, match="already in use"):
        cached_executable(_poly, name="tests.base.poly", static_argnums=(1,))


_CHILD = textwrap.dedent("""
    import sys, jax, numpy as np
    jax.config.update("jax_enable_x64", True)
    jax.config.update("jax_compilation_cache_dir", sys.argv[1] + "/xla")
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    from cdprid.base import cached_executable, enable_executables
    from cdprid.model import quat_to_matrix
    enable_executables(sys.argv[1] + "/exe")
    f = cached_executable(jax.jit(jax.vmap(quat_to_matrix)), name="child.quat")
    q = np.random.default_rng(3).normal(size=(64, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    R = np.asarray(f(q))
    np.save(sys.argv[2], R)
""")


def _child(tmp_path, out):
    env = dict(os.environ, CDPRID_DEBUG="1")
    r = subprocess.run([sys.executable, "-c", _CHILD, str(tmp_path), str(out)], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "dropped" not in r.stderr and "executable cache of" not in r.stderr, r.stderr
    return np.load(out)


def test_a_new_process_runs_what_another_stored(tmp_path):
    # 1 builds (XLA's cache filled by then), 2 rebuilds with XLA's cache full (an executable
    # taken from it would lack its fusions' code), 3 and 4 load; every one the same numbers
    from cdprid.model import quat_to_matrix

    q = np.random.default_rng(3).normal(size=(64, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    want = np.asarray(jax.jit(jax.vmap(quat_to_matrix))(q))
    first = _child(tmp_path, tmp_path / "r1.npy")
    for f in (tmp_path / "exe").glob("*.exe"):
        f.unlink()
    second = _child(tmp_path, tmp_path / "r2.npy")
    (stored,) = (tmp_path / "exe").glob("*.exe")
    inode = os.stat(stored).st_ino
    third = _child(tmp_path, tmp_path / "r3.npy")
    assert os.stat(stored).st_ino == inode  # loaded, not rebuilt (that replaces the file)
    for got in (first, second, third):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(second, third)


class _Opaque:
    """A static argument whose repr is its address: never a key (another object could take
    the same address in another process)."""

    def __init__(self, k):
        self.k = k

    def __hash__(self):
        return hash(self.k)

    def __eq__(self, other):
        return isinstance(other, _Opaque) and other.k == self.k


@functools.partial(jax.jit, static_argnums=(1,))
def _scaled(x, o):
    return x * o.k


_scaled_cached = cached_executable(_scaled, name="tests.base.scaled", static_argnums=(1,))


def test_static_argument_without_a_faithful_repr_is_not_stored(folder):
    x = np.arange(4.0)
    np.testing.assert_array_equal(np.asarray(_scaled_cached(x, _Opaque(3.0))), 3.0 * x)
    assert _files(folder) == []


def test_folder_bounded_least_recently_used_first(folder, monkeypatch):
    x = np.ones((3, 2))
    _poly_cached(x, 2, 1.0)
    (first,) = folder.glob("*.exe")
    size = first.stat().st_size
    os.utime(first, (1.0, 1.0))  # long unused
    monkeypatch.setattr(ex, "MAX_BYTES", int(2.5 * size))
    _poly_cached(x, 3, 1.0)
    ex._MEMO.clear()
    _poly_cached(x, 3, 1.0)  # loaded: used now
    _poly_cached(x, 4, 1.0)  # a third one: over the limit, the unused first goes
    names = _files(folder)
    assert len(names) == 2 and first.name not in names
