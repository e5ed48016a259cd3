"""The one tension interpolant (:func:`cdprid.core.tension_at`), the one the diagnosis' forward
model reads (Catmull-Rom) and the nuisance fit's (linear); oracles: smooth signals sampled
exactly, the grid values, finite differences, ``np.interp``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from cdprid.core import CATMULL_ROM, TensionStream, tension_at, tension_rate_at


@pytest.fixture(autouse=True)
def _x64():
    jax.config.update("jax_enable_x64", True)


def _signal(t):
    return np.column_stack([50 + 20 * np.sin(2 * np.pi * 3 * t),
                            30 + 5 * np.cos(2 * np.pi * 7 * t)])


def _grid(k=200, dt=1e-3, t0=4.42):
    t = t0 + dt * np.arange(k)
    y = _signal(t)
    return TensionStream.from_arrays(t, y), t, y


def test_interior_matches_a_smooth_signal_and_reproduces_grid_values():
    st, t, y = _grid()
    np.testing.assert_allclose(np.asarray(tension_at(st, jnp.asarray(t[5:-5]), CATMULL_ROM)),
                               y[5:-5], atol=1e-12)
    s = t[10:-10] + 0.37e-3  # between grid points: a cubic of a 3-7 Hz signal at 1 kHz
    np.testing.assert_allclose(np.asarray(tension_at(st, jnp.asarray(s), CATMULL_ROM)),
                               _signal(s), atol=1e-4)


@pytest.mark.parametrize("method", ["linear", CATMULL_ROM])
def test_times_off_the_grid_read_its_end_values_not_an_extrapolated_cubic(method):
    st, t, y = _grid()
    before = t[0] - np.array([0.025, 0.010, 0.0015])  # a 25 ms delay shifts samples off it
    after = t[-1] + np.array([0.0015, 0.010, 0.025])
    np.testing.assert_allclose(np.asarray(tension_at(st, jnp.asarray(before), method)),
                               np.repeat(y[:1], 3, axis=0), atol=1e-12)
    np.testing.assert_allclose(np.asarray(tension_at(st, jnp.asarray(after), method)),
                               np.repeat(y[-1:], 3, axis=0), atol=1e-12)


def test_end_intervals_are_linear_and_continuous():
    """Catmull-Rom has no neighbour on the first and last intervals: linear there (as
    ``np.interp``), and continuous where the cubic takes over."""
    st, t, y = _grid()
    s = np.r_[t[0] + np.linspace(0, 1, 7) * 1e-3, t[-2] + np.linspace(0, 1, 7) * 1e-3]
    want = np.column_stack([np.interp(s, t, y[:, j]) for j in range(2)])
    np.testing.assert_allclose(np.asarray(tension_at(st, jnp.asarray(s), CATMULL_ROM)), want,
                               atol=1e-12)
    eps = 1e-9
    for edge in (t[1], t[-2]):
        a, b = (np.asarray(tension_at(st, jnp.asarray([edge + h]), CATMULL_ROM))
                for h in (-eps, eps))
        np.testing.assert_allclose(a, b, atol=1e-5)


def test_rate_equals_central_differences_of_the_interpolant():
    st, t, _ = _grid()
    s = t[20:-20:7] + 0.29e-3
    h = 1e-6
    fd = (np.asarray(tension_at(st, jnp.asarray(s + h), CATMULL_ROM))
          - np.asarray(tension_at(st, jnp.asarray(s - h), CATMULL_ROM))) / (2 * h)
    got = np.asarray(tension_rate_at(st, jnp.asarray(s), CATMULL_ROM))
    np.testing.assert_allclose(got, fd, rtol=1e-6, atol=1e-5)
    exact = np.column_stack([20 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * s),
                             -5 * 2 * np.pi * 7 * np.sin(2 * np.pi * 7 * s)])
    np.testing.assert_allclose(got, exact, atol=0.02 * np.max(np.abs(exact)))


def test_a_jittered_stream_is_put_on_a_uniform_grid_and_a_uniform_one_kept():
    st, t, y = _grid()
    same = TensionStream.on_uniform_grid(t, y)
    np.testing.assert_array_equal(np.asarray(same.values), y)
    rng = np.random.default_rng(0)
    tj = t + rng.uniform(-2e-4, 2e-4, size=t.size)  # 20 % jitter of the 1 ms step
    tj[0] = t[0]
    jit = TensionStream.on_uniform_grid(tj, _signal(tj))
    grid = np.asarray(jit.t)
    assert np.allclose(np.diff(grid), np.median(np.diff(tj)), rtol=1e-9)
    np.testing.assert_allclose(np.asarray(jit.values), _signal(grid), atol=0.05)
    with pytest.raises(ValueError, match="step varies"):
        TensionStream.from_arrays(tj, _signal(tj))
