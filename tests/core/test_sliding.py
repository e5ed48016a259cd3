"""The friction sign of the diagnosis (:func:`cdprid.core.sliding_sign`): the expected sign
of a Gaussian-derivative speed.

Oracles: exact derivatives of polynomials, the kernel's noise gain against a Monte-Carlo
std, and the errors-in-variables bias of a Coulomb level fitted on a sign with errors.
"""

import numpy as np
import pytest

from cdprid.core import SLIDE_NOISE_M_S, gauss_derivative, sliding_sign
from cdprid.signal import zero_phase_filter

DT = 0.01


def test_gaussian_derivative_is_exact_on_quadratics_and_attenuates_like_a_gaussian():
    t = np.arange(2000) * DT
    x = np.column_stack([3.0 * t - 1.0, 0.5 * t**2])
    dx, h = gauss_derivative(x, DT, 0.033)
    half = len(h) // 2
    inner = slice(half, -half)  # away from the reflected ends
    assert np.allclose(dx[inner, 0], 3.0, atol=1e-9)
    assert np.allclose(dx[inner, 1], t[inner], atol=1e-9)
    f, sig = 1.3, 0.033
    dx, _ = gauss_derivative(np.sin(2 * np.pi * f * t)[:, None], DT, sig)
    want = 2 * np.pi * f * np.cos(2 * np.pi * f * t) * np.exp(-0.5 * (2 * np.pi * f * sig) ** 2)
    assert np.max(np.abs(dx[inner, 0] - want[inner])) < 2e-3 * 2 * np.pi * f


def test_sliding_speed_noise_std_matches_monte_carlo():
    rng = np.random.default_rng(0)
    n, noise = 6000, 4e-4
    t = np.arange(n) * DT
    clean = 1.5 + 0.2 * np.sin(2 * np.pi * 0.2 * t)[:, None] + np.zeros((n, 3))
    _, speed, std = sliding_sign(clean + noise * rng.normal(size=(n, 3)), DT, 4.0)
    _, speed0, _ = sliding_sign(clean, DT, 4.0)
    err = (speed - speed0)[100:-100]  # the kernel is linear: this is the noise's part
    assert np.allclose(std, err.std(0), rtol=0.1)
    assert np.all(std > SLIDE_NOISE_M_S)  # this noise is above the floor


def test_expected_sign_is_calibrated_and_sure_away_from_reversals():
    """Binned by its value, the expected sign matches the mean of the true sign."""
    rng = np.random.default_rng(1)
    n = 20000
    t = np.arange(n) * DT
    w1, w2 = 2 * np.pi * 0.25, 2 * np.pi * 0.4
    true_rate = np.column_stack([0.03 * np.cos(w1 * t), 0.01 * np.cos(w2 * t + 1.0)])
    lengths = np.column_stack([0.03 / w1 * np.sin(w1 * t), 0.01 / w2 * np.sin(w2 * t + 1.0)])
    lengths += 3e-4 * rng.normal(size=lengths.shape)
    sign, _, std = sliding_sign(lengths, DT, 4.0)
    inner = slice(50, -50)
    s, truth = sign[inner].ravel(), np.sign(true_rate[inner]).ravel()
    sure = np.abs(s) > 0.999
    assert np.all(s[sure] * truth[sure] > 0)  # never confidently wrong
    assert sure.mean() > 0.6  # slow motion: 10-30 mm/s peaks, 2 mm/s noise
    for lo in np.arange(-0.9, 0.9, 0.3):  # calibration where the sign is uncertain
        b = (s >= lo) & (s < lo + 0.3)
        assert b.sum() > 50
        assert abs(truth[b].mean() - s[b].mean()) < 0.12


@pytest.mark.parametrize("seed,scale", [(2, 1.0), (3, 1.0), (4, 4.0)])
def test_coulomb_level_on_the_expected_sign_is_unbiased(seed, scale):
    """y = c sign(true rate) + noise, fitted with the matched filter on the estimated signs:
    the expected sign is unbiased; a dead zone (sign 0 near reversals) inflates the level."""
    rng = np.random.default_rng(seed)
    n, c = 12000, 2.0
    t = np.arange(n) * DT
    # a slow motion with many reversals, position noise of a motion-capture system
    true_l = scale * (0.02 * np.sin(2 * np.pi * 0.3 * t)
                      + 0.01 * np.sin(2 * np.pi * 0.77 * t + 0.4))
    true_rate = np.gradient(true_l, DT)
    y = c * np.sign(true_rate) + 0.5 * rng.normal(size=n)
    sign, speed, std = sliding_sign((true_l + 3e-4 * rng.normal(size=n))[:, None], DT, 4.0)
    yf = zero_phase_filter(y[:, None], DT, 4.0, 2)[:, 0]
    inner = slice(200, -200)

    def fit(s):
        xf = zero_phase_filter(np.asarray(s, float), DT, 4.0, 2)[:, 0]
        return float(xf[inner] @ yf[inner] / (xf[inner] @ xf[inner]))

    assert abs(fit(sign) - c) < 0.01 * c
    dead_zone = np.where(np.abs(speed) > 4 * std, np.sign(speed), 0.0)
    if scale == 1.0:  # slow: many samples near reversals
        assert fit(dead_zone) > 1.02 * c


def test_expected_sign_is_scipys_erf_per_column_and_the_sign_without_noise():
    """The one implementation of the sliding sign's expectation (the diagnosis, the episodes'
    null model, the drives' fit): scipy's erf of v / (sqrt(2) std) with a std per column, the
    plain sign where the std is 0, and a Monte-Carlo mean of sign(v + noise) at one point."""
    from scipy.special import erf

    from cdprid.core import expected_sign

    rng = np.random.default_rng(3)
    v = rng.normal(size=(200, 3)) * 0.01
    std = np.array([0.002, 0.0, 0.05])
    got = expected_sign(v, std)
    assert np.allclose(got[:, 0], erf(v[:, 0] / (np.sqrt(2) * 0.002)), rtol=0, atol=1e-15)
    assert np.array_equal(got[:, 1], np.sign(v[:, 1]))
    assert np.allclose(got[:, 2], erf(v[:, 2] / (np.sqrt(2) * 0.05)), rtol=0, atol=1e-15)
    assert np.array_equal(expected_sign(v, 0.0), np.sign(v))
    mc = np.mean(np.sign(0.003 + 0.004 * rng.normal(size=400_000)))
    assert abs(float(expected_sign(0.003, 0.004)) - mc) < 0.005  # MC std 0.0013
