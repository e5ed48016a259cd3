"""Errors-in-variables weighting of identify (issue 24): ``weighting="eiv"``."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.core import noise_gains, whitening
from cdprid.identify import identify_dataset
from cdprid.io import read_dataset
from cdprid.model import (
    EIGHT_REDUNDANT,
    SIX_SUSPENDED,
    InertialParameters,
    craft_like_robot,
    craft_like_truth,
    preset,
    robot_from_dict,
)
from cdprid.signal import differentiate
from cdprid.simulation import SensorNoise, simulate, write_simulation

SMALL = InertialParameters(4.5, np.array([0.01, -0.005, -0.04]), np.diag([0.03, 0.035, 0.05]))


def _dataset(tmp_path, robot, truth, noise, seed=1, tau_ref=25.0, duration=26.0):
    traj = preset("rich", robot, duration=duration, rotation_amplitude=0.05)
    sim = simulate(robot, traj, truth, noise=noise, seed=seed, tau_ref=tau_ref)
    return read_dataset(write_simulation(sim, tmp_path / f"d{seed}"))


def test_noise_gains_equal_the_impulse_responses_of_a_linear_differentiator():
    """Oracle: for a linear method the white-noise covariance of (x, D1 x, D2 x) is the sum of
    products of the impulse responses."""
    dt, n = 0.01, 3000
    C = noise_gains("euler-filtfilt", {}, dt, None, n=n)
    e = np.zeros((n, 1))
    e[n // 2] = 1.0
    v, a = (np.asarray(z)[:, 0] for z in differentiate(e, dt, method="euler-filtfilt"))
    h = np.stack([e[:, 0], v, a])
    exact = h @ h.T
    np.testing.assert_allclose(np.diag(C), np.diag(exact), rtol=0.1)
    assert C[0, 2] == pytest.approx(exact[0, 2], rel=0.25)  # pose and acceleration correlate


def test_eiv_recovers_the_truth_on_noise_free_rotating_data(tmp_path):
    robot = robot_from_dict(SIX_SUSPENDED)
    ds = _dataset(tmp_path, robot, SMALL, SensorNoise.off())
    rep = identify_dataset(ds, weighting="eiv", bound=False)
    ols = identify_dataset(ds, weighting="none", bound=False)
    truth = np.asarray(SMALL.vector(rep.model))
    # the same estimator on exact data: both at the truth to the differentiator's accuracy
    np.testing.assert_allclose(rep.result.x, ols.result.x, atol=5e-4)
    assert abs(rep.result.x[0] / truth[0] - 1) < 1e-4
    assert any("errors-in-variables" in n for n in rep.notes)


def test_whitened_residuals_have_unit_variance(tmp_path):
    """The residual covariance the weighting assumes is the one the data show: whitened
    residuals of a noisy recording have variance ~1 per row (checked against the truth)."""
    from cdprid.core import estimate_motion
    from cdprid.identify._batch import _streamed_regression, _wrench_filter, noise_levels
    from cdprid.io import align

    robot = robot_from_dict(EIGHT_REDUNDANT)
    ds = _dataset(tmp_path, robot, SMALL, SensorNoise(position_m=3e-4, tension_N=0.5,
                                                       orientation_rad=3e-4), tau_ref=40.0)
    sig = align(ds)
    motion = estimate_motion(sig, "euler-filtfilt", {}, angular=True)
    wf = _wrench_filter(robot, "euler-filtfilt", {}, sig.dt, "matched")[0]
    keep = np.zeros(len(motion.t), bool)
    keep[100:-100] = True
    reg = _streamed_regression(robot, motion, sig.tension, "full", wf, keep, 4096)
    s_tau, _, s_pos, s_rot = noise_levels(ds, sig)
    idx = np.flatnonzero(keep)

    class Sub:
        pass

    sub = Sub()
    for k in ("t", "position", "B_R_P", "velocity", "acceleration", "omega", "alpha"):
        setattr(sub, k, np.asarray(getattr(motion, k))[idx])
    theta = np.asarray(SMALL.vector("full"))
    U = whitening(robot, "full", sub, np.asarray(sig.tension)[idx], theta, s_tau, s_pos, s_rot,
                  noise_gains("euler-filtfilt", {}, sig.dt, wf))
    Z, y = reg.wrench_block(0, len(idx))
    e = np.einsum("nij,nj->ni", U, y - Z @ theta)
    var = np.mean(e ** 2, axis=0)
    assert np.all(var > 0.5) and np.all(var < 2.0), var
    # unweighted, the rows differ by orders of magnitude (what OLS ignores)
    raw = np.mean((y - Z @ theta) ** 2, axis=0)
    assert raw.max() / raw.min() > 10


@pytest.mark.slow
@pytest.mark.parametrize("name", ["eight", "craft"])
def test_eiv_is_closer_to_the_bound_than_ols(tmp_path, name):
    """Monte Carlo (8 seeds): the EIV-GLS RMSE of every parameter is below OLS's worst and
    within 1.5x of the recording's own Cramer-Rao bound on the mass."""
    if name == "eight":
        robot, truth, ref = robot_from_dict(EIGHT_REDUNDANT), SMALL, 40.0
    else:
        robot, truth, ref = craft_like_robot(), craft_like_truth(), 25.0
    noise = SensorNoise(position_m=3e-4, tension_N=0.5, orientation_rad=3e-4)
    e_ols, e_eiv, crb = [], [], []
    for seed in range(8):
        ds = _dataset(tmp_path, robot, truth, noise, seed=100 + seed, tau_ref=ref)
        a = identify_dataset(ds, weighting="none")
        b = identify_dataset(ds, weighting="eiv", bound=False)
        t = np.asarray(truth.vector(a.model))
        e_ols.append(a.result.x - t)
        e_eiv.append(b.result.x - t)
        crb.append(a.crb.std)
    cb = np.median(crb, axis=0)
    r_ols = np.sqrt(np.mean(np.square(e_ols), axis=0)) / cb
    r_eiv = np.sqrt(np.mean(np.square(e_eiv), axis=0)) / cb
    assert r_eiv.max() < r_ols.max()
    assert r_eiv[0] < 1.5


def _perturbed(robot, state, xi):
    """Oracle: the cable side and the regressor from the public ``measured_wrench`` and
    ``regressors`` at ``state = (tau, p, R, a, omega, alpha)`` perturbed by ``xi`` (position,
    acceleration, rotation vector, angular rate, angular acceleration; 3 each)."""
    from cdprid.core import measured_wrench, regressors

    tau, p, R, a, w, al = state
    dp, da, dphi, dw, dal = (xi[3 * k:3 * k + 3] for k in range(5))
    Rk = (np.eye(3) + np.array([[0, -dphi[2], dphi[1]], [dphi[2], 0, -dphi[0]],
                                [-dphi[1], dphi[0], 0]])) @ R
    y = np.asarray(measured_wrench(robot, (p + dp)[None], Rk[None], tau[None]))[0]
    Y = np.asarray(regressors("full", Rk[None], (a + da)[None], (w + dw)[None],
                              (al + dal)[None], robot.gravity))[0]
    return y, Y


def test_residual_jacobians_match_finite_differences():
    """The per-sample Jacobians the weighting uses (the bound's, cdprid.core.sample_jacobians)
    against central differences of the residual built from the public measured_wrench and
    regressors (position, acceleration, rotation vector, angular rate, angular acceleration)."""
    import jax.numpy as jnp

    from cdprid.core import sample_jacobians

    robot = craft_like_robot()
    rng = np.random.default_rng(0)
    p, a, w, al = np.array([0.1, -0.2, 1.0]), *rng.normal(size=(3, 3))
    R = np.eye(3)
    tau = 30.0 + 5.0 * rng.random(robot.n_cables)
    theta = np.asarray(craft_like_truth().vector("full"))
    G = np.asarray(sample_jacobians(robot, "full", jnp.asarray(theta), *(
        jnp.asarray(x[None]) for x in (tau, p, R, a, w, al)))[0])[0]

    def residual(xi):
        y, Y = _perturbed(robot, (tau, p, R, a, w, al), xi)
        return y - Y @ theta

    h = 1e-6
    fd = np.stack([(residual(h * e) - residual(-h * e)) / (2 * h) for e in np.eye(15)], axis=1)
    np.testing.assert_allclose(G, fd, rtol=1e-6, atol=1e-6)


def test_json_names_the_weighting(tmp_path):
    # the 26 s of test_eiv_recovers_the_truth_on_noise_free_rotating_data: same shapes, so the
    # module's compiled simulation and identification are reused (16 s recompiled them all)
    robot = robot_from_dict(SIX_SUSPENDED)
    ds = _dataset(tmp_path, robot, SMALL, SensorNoise(position_m=3e-4, tension_N=0.5))
    assert identify_dataset(ds, bound=False).as_json()["weighting"] == "eiv"
    assert identify_dataset(ds, weighting="none", bound=False).as_json()["weighting"] == "none"


def test_bias_correction_trace_against_finite_differences():
    """Oracle: central differences of the public regressors and measured wrench. The bias of
    the normal equations, sum_n E[dY_n^T Omega_n dr_n] for inputs of covariance Su = L L^T,
    is sum_i dY(l_i)^T Omega dr(l_i) over the columns l_i of L; bias_correction's jacfwd
    trace must give it (this also checks that H and G order the 15 inputs alike)."""
    import jax.numpy as jnp

    from cdprid.core import regressor_jacobians, sample_jacobians

    robot = robot_from_dict(EIGHT_REDUNDANT, source="eight")
    rng = np.random.default_rng(3)
    p, a, w, al = np.array([0.05, -0.1, 0.9]), *rng.normal(size=(3, 3))
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    from cdprid.model import quat_to_matrix
    R = np.asarray(quat_to_matrix(jnp.asarray(q)))
    tau = 40.0 + 5.0 * rng.random(robot.n_cables)
    theta = np.asarray(SMALL.vector("full"))
    U = rng.normal(size=(6, 6))
    L = rng.normal(size=(15, 15)) * 1e-3
    Su = L @ L.T
    args = [jnp.asarray(x[None]) for x in (tau, p, R, a, w, al)]
    G = np.asarray(sample_jacobians(robot, "full", jnp.asarray(theta), *args)[0])[0]
    H = np.asarray(regressor_jacobians(robot, "full", *args[2:]))[0]
    b = np.einsum("rs,spi,ri->p", U, H, U @ G @ Su)

    def parts(xi):
        y, Y = _perturbed(robot, (tau, p, R, a, w, al), xi)
        return Y, y - Y @ theta

    h = 1e-4
    fd = np.zeros(len(theta))
    for li in L.T:
        (Yp, rp), (Ym, rm) = parts(h * li / 1e-3), parts(-h * li / 1e-3)
        dY, dr = (Yp - Ym) / (2 * h) * 1e-3, (rp - rm) / (2 * h) * 1e-3
        fd += np.einsum("rp,rs,st,t->p", dY, U.T, U, dr)
    np.testing.assert_allclose(b, fd, rtol=1e-5, atol=1e-12 * np.max(np.abs(fd)))
