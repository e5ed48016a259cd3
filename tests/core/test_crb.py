"""The Cramer-Rao bound of a recording (cdprid.core.crb) and identify's crb_std / efficiency
(issue 24)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from cdprid.core import crb
from cdprid.core._crb import bspline_basis


def test_bspline_basis_matches_scipy():
    from scipy.interpolate import BSpline

    rng = np.random.default_rng(0)
    u = rng.uniform(0, 6, 40)
    i, b, d1, d2 = bspline_basis(u)
    knots = np.arange(-3, 13, dtype=float)  # basis j spans [j-3, j+1]: index j = i + k + 3
    for k in range(4):
        for n, (ui, ii) in enumerate(zip(u, i, strict=True)):
            c = np.zeros(len(knots) - 4)
            c[ii + k] = 1.0
            spl = BSpline(knots, c, 3)
            assert b[n, k] == pytest.approx(spl(ui), abs=1e-12)
            assert d1[n, k] == pytest.approx(spl.derivative(1)(ui), abs=1e-12)
            assert d2[n, k] == pytest.approx(spl.derivative(2)(ui), abs=1e-12)
    assert np.allclose(b.sum(1), 1.0) and np.allclose(d1.sum(1), 0.0)


def _trajectory(robot, n=400, rot=True):
    """A smooth motion of the platform around the middle of the workspace (no simulator)."""
    from cdprid.model import quat_to_matrix, rotvec_to_quat

    t = np.arange(n) * 0.01
    w = 2 * np.pi * np.array([0.7, 0.9, 1.1])
    centre = np.mean(np.asarray(robot.B_A), axis=0) * np.array([1, 1, 0.5])
    p = centre + 0.1 * np.sin(w[None, :] * t[:, None])
    a = -0.1 * w**2 * np.sin(w[None, :] * t[:, None])
    amp = 0.05 if rot else 0.0
    phi = amp * np.sin(w[None, :] * t[:, None] + 1.0)
    om = amp * w * np.cos(w[None, :] * t[:, None] + 1.0)  # small angles: omega ~ dphi/dt
    al = -amp * w**2 * np.sin(w[None, :] * t[:, None] + 1.0)
    R = np.asarray(jax.vmap(lambda r: quat_to_matrix(rotvec_to_quat(r)))(phi))
    return t, p, R, a, om, al


def _gls_bound(robot, model, theta, p, R, a, om, al, tension, s):
    """(sum_k Y^T (W S W^T)^+ Y)^-1 in numpy: the bound when the motion is known."""
    from cdprid.model import regressor_full, regressor_translation, wrench_matrix

    info = 0.0
    for k in range(len(p)):
        W = np.asarray(wrench_matrix(robot, p[k], R[k]))
        Y = np.asarray(regressor_full(R[k], a[k], om[k], al[k], robot.gravity)
                       if model == "full" else regressor_translation(R[k], a[k], robot.gravity))
        info = info + Y.T @ np.linalg.pinv(W @ np.diag(s**2) @ W.T, rcond=1e-10) @ Y
    return np.linalg.inv(info)


@pytest.mark.parametrize("name", ["SIX_SUSPENDED",
                                  pytest.param("EIGHT_REDUNDANT", marks=pytest.mark.slow)])
def test_bound_with_known_motion_is_the_gls_bound(name):
    import cdprid.model as M

    robot = M.robot_from_dict(getattr(M, name))
    t, p, R, a, om, al = _trajectory(robot)
    theta = np.array([8.0, 0.05, -0.02, -0.4, 0.2, 0.0, 0.01, 0.15, 0.0, 0.1])
    tension = np.full((len(t), robot.n_cables), 40.0)
    s = np.linspace(0.3, 0.6, robot.n_cables)
    ref = _gls_bound(robot, "full", theta, p, R, a, om, al, tension, s)
    got = crb(robot, "full", theta, t, p, R, a, om, al, tension, s, 1e-9, 1e-9)
    assert np.allclose(got.cov, ref, rtol=1e-5, atol=0), np.diag(got.cov) / np.diag(ref)
    # pose noise only adds uncertainty, and the bound scales with the tension noise
    noisy = crb(robot, "full", theta, t, p, R, a, om, al, tension, s, 1e-3, 2e-3)
    assert np.all(noisy.std >= got.std * (1 - 1e-9)) and np.any(noisy.std > 1.01 * got.std)
    twice = crb(robot, "full", theta, t, p, R, a, om, al, tension, 2 * s, 1e-9, 1e-9)
    assert np.allclose(twice.std, 2 * got.std, rtol=1e-5)


def test_identify_reports_the_bound_for_every_parameter(sample_dataset):
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset

    jax.config.update("jax_enable_x64", True)
    rep = identify_dataset(read_dataset(sample_dataset))
    j = rep.as_json()
    names = list(j["parameters"])
    assert set(j["crb_std"]) == set(names) == set(j["efficiency"])
    for n in names:
        c, e = j["crb_std"][n], j["efficiency"][n]
        assert c > 0 and np.isfinite(c)
        assert e == pytest.approx(j["parameters"][n]["std"] / c)
        assert j["parameters"][n]["crb_std"] == c
    # noise levels estimated from the data: the sample's 0.5 N / 0.2 mm
    assert np.allclose(j["crb"]["noise"]["tension_N"], 0.5, rtol=0.15)
    from cdprid.identify import format_table

    assert "sigma/CRB" in format_table(rep)


@pytest.mark.slow
def test_no_estimate_beats_the_bound_monte_carlo(tmp_path):
    """20 noisy recordings of a 6-cable robot: the spread of the estimates is not below the
    bound (beyond Monte-Carlo error), and the bound is within a factor 3 of it."""
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset
    from cdprid.model import SIX_SUSPENDED, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    jax.config.update("jax_enable_x64", True)
    rob = robot_from_dict(SIX_SUSPENDED)
    est, bounds = [], []
    for seed in range(20):
        sim = simulate(rob, preset("rich", rob, duration=20.0), None,
                       noise=SensorNoise(position_m=3e-4, tension_N=0.5), seed=seed)
        rep = identify_dataset(read_dataset(write_simulation(sim, tmp_path / f"s{seed}")))
        est.append(rep.result.x)
        bounds.append(rep.crb_std())
    est, bounds = np.array(est), np.array(bounds)
    spread = est.std(axis=0, ddof=1)
    b = np.median(bounds, axis=0)
    # the sample std of 20 draws is within ~35 % of the true std (chi, 95 %)
    assert np.all(spread >= 0.65 * b), spread / b
    assert np.all(spread <= 3.0 * b), spread / b


@pytest.mark.parametrize("d", [3, 6])
def test_block_banded_solve_equals_a_dense_solve(d):
    """The nuisance block (a sample touches 4 consecutive knots of d coordinates) solved by
    block Cholesky equals numpy's dense solve; and the Schur complement built from
    per-sample blocks equals the one written out densely."""
    from cdprid.core import _crb

    rng = np.random.default_rng(d)
    K, n, p = 40, 500, 4
    nc = K * d
    i0 = np.minimum(np.arange(n) * (K - 3) // n, K - 4)
    cols = ((i0[:, None] + np.arange(4)[None, :])[:, :, None] * d
            + np.arange(d)[None, None, :]).reshape(n, 4 * d)
    J = rng.normal(size=(n, 6, 4 * d))
    Icc_loc = np.einsum("nkc,nkd->ncd", J, J) + 1e-3 * np.eye(4 * d)
    Itc_loc = np.einsum("nkp,nkc->npc", rng.normal(size=(n, 6, p)), J)
    Icc = np.zeros((nc, nc))
    Itc = np.zeros((p, nc))
    for k in range(n):
        Icc[np.ix_(cols[k], cols[k])] += Icc_loc[k]
        Itc[:, cols[k]] += Itc_loc[k]
    B = rng.normal(size=(nc, 5))
    np.testing.assert_allclose(_crb.block_banded_solve(Icc, B, d, 3), np.linalg.solve(Icc, B),
                               rtol=1e-8, atol=1e-10)
    Itt = 50.0 * np.eye(p)
    ridge = 1e-12 * np.max(np.diag(Icc)) * np.eye(nc)
    dense = Itt - Itc @ np.linalg.solve(Icc + ridge, Itc.T)
    got = _crb._schur_banded(Itt, Itc_loc, Icc_loc, cols, nc, d)
    np.testing.assert_allclose(got, dense, rtol=1e-9, atol=1e-9 * np.abs(dense).max())
