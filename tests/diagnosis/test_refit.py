"""The diagnosis's nonlinear refit: damped Gauss-Newton against scipy's least squares."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from cdprid.base import Status
from cdprid.diagnosis import _refit as refit_module
from cdprid.diagnosis._refit import refit_gauss_newton


def _problem(seed: int = 0):
    """A steep nonlinear effect (10 atan(theta (t - 1.5)) on one force row) beside four
    linear platform parameters: the diagnosis's ``design`` contract ``(y, A, C)``."""
    rng = np.random.default_rng(seed)
    n = 200
    t = np.linspace(0.0, 3.0, n)
    A = rng.normal(size=(n, 6, 4))
    x_true = np.array([2.0, -1.0, 0.5, 0.3])

    def g(th):
        out = np.zeros((n, 6))
        out[:, 0] = 10.0 * np.arctan(th[0] * (t - 1.5))
        return out

    def dg(th):
        C = np.zeros((n, 6, 1))
        C[:, 0, 0] = 10.0 * (t - 1.5) / (1.0 + (th[0] * (t - 1.5)) ** 2)
        return C

    meas = A @ x_true + g(np.array([8.0])) + 0.01 * rng.normal(size=(n, 6))

    def design(theta, x, rotational):
        return meas - g(theta), A, dg(theta)

    def residual(z):  # scipy's view: x (4) and theta (1) together
        return (meas - A @ z[:4] - g(z[4:])).ravel()

    return design, residual


@pytest.mark.parametrize("start", [0.5, 30.0, 100.0])
def test_damped_refit_reaches_the_least_squares_optimum(start):
    """From far starts (where a full Gauss-Newton step raises the cost) the damped refit
    converges to scipy's optimum; its status says so."""
    design, residual = _problem()
    ref = least_squares(residual, np.r_[np.zeros(4), 7.0], xtol=1e-14, ftol=1e-14)
    th, x, _, lin, status = refit_gauss_newton(design, np.array([start]), np.zeros(10), [0],
                                               False, np.ones(6), np.ones(200, bool), 3,
                                               max_iter=40)
    assert status is Status.CONVERGED and lin is not None
    np.testing.assert_allclose(th[0], ref.x[4], rtol=1e-6)
    np.testing.assert_allclose(x[:4], ref.x[:4], rtol=1e-6, atol=1e-8)


def test_undamped_step_that_raises_the_cost_is_reported_not_taken(monkeypatch):
    """With full steps only, a start of 30 finds no step that lowers the cost: the refit
    stops there with status failed instead of walking away."""
    design, _ = _problem()
    monkeypatch.setattr(refit_module, "STEP_FRACTIONS", (1.0,))
    th, _, _, lin, status = refit_gauss_newton(design, np.array([30.0]), np.zeros(10), [0],
                                               False, np.ones(6), np.ones(200, bool), 3)
    assert status is Status.FAILED and lin is None
    assert th[0] == 30.0


def test_a_start_where_the_model_is_not_finite_is_a_failed_refit():
    """A design that is NaN at the start (a clock offset reaching past the tension stream,
    which is never extrapolated) ends the refit as failed instead of raising LinAlgError in
    the least squares (UACDPR: a competing model's refit did, 2026-11-27)."""
    design, _ = _problem()

    def nan_design(theta, x, rotational):
        y, A, C = design(theta, x, rotational)
        A = A.copy()
        A[:5] = np.nan
        return y, A, C

    th, _, _, lin, status = refit_gauss_newton(nan_design, np.array([7.0]), np.zeros(10), [0],
                                               False, np.ones(6), np.ones(200, bool), 3)
    assert status is Status.FAILED and lin is None
    assert th[0] == 7.0
