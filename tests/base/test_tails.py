"""cdprid.base's tail probabilities against scipy.stats (the oracle they replace)."""

import numpy as np
from scipy import stats

from cdprid.base import chi2_isf, chi2_sf, f_isf, normal_isf, normal_sf


def test_tails_equal_scipy_stats():
    z = np.linspace(-8.0, 12.0, 41)
    assert np.allclose(normal_sf(z), stats.norm.sf(z), rtol=1e-13, atol=0)
    q = np.logspace(-14, -0.31, 30)
    assert np.allclose(normal_isf(q), stats.norm.isf(q), rtol=1e-12, atol=0)
    for k in (1, 2, 3, 6, 12, 40):
        x = np.linspace(0.0, 200.0, 50)
        assert np.allclose(chi2_sf(x, k), stats.chi2.sf(x, k), rtol=1e-11, atol=1e-300)
        assert np.allclose(chi2_isf(q, k), stats.chi2.isf(q, k), rtol=1e-11, atol=0)
        assert np.isclose(chi2_isf(0.1, k), stats.chi2.ppf(0.9, k), rtol=1e-12)
        for nu in (k + 5, 50, 400):
            f = f_isf(q, k, nu)
            # scipy.stats.f.isf rounds 1 - q (8e-4 off its own sf at q = 1e-14): the oracle is
            # the F law's upper tail at the returned value, and stats.f.isf where q is not tiny
            assert np.allclose(stats.f.sf(f, k, nu), q, rtol=1e-12, atol=0)
            big = q > 1e-4
            assert np.allclose(f[big], stats.f.isf(q[big], k, nu), rtol=1e-12, atol=0)
