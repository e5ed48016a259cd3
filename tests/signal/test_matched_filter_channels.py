"""Issue 40 #5: the full model's zero-phase matched regression (cdprid.core) filters its 60
regressor channels 6 at a time (the filter's temporaries were (n, 60) copies, 3 GB at 2 h); that
is exact because the matched filter (cdprid.signal.acceleration_filter, tested here) treats each
channel alone, so the blocks equal the whole to rounding. (Moved from tests/identify: it tests
the signal package; the identification check beside it went to
tests/identify/test_full_model_sample.py.)"""

from __future__ import annotations

import numpy as np

from cdprid.signal import acceleration_filter


def test_matched_filter_channels_are_independent():
    rng = np.random.default_rng(3)
    n, dt = 3000, 0.01
    t = np.arange(n) * dt
    u = np.sin(2 * np.pi * rng.uniform(0.1, 3, 60) * t[:, None]) + 0.01 * rng.normal(size=(n, 60))
    scale = rng.uniform(0.1, 10, 60)
    whole = acceleration_filter(u, dt, "euler-filtfilt", scale=scale, cutoff_hz=3.0, order=2)
    blocks = np.concatenate([acceleration_filter(u[:, j:j + 6], dt, "euler-filtfilt",
                                                 scale=scale[j:j + 6], cutoff_hz=3.0, order=2)
                             for j in range(0, 60, 6)], axis=1)
    np.testing.assert_allclose(blocks, whole, rtol=0, atol=1e-12 * np.abs(whole).max())
