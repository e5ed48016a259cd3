"""cdprid.core._linear_match: the private second difference of the linear match (moved from
``tests/identify/test_rotation_consistent.py`` with the module, issue 36)."""

from __future__ import annotations

import numpy as np

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
