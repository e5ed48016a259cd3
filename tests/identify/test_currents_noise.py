"""The HAC bandwidth of ``identify --source currents`` from its filter chain's autocovariance
(identify/_currents_noise.py)."""

import numpy as np
import pytest

from cdprid.identify._currents_noise import chain_alpha, hac_bandwidth


def _moving_average(L):
    def wf(y, scale=None):
        k = np.ones(L) / L
        return np.column_stack([np.convolve(c, k, mode="same") for c in np.asarray(y).T])
    return wf


@pytest.mark.parametrize("L", [1, 5, 20])
def test_chain_alpha_matches_the_moving_average_autocovariance(L):
    """White noise through a moving average of L samples: gamma_j = (L - |j|) / L^2, so
    alpha = (sum |j| gamma_j / sum gamma_j)^2 = ((L^2 - 1) / (3 L))^2 exactly."""
    t = np.arange(40000) * 0.01
    alpha = chain_alpha(t, t, _moving_average(L))
    exact = ((L * L - 1) / (3.0 * L)) ** 2
    assert alpha == pytest.approx(exact, rel=0.06, abs=0.02)


def test_chain_alpha_sees_the_prefilter_and_the_interpolation():
    """A faster stream low-passed before its interpolation is correlated over more pose
    samples than the same chain without the low-pass."""
    ts = np.arange(100000) * 0.002
    t = np.arange(20000) * 0.01
    wf = _moving_average(3)
    assert chain_alpha(ts, t, wf, pre=2.0) > 10 * chain_alpha(ts, t, wf)


def test_hac_bandwidth_is_andrews_formula_clipped():
    assert hac_bandwidth(4.0, 2000) == pytest.approx(1.1447 * 8000 ** (1 / 3))
    assert hac_bandwidth(0.0, 2000) == 1.0
    assert hac_bandwidth(1e9, 2000) == 500.0
    assert hac_bandwidth(float("inf"), 2000) == 500.0
