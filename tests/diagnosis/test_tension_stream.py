"""The forward model interpolates the low-passed tension stream (issue 37: an 800 Hz stream's
clock offset read 2 ms early with an interval that excluded the truth)."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.core import CATMULL_ROM, SMOOTH_HZ, TensionStream, tension_at
from cdprid.diagnosis._problem import smoothed_stream


def _noise_variance_at(stream, frac, rng_cols):
    """Variance of the interpolated stream at the fraction ``frac`` of every sample interval."""
    s = stream.t0 + stream.dt * (np.arange(200, stream.values.shape[0] - 200) + frac)
    return float(np.var(np.asarray(tension_at(stream, s, CATMULL_ROM))))


def test_interpolated_noise_no_longer_ripples_with_the_tension_step(rng):
    """White noise at 800 Hz: interpolated mid-interval its variance is 0.63 of that at the
    samples (Catmull-Rom weights -1/16, 9/16, 9/16, -1/16), so a fit's cost ripples with the
    1.25 ms step in the delay; after the stream's low-pass the two agree within 3 %."""
    t = np.arange(0.0, 60.0, 1 / 800)
    raw = TensionStream.from_arrays(t, rng.normal(size=(t.size, 4)))
    v0, v5 = _noise_variance_at(raw, 0.0, 4), _noise_variance_at(raw, 0.5, 4)
    assert 0.60 < v5 / v0 < 0.67, v5 / v0  # the ripple, from first principles
    sm = smoothed_stream(raw)
    s0, s5 = _noise_variance_at(sm, 0.0, 4), _noise_variance_at(sm, 0.5, 4)
    assert abs(s5 / s0 - 1) < 0.03, s5 / s0
    # the band the model fits passes: a 4 Hz sine keeps its amplitude to 0.5 %
    sine = TensionStream.from_arrays(t, np.sin(2 * np.pi * 4.0 * t)[:, None])
    mid = slice(4000, -4000)
    assert np.allclose(np.asarray(smoothed_stream(sine).values)[mid],
                       np.asarray(sine.values)[mid], atol=5e-3)


def test_a_slow_stream_is_interpolated_as_recorded():
    """Below 2.5 x SMOOTH_HZ samples per second the low-pass would reach the Nyquist band."""
    t = np.arange(0.0, 10.0, 1 / (2.0 * SMOOTH_HZ))
    raw = TensionStream.from_arrays(t, np.cos(t)[:, None] * np.ones((1, 3)))
    assert smoothed_stream(raw) is raw


@pytest.mark.slow
def test_the_clock_of_a_clean_800_hz_recording_is_covered(tmp_path):
    """The test simulator's floor-winch robot, tensions at 800 Hz on their own clock, no
    effect (seed 3, 20 s): the delay refitted alone in the base model is 0 within its 95 %
    interval, and that interval is not a ripple's (std > 0.1 ms; was -2.02 +- 0.04 ms)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import tests._testbench as tb

    from cdprid.diagnosis import base_fit, prepare, start
    from cdprid.diagnosis._profile import clock_index
    from cdprid.diagnosis._selection import refit
    from cdprid.io import read_dataset

    rec = tb.floor8_with([], 3, duration_s=20.0)
    assert rec.sensors.tension_rate_hz == 800.0 and rec.sensors.clock_offset_s == 0.0
    prob, base = base_fit(prepare(read_dataset(tb.write(rec, tmp_path / "d"))))
    s = start(prob, base)
    di = clock_index(prob)
    t = refit(prob, s, active_idx=[di])
    d, sd = float(t.theta[di]), float(np.sqrt(t.th_cov[di, di]))
    assert abs(d) < 1.96 * sd and sd > 1e-4, (d, sd)
