"""The diagnosis's tension interpolant (:func:`cdprid.diagnosis._model.tension_at`)."""

from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from cdprid.diagnosis._model import tension_at


@pytest.fixture(autouse=True)
def _x64():
    jax.config.update("jax_enable_x64", True)


def _grid(k=200, dt=1e-3, t0=4.42):
    t = t0 + dt * np.arange(k)
    y = np.column_stack([50 + 20 * np.sin(2 * np.pi * 3 * t), 30 + 5 * np.cos(2 * np.pi * 7 * t)])
    return SimpleNamespace(tau_grid=jnp.asarray(y), tau_t0=t0, tau_dt=dt), t, y


def test_interior_matches_a_smooth_signal_and_reproduces_grid_values():
    d, t, y = _grid()
    np.testing.assert_allclose(np.asarray(tension_at(d, jnp.asarray(t[5:-5]))), y[5:-5],
                               atol=1e-12)
    s = t[10:-10] + 0.37e-3  # between grid points: a cubic of a 3-7 Hz signal at 1 kHz
    exact = np.column_stack([50 + 20 * np.sin(2 * np.pi * 3 * s),
                             30 + 5 * np.cos(2 * np.pi * 7 * s)])
    np.testing.assert_allclose(np.asarray(tension_at(d, jnp.asarray(s))), exact, atol=1e-4)


def test_times_off_the_grid_read_its_end_values_not_an_extrapolated_cubic():
    d, t, y = _grid()
    before = t[0] - np.array([0.025, 0.010, 0.0015])  # a 25 ms delay shifts samples off it
    after = t[-1] + np.array([0.0015, 0.010, 0.025])
    np.testing.assert_allclose(np.asarray(tension_at(d, jnp.asarray(before))),
                               np.repeat(y[:1], 3, axis=0), atol=1e-12)
    np.testing.assert_allclose(np.asarray(tension_at(d, jnp.asarray(after))),
                               np.repeat(y[-1:], 3, axis=0), atol=1e-12)
