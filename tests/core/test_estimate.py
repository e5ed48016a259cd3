"""Typed estimates (cdprid.core.Estimate / Estimates, issue 36): the numbers against numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from cdprid.core import PARAMETER_UNITS, Estimate, Estimates, parameter_unit
from cdprid.model import PARAMETER_NAMES


def _random_case(seed: int = 3):
    rng = np.random.default_rng(seed)
    names = PARAMETER_NAMES["full"]
    x = rng.normal(size=10)
    B = rng.normal(size=(10, 10))
    cov = B @ B.T * 1e-4
    cov_iid = np.diag(rng.uniform(1e-6, 1e-4, 10))
    crb = np.sqrt(np.diag(cov)) * rng.uniform(0.3, 0.9, 10)
    crb[2] = 0.0  # no bound for this one
    return names, x, cov, cov_iid, crb


def test_estimates_match_numpy_and_keep_the_order():
    names, x, cov, cov_iid, crb = _random_case()
    est = Estimates.from_covariance(names, x, cov, cov_iid, crb)
    s = np.sqrt(np.diag(cov))
    assert est.names == names and len(est) == 10
    np.testing.assert_array_equal(est.values, x)
    np.testing.assert_array_equal(est.std, s)
    np.testing.assert_array_equal([e.std_iid for e in est], np.sqrt(np.diag(cov_iid)))
    np.testing.assert_array_equal([e.rel_std_percent for e in est], 100.0 * s / np.abs(x))
    assert est["mxG"] is est[1]
    assert est[2].crb_std is None and est[2].efficiency is None
    assert est[0].efficiency == s[0] / crb[0]
    assert [e.unit for e in est] == ["kg"] + ["kg m"] * 3 + ["kg m^2"] * 6
    with pytest.raises(KeyError):
        est["nope"]
    assert "Izz" in est and "nope" not in est


def test_interval_is_the_normal_95_percent_interval():
    e = Estimate("m", 6.3, 0.01, 0.02, "kg")
    lo, hi = e.interval
    z = stats.norm.ppf(0.975)
    assert math.isclose(hi - e.value, z * e.std, rel_tol=1e-12)
    assert math.isclose(e.value - lo, z * e.std, rel_tol=1e-12)


def test_json_of_an_estimate_has_the_contract_keys_and_edge_values():
    e = Estimate("m", 0.0, 0.5, 0.4, "kg", crb_std=0.25)
    assert list(e.as_json()) == ["value", "std", "rel_std_percent", "std_iid", "crb_std",
                                 "efficiency"]
    assert e.as_json()["rel_std_percent"] == math.inf and e.efficiency == 2.0
    assert math.isnan(Estimate("m", 0.0, 0.0, 0.0).rel_std_percent)
    names, x, cov, cov_iid, crb = _random_case()
    est = Estimates.from_covariance(names, x, cov, cov_iid)
    assert list(est.as_json()) == list(names)
    assert all(v["crb_std"] is None and v["efficiency"] is None for v in est.as_json().values())


def test_negative_variance_counts_as_zero_and_units_cover_every_parameter():
    est = Estimates.from_covariance(["m"], [1.0], [[-1e-20]], [[4.0]])
    assert est[0].std == 0.0 and est[0].std_iid == 2.0
    assert set(PARAMETER_NAMES["full"]) == set(PARAMETER_UNITS)
    assert parameter_unit("offset_1") == ""
