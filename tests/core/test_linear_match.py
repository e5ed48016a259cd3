"""cdprid.core._linear_match: the private second difference of the linear match (moved from
``tests/identify/test_rotation_consistent.py`` with the module, issue 36)."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.core._linear_match import _second


def test_second_difference_skips_the_centre_sample_and_is_exact_on_cubics():
    dt = 0.01
    t = np.arange(200) * dt
    x = (1.0 + 2.0 * t - 3.0 * t ** 2 + 0.5 * t ** 3)[:, None]
    d2 = _second(x, dt)
    np.testing.assert_allclose(d2[3:-3, 0], -6.0 + 3.0 * t[3:-3], atol=1e-8)
    spike = np.zeros((20, 1))
    spike[10] = 1.0  # noise on sample 10 does not reach its own second derivative
    assert _second(spike, dt)[10, 0] == 0.0


def test_noise_gains_of_a_linear_match_use_every_noise_sample():
    """``noise_gains`` passes ``n`` noise samples through the recording's linear match, whose
    segments cover fewer samples (a 26 s recording at 100 Hz, 3000 noise samples): the
    filter is applied on the whole noise sequence (CI 2026-11-28 read uninitialised memory past
    the recording's end and overflowed). Oracle: the sums of products of the impulse
    responses, as for a linear differentiator."""
    from cdprid.core import noise_gains
    from cdprid.core._linear_match import LinearMatch
    from cdprid.signal import differentiate

    dt, n = 0.01, 3000
    taps = np.array([0.0, 0.2, 0.5, 0.2, -0.3, -0.6]) / dt ** 2
    taps -= taps.mean()
    taps -= np.arange(len(taps)) * (taps @ np.arange(len(taps))) / (np.arange(len(taps)) ** 2).sum()
    lm = LinearMatch(taps, 0.0, ((0, 2600),), dt)
    C = noise_gains("kalman", {}, dt, lm, n=n)
    assert np.all(np.isfinite(C))
    np.testing.assert_allclose(C, noise_gains("kalman", {}, dt, lm.whole(n), n=n), rtol=1e-12)
    # a-channel variance: white noise through the FIR taps is sum(taps^2)
    assert C[2, 2] == pytest.approx(np.sum(taps ** 2), rel=0.1)
    # and the recording's filter refuses a sequence of another length instead of leaving
    # samples unset
    with pytest.raises(RuntimeError, match="segments cover"):
        lm(np.zeros((n, 3)))
    e = np.zeros((n, 1))
    e[n // 2] = 1.0
    v = np.asarray(differentiate(e, dt, method="kalman")[0])[:, 0]
    assert C[1, 1] == pytest.approx(v @ v, rel=0.15)
