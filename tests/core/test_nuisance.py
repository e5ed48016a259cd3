"""The one nuisance pipeline (cdprid.core._nuisance): masks, interpolation, joint fit."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from cdprid.base import ConvergenceError
from cdprid.core import (
    NuisanceSpec,
    TensionStream,
    fit_nuisance,
    mask_windows,
    rest_mask,
    taut_mask,
    tension_at,
)


def test_taut_mask_matches_brute_force(rng):
    tt = np.arange(0.0, 5.0, 0.001)
    tau = 20.0 + 30.0 * np.sin(2 * np.pi * np.outer(tt, [0.3, 0.5, 0.7, 0.2])) \
        + rng.normal(0, 0.5, (tt.size, 4))
    t = np.arange(0.0, 5.0, 0.01)
    got = taut_mask(t, tt, tau, threshold_N=5.0, window_s=0.1)
    want = np.array([
        (ti >= 0.1) & (ti <= tt[-1] - 0.1)
        and bool(np.all(tau[np.abs(tt - ti) <= 0.1 + 1e-9] > 5.0)) for ti in t])
    assert want.any() and (~want).any()
    # equal except within one tension sample of a window edge
    assert np.mean(got == want) > 0.99


def test_rest_mask_needs_the_minimum_duration():
    t = np.arange(0.0, 10.0, 0.01)
    speed = np.full(t.size, 0.1)
    speed[(t >= 2.0) & (t < 2.3)] = 0.001  # too short
    speed[(t >= 5.0) & (t < 6.0)] = 0.001
    m = rest_mask(t, speed, max_speed=0.005, min_duration_s=0.5)
    w = mask_windows(t, m)
    assert len(w) == 1 and w[0][0] == pytest.approx(5.0) and w[0][1] == pytest.approx(5.99)


def test_rest_mask_edge_drops_where_a_rest_meets_motion_not_at_the_recording_ends():
    t = np.arange(0.0, 10.0, 0.01)
    speed = np.full(t.size, 0.1)
    speed[t < 1.0] = 0.001  # the recording starts at rest
    speed[(t >= 5.0) & (t < 6.0)] = 0.001
    speed[t >= 9.0] = 0.001  # and ends at rest
    m = rest_mask(t, speed, max_speed=0.005, min_duration_s=0.5, edge_s=0.25)
    w = mask_windows(t, m)
    assert [a for a, _ in w] == pytest.approx([0.0, 5.25, 9.25])
    assert [b for _, b in w] == pytest.approx([0.74, 5.74, 9.99])
    plain = rest_mask(t, speed, max_speed=0.005, min_duration_s=0.5)
    assert np.all(plain[m]) and plain.sum() - m.sum() == 25 + 25 + 25 + 25


@pytest.mark.parametrize("method, degree", [("linear", 1), ("catmull-rom", 2)])
def test_interpolation_reproduces_polynomials(method, degree, rng):
    t = np.arange(0.0, 1.0, 0.01)
    c = rng.normal(size=(degree + 1, 3))
    vals = np.stack([np.polyval(c[:, j], t) for j in range(3)], axis=1)
    s = rng.uniform(0.05, 0.9, 50)
    got = np.asarray(tension_at(TensionStream.from_arrays(t, vals), jnp.asarray(s), method))
    want = np.stack([np.polyval(c[:, j], s) for j in range(3)], axis=1)
    np.testing.assert_allclose(got, want, atol=1e-12)


def test_stream_with_a_gap_is_refused():
    t = np.concatenate([np.arange(0, 1, 0.001), np.arange(1.5, 2, 0.001)])
    with pytest.raises(ValueError, match="gap"):
        TensionStream.from_arrays(t, np.zeros((t.size, 2)))


def _synthetic(delay: float, offset, n_cables: int = 4, seed: int = 0):
    """A linear toy problem with the structure of the real one: y = W k (tau(t + d) - o).

    Tensions are smooth random signals on a 1 kHz grid, W random per pose sample; the model
    side A x is built from the TRUE wrench so that the truth is an exact solution.
    """
    rng = np.random.default_rng(seed)
    tt = np.arange(0.0, 7.0, 0.001)
    f = rng.uniform(0.2, 1.5, (3, n_cables))
    tau = 40.0 + sum(10 * np.sin(2 * np.pi * f[i] * tt[:, None] + i) for i in range(3))
    t = np.arange(1.0, 6.0, 0.01)
    W = rng.normal(size=(t.size, 6, n_cables))
    tau_true = np.stack([np.interp(t + delay, tt, tau[:, j]) for j in range(n_cables)], 1)
    y = np.einsum("nij,nj->ni", W, tau_true - offset)
    p = 3
    A = rng.normal(size=(t.size, 6, p))
    A[:, :, 0] = y  # x = [1, 0, 0] is exact
    return W, A, TensionStream.from_arrays(tt, tau), t, np.array([1.0, 0.0, 0.0])


def test_fit_recovers_delay_and_offsets_noise_free():
    o = np.array([1.5, -2.0, 0.5, 3.0])
    W, A, stream, t, x = _synthetic(0.0123, o)
    spec = NuisanceSpec(offsets=True, delay=True, smooth_hz=None, delay_range_s=0.03)
    fit = fit_nuisance(W, A, stream, t, np.ones(t.size, bool), lambda w: w, spec)
    assert fit.delay == pytest.approx(0.0123, abs=1e-6)
    np.testing.assert_allclose(fit.offset, o, atol=1e-4)
    np.testing.assert_allclose(fit.x, x, atol=1e-6)
    assert np.all(np.isfinite(fit.x_std)) and fit.delay_std >= 0


def test_fit_raises_when_the_solver_stops_early():
    W, A, stream, t, _ = _synthetic(0.0123, np.zeros(4))
    spec = NuisanceSpec(offsets=True, delay=True, smooth_hz=None, delay_range_s=0.03)
    with pytest.raises(ConvergenceError, match="did not converge"):
        fit_nuisance(W, A, stream, t, np.ones(t.size, bool), lambda w: w, spec, max_steps=1)
