"""cdprid.base's tail probabilities against scipy.stats (the oracle they replace)."""

import numpy as np
from scipy import stats

from cdprid.base import chi2_isf, chi2_logsf, chi2_sf, f_isf, f_sf, normal_isf, normal_sf


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


def test_the_diagnosis_tails_are_scipy_stats_to_the_last_bit():
    """The diagnosis's p-values decide its search: chi2.sf, chi2.logsf (its sort key), norm.sf
    and f.sf equal scipy.stats bit for bit, on and off the support (x < 0, nan, inf) and for
    scalars (NumPy scalars, as scipy.stats returns them)."""
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.exponential(5.0, 4000), rng.uniform(0.0, 3000.0, 4000),
                        rng.uniform(-1.0, 0.0, 50), [0.0, 1e-300, 1e5, np.inf, np.nan, -1e-18]])

    def same(a, b):
        return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)

    for k in (1, 2, 3, 5, 8, 12, 24, 48):
        assert same(chi2_sf(x, k), stats.chi2.sf(x, k)), k
        assert same(chi2_logsf(x, k), stats.chi2.logsf(x, k)), k
        for v in (3.2, -0.5, 0.0):
            for mine, ref in ((chi2_sf, stats.chi2.sf), (chi2_logsf, stats.chi2.logsf)):
                a, b = mine(v, k), ref(v, k)
                assert a == b and type(a) is type(b), (mine.__name__, v, k, a, b)
    z = np.concatenate([rng.normal(0.0, 4.0, 4000), [-40.0, 40.0, np.inf, -np.inf]])
    assert same(normal_sf(z), stats.norm.sf(z))
    q = np.concatenate([rng.exponential(3.0, 4000), [-1.0, 0.0, np.nan]])
    for dfn, dfd in ((2, 4), (2, 10), (2, 60), (3, 7)):
        assert same(f_sf(q, dfn, dfd), stats.f.sf(q, dfn, dfd)), (dfn, dfd)
    assert np.isnan(chi2_sf(2.0, 0)) and np.isnan(stats.chi2.sf(2.0, 0))


def test_the_thresholds_quantiles_need_no_scipy_and_match_it():
    """normal_isf and chi2_isf at integer dof (q <= 0.5: every episode threshold) are the
    standard library's and a closed-form Newton solve: within 4e-15 of scipy.stats over
    q in [1e-250, 0.5], k = 1..64, and computed in a process that never imports SciPy."""
    import subprocess
    import sys

    q = np.concatenate([np.logspace(-250, np.log10(0.5), 120), [0.5, 0.4999]])
    for k in range(1, 65):
        got = chi2_isf(q, k)
        assert np.allclose(got, stats.chi2.isf(q, k), rtol=4e-15, atol=0), k
    qq = np.logspace(-300, -1e-4, 400)
    assert np.allclose(normal_isf(qq), stats.norm.isf(qq), rtol=4e-15, atol=0)
    code = ("import sys; from cdprid.base import chi2_isf, normal_isf; "
            "x = [float(chi2_isf(q, k)) for q in (1e-9, 0.001, 0.1, 0.5) for k in (1, 2, 3, 6)]; "
            "z = float(normal_isf(1e-7)); "
            "import cdprid.episodes, cdprid.identify; "
            "print(sorted(m for m in sys.modules if m.startswith('scipy')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", out
