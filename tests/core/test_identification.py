"""Least squares and the full identification path against independent oracles."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

from cdprid.core import condition_number, least_squares
from cdprid.identify import identify_dataset
from cdprid.io import read_dataset, write_dataset
from cdprid.model import (
    InertialParameters,
    platform_wrench,
    quat_to_matrix,
    regressor_full,
    rotvec_to_quat,
)


def test_least_squares_matches_independent_oracle(rng):
    A = rng.normal(size=(600, 4)) * np.array([1.0, 10.0, 0.1, 3.0])
    x_true = rng.normal(size=4)
    y = A @ x_true + rng.normal(0, 0.5, 600)
    res = least_squares(A, y, ("a", "b", "c", "d"))
    # oracle: scipy's lstsq and the textbook formulas (eqs. 19-20) via the explicit inverse
    x_ref = scipy.linalg.lstsq(A, y)[0]
    s2 = np.sum((y - A @ x_ref) ** 2) / (600 - 4)
    cov_ref = s2 * np.linalg.inv(A.T @ A)
    assert np.allclose(res.x, x_ref, rtol=1e-12)
    assert np.isclose(res.sigma_rho**2, s2, rtol=1e-12)
    assert np.allclose(res.cov_iid, cov_ref, rtol=1e-9)
    iid = least_squares(A, y, covariance="iid")
    assert np.allclose(iid.cov, cov_ref, rtol=1e-9)
    assert np.allclose(iid.rel_std_percent, 100 * np.sqrt(np.diag(cov_ref)) / np.abs(x_ref))
    assert np.allclose(res.std_iid, np.sqrt(np.diag(cov_ref)))
    sv = np.linalg.svd(A, compute_uv=False)
    assert np.isclose(res.cond, sv[0] / sv[-1])
    assert np.isclose(res.cond_scaled, np.linalg.cond(A / np.linalg.norm(A, axis=0)))
    assert res.cond_scaled < res.cond


def test_weighted_least_squares_by_groups(rng):
    n = 2000
    A = rng.normal(size=(n, 3))
    x_true = np.array([1.0, -2.0, 0.5])
    groups = np.tile([0, 1], n // 2)
    noise = np.where(groups == 0, 0.01, 5.0) * rng.normal(size=n)
    y = A @ x_true + noise
    ols = least_squares(A, y)
    wls = least_squares(A, y, groups=groups)
    # oracle: statsmodels-free WLS with the true weights
    w = np.where(groups == 0, 1 / 0.01, 1 / 5.0)
    x_w = np.linalg.lstsq(A * w[:, None], y * w, rcond=None)[0]
    assert np.allclose(wls.x, x_w, atol=5e-3)
    assert np.linalg.norm(wls.x - x_true) < np.linalg.norm(ols.x - x_true)
    assert np.all(wls.std < ols.std)


def test_least_squares_blocks_equal_the_stacked_solution(rng):
    """Block-by-block QR, residual and HAC passes give the stacked arrays' answer to rounding."""
    from cdprid.core import (
        hac_covariance,
        hac_covariance_blocks,
        least_squares_blocks,
        sample_scores,
    )

    n, k, p = 1500, 6, 5
    Z = rng.normal(size=(n, k, p)) * np.array([1.0, 10.0, 0.1, 3.0, 0.5])
    e = rng.normal(size=(n, k))
    for t in range(1, n):  # AR(1) regressors and residuals: correlated scores, a wide window
        Z[t] += 0.9 * Z[t - 1]
        e[t] += 0.9 * e[t - 1]
    y = Z @ rng.normal(size=p) + e
    A, Y = Z.reshape(-1, p), y.reshape(-1)
    x_ref = np.linalg.lstsq(A, Y, rcond=None)[0]
    r = Y - A @ x_ref
    cov_iid = (r @ r) / (n * k - p) * np.linalg.inv(A.T @ A)
    cov_hac, bw = hac_covariance(Z, r.reshape(n, k))
    for chunk in (1, 13, 10**6):
        res = least_squares_blocks(lambda i0, i1: (Z[i0:i1], y[i0:i1]), n, chunk=chunk)
        np.testing.assert_allclose(res.x, x_ref, rtol=1e-11)
        np.testing.assert_allclose(res.residual, r, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(res.cov_iid, cov_iid, rtol=1e-9)
        np.testing.assert_allclose(res.cov, cov_hac, rtol=1e-9)
        assert res.hac_bandwidth == pytest.approx(bw, rel=1e-9) and bw > 5
    # the HAC leverage windows, streamed in chunks of 7 windows, equal one pass over all
    S = sample_scores(Z, r.reshape(n, k))
    R = np.linalg.qr(A, mode="r")
    cov7, _ = hac_covariance_blocks(lambda i0, i1: Z[i0:i1], S, R, chunk=7)
    np.testing.assert_allclose(cov7, cov_hac, rtol=1e-9)
    # weighted by row groups: the same two-step estimate as the stacked one
    groups = np.tile([0, 0, 0, 1, 1, 1], n)
    ref = least_squares(A, Y, groups=groups, rows_per_sample=k)
    res = least_squares_blocks(lambda i0, i1: (Z[i0:i1], y[i0:i1]), n, groups=groups, chunk=29)
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-11)
    np.testing.assert_allclose(res.cov, ref.cov, rtol=1e-9)
    np.testing.assert_allclose(res.weights, ref.weights, rtol=1e-12)


def test_condition_number_scaled_invariance(rng):
    A = rng.normal(size=(100, 4))
    D = np.diag([1e-3, 1.0, 1e3, 10.0])
    assert np.isclose(condition_number(A @ D, scaled=True), condition_number(A, scaled=True))
    assert condition_number(A @ D) > 100 * condition_number(A)


def _noise_free_dataset(tmp_path, robot_dict, rotate: bool):
    """A minimal in-test generator: analytic orbit, exact tensions by least norm."""
    from cdprid.model import robot_from_dict, wrench_matrix

    robot = robot_from_dict(robot_dict)
    par = InertialParameters(9.88, [-0.0065, 0.0019, -0.107], np.diag([0.12, 0.12, 0.10]))
    t = np.arange(0.0, 30.0, 0.01)

    def pose(s):
        w1, w2 = 2 * jnp.pi * 0.25, 2 * jnp.pi * 0.4
        p = jnp.array([0.3 * jnp.cos(w1 * s), 0.25 * jnp.sin(w1 * s) + 0.05 * jnp.sin(w2 * s),
                       1.2 + 0.1 * jnp.sin(w2 * s)])
        rv = jnp.array([0.05 * jnp.sin(w2 * s), 0.04 * jnp.cos(w1 * s), 0.03 * jnp.sin(w1 * s)])
        q = rotvec_to_quat(rv if rotate else 0.0 * rv)
        return p, q

    def state(s):
        p, q = pose(s)
        v, qd = jax.jacfwd(pose)(s)
        a, qdd = jax.jacfwd(jax.jacfwd(pose))(s)
        from cdprid.model import angular_rates_from_quat

        om, al = angular_rates_from_quat(q, qd, qdd)
        R = quat_to_matrix(q)
        w = platform_wrench(par, R, a, om, al, robot.gravity)
        W = wrench_matrix(robot, p, R)
        tau = jnp.linalg.pinv(W) @ w + 0.0
        # add a null-space pretension so all tensions are positive
        return p, q, tau, W, w

    p, q, tau, W, w = jax.vmap(state)(jnp.asarray(t))
    Wn = np.asarray(W)
    tau = np.array(tau)
    # null-space component for positive tensions
    for k in range(len(t)):
        N = scipy.linalg.null_space(Wn[k])
        if N.shape[1]:
            tau[k] += N @ (N.T @ np.full(tau.shape[1], 30.0))
    assert np.allclose(np.einsum("kij,kj->ki", Wn, tau), np.asarray(w), atol=1e-9)
    write_dataset(tmp_path / "ds", robot, t, np.asarray(p), t, tau,
                  quaternion=np.asarray(q) if rotate else None,
                  meta={"truth": {"mass": 9.88}})
    return read_dataset(tmp_path / "ds"), par


@pytest.mark.parametrize("rotate", [False, True])
def test_noise_free_recovery_with_exact_derivatives(tmp_path, rotate):
    """With the differentiator replaced by exact derivatives the truth comes back to 1e-9."""
    from cdprid.core import Motion, build_regression
    from conftest import ROBOT_CRAFT

    ds, par = _noise_free_dataset(tmp_path, ROBOT_CRAFT, rotate)
    # exact motion from a fine analytic re-evaluation: use savgol-free route -> jax derivatives
    t = ds.pose_t

    def pose(s):
        w1, w2 = 2 * jnp.pi * 0.25, 2 * jnp.pi * 0.4
        p = jnp.array([0.3 * jnp.cos(w1 * s), 0.25 * jnp.sin(w1 * s) + 0.05 * jnp.sin(w2 * s),
                       1.2 + 0.1 * jnp.sin(w2 * s)])
        rv = jnp.array([0.05 * jnp.sin(w2 * s), 0.04 * jnp.cos(w1 * s), 0.03 * jnp.sin(w1 * s)])
        return p, rotvec_to_quat(rv if rotate else 0.0 * rv)

    from cdprid.model import angular_rates_from_quat

    def kin(s):
        p, q = pose(s)
        v, qd = jax.jacfwd(pose)(s)
        a, qdd = jax.jacfwd(jax.jacfwd(pose))(s)
        om, al = angular_rates_from_quat(q, qd, qdd)
        return p, v, a, quat_to_matrix(q), om, al

    p, v, a, R, om, al = (np.asarray(z) for z in jax.vmap(kin)(jnp.asarray(t)))
    motion = Motion(t, p, v, a, R, om, al, "exact")
    model = "full" if rotate else "translation"
    reg = build_regression(ds.robot, motion, ds.tension, model)
    res = least_squares(reg.W_ID, reg.Y_ID)
    assert np.allclose(res.x, np.asarray(par.vector(model)), rtol=0, atol=1e-9)
    # and the regressor reproduces the wrench, sample by sample, to 1e-10
    Af = jax.vmap(lambda R_, a_, w_, l_: regressor_full(R_, a_, w_, l_, ds.robot.gravity))(
        R, a, om, al)
    assert np.allclose(np.einsum("kij,j->ki", np.asarray(Af), np.asarray(par.vector("full"))),
                       reg.y, atol=1e-9)


def test_pipeline_noise_free_translation(tmp_path):
    """The whole pipeline (paper differentiator + matched filter) on noise-free data."""
    from conftest import ROBOT_CRAFT

    ds, par = _noise_free_dataset(tmp_path, ROBOT_CRAFT, rotate=False)
    rep = identify_dataset(ds, differentiator="euler-filtfilt")
    assert np.allclose(rep.result.x, np.asarray(par.vector("translation")), rtol=2e-4, atol=2e-4)
    assert rep.n_samples == len(ds.pose_t) - 200


# ----------------------------------------------------------------------------- honest defaults


@pytest.fixture(scope="module")
def rotating_ds(tmp_path_factory):
    from conftest import ROBOT_CRAFT

    return _noise_free_dataset(tmp_path_factory.mktemp("rot"), ROBOT_CRAFT, rotate=True)


@pytest.mark.parametrize("method,tol", [("euler-filtfilt", 1e-2), ("sihd2-cascade", 3e-2),
                                        ("kalman", 1e-2)])
def test_auto_model_and_matched_filter_unbiased_on_rotating_data(rotating_ds, method, tol):
    """Default options on noise-free rotating data: full model, no lag bias, no warning.

    Without the matched filter the SIHD cascade's lag shrinks mzG by ~10 %; the homogeneous
    SIHD is matched through its describing function (linear methods exactly), hence 3 %.
    """
    ds, par = rotating_ds
    rep = identify_dataset(ds, differentiator=method)
    assert rep.model == "full" and rep.rotation_deg > 1.0
    x = np.asarray(par.vector("full"))
    np.testing.assert_allclose(rep.result.x[:4], x[:4], rtol=tol, atol=2e-3)
    if method != "sihd2-cascade":  # homogeneous SIHD: the inertia's describing function differs
        np.testing.assert_allclose(rep.result.x[4:], x[4:], atol=0.08 * np.abs(x[4:]).max())
        assert rep.warnings == ()
    else:  # ... and then the physics guard says so
        assert all(w.startswith("physically impossible") for w in rep.warnings)
    j = rep.as_json()
    assert j["model"] == "full" and j["warnings"] == list(rep.warnings)
    assert j["inertia_about"] == "P, platform frame"
    assert set(j["parameters"]["m"]) >= {"value", "std", "rel_std_percent", "std_iid"}


@pytest.mark.parametrize("method", ["euler-filtfilt",
                                    pytest.param("kalman", marks=pytest.mark.slow)])
def test_streamed_identify_equals_the_materialised_regression(rotating_ds, method):
    """identify evaluates the regressor block by block (bounded memory, issue 17); the oracle
    holds every array: W tau and the pose-only regressor terms filtered whole, stacked LS (for
    the causal kalman, the rotation-consistent linear match evaluated in one block)."""
    import dataclasses

    from cdprid.core import build_regression, estimate_motion, regressors
    from cdprid.io import align
    from cdprid.signal import acceleration_filter

    ds, _ = rotating_ds
    noise = np.random.default_rng(7).normal(0.0, 0.5, ds.tension.shape)  # realistic residuals
    ds = dataclasses.replace(ds, tension=ds.tension + noise)
    sig = align(ds)
    motion = estimate_motion(sig, method, {}, angular=True)

    def wf(y):  # linear methods: the amplitude normalisation cancels
        return acceleration_filter(y, sig.dt, method)

    keep = (motion.t >= motion.t[0] + 1.0) & (motion.t <= motion.t[-1] - 1.0)
    mb = 1.0
    if method == "euler-filtfilt":  # the zero-phase rotation-consistent regression, one block
        from cdprid.identify import reference_rates

        reg = build_regression(ds.robot, motion, sig.tension, "full", wf)
        n = len(motion.t)
        z = jnp.zeros((n, 3))
        q = np.asarray(sig.quaternion)[keep]
        q0 = (q * np.where(q @ q[0] < 0, -1.0, 1.0)[:, None]).mean(axis=0)
        R0 = jnp.asarray(np.broadcast_to(np.asarray(quat_to_matrix(
            jnp.asarray(q0 / np.linalg.norm(q0)))), (n, 3, 3)))
        a_ref, om, al = (jnp.asarray(v) for v in reference_rates(motion, sig.quaternion))
        g = ds.robot.gravity

        def Y(R, a, w, alpha):
            return np.asarray(regressors("full", R, a, w, alpha, g))

        base = Y(R0, z, z, z)
        rot = Y(jnp.asarray(motion.B_R_P), a_ref, om, al) - Y(R0, a_ref, z, z) + base
        A = Y(R0, jnp.asarray(motion.acceleration), z, z) - base + wf(rot.reshape(n, -1)).reshape(
            rot.shape)
        y = reg.y
    else:  # a causal method: the rotation-consistent linear match, built in one block
        from cdprid.core import fit_linear_match, matched_regression, settled

        lm = fit_linear_match(motion, keep, 1.0)
        reg = matched_regression(ds.robot, motion, sig.quaternion, sig.tension, "full", keep, lm,
                                 10 ** 6)
        keep = settled(keep, motion.segments, len(lm.taps))
        A, y, mb = np.empty((len(keep), 6, 10)), np.empty((len(keep), 6)), float(len(lm.taps))
        A[keep], y[keep] = reg.A, reg.y
    for weighting in ("none", "groups"):
        groups = np.tile([0, 0, 0, 1, 1, 1], int(keep.sum())) if weighting == "groups" else None
        ref = least_squares(A[keep].reshape(-1, 10), y[keep].reshape(-1), groups=groups,
                            rows_per_sample=6, min_bandwidth=mb)
        rep = identify_dataset(ds, differentiator=method, weighting=weighting, chunk=257)
        res = rep.result
        assert rep.model == "full" and rep.n_samples == keep.sum()
        np.testing.assert_allclose(res.x, ref.x, rtol=1e-9, atol=1e-12)
        for c, c_ref in ((res.cov, ref.cov), (res.cov_iid, ref.cov_iid)):
            d = np.sqrt(np.diag(c_ref))  # entries relative to their std: ~0 ones stay testable
            np.testing.assert_allclose(c / np.outer(d, d), c_ref / np.outer(d, d), atol=1e-9)
            np.testing.assert_allclose(np.diag(c), d**2, rtol=1e-9)
        assert res.hac_bandwidth == pytest.approx(ref.hac_bandwidth, rel=1e-9)
        np.testing.assert_allclose([res.sigma_rho, res.cond_scaled],
                                   [ref.sigma_rho, ref.cond_scaled], rtol=1e-9)
    np.testing.assert_allclose(rep.regression.W_ID, A[keep].reshape(-1, 10), rtol=1e-12,
                               atol=1e-12)


def test_guards_fire_where_they_should(rotating_ds):
    ds, _ = rotating_ds
    rep = identify_dataset(ds, model="translation")
    assert len(rep.warnings) == 1 and "rotates" in rep.warnings[0]
    rep = identify_dataset(ds, differentiator="sihd2-cascade", wrench_filter="none")
    assert sum("not filtered the same way" in w for w in rep.warnings) == 1
    with pytest.raises(ValueError, match="not available in batch"):
        identify_dataset(ds, wrench_filter="delay")


def test_inertia_about_com_and_its_jacobian(rotating_ds):
    from cdprid.core import inertia_about_com

    ds, par = rotating_ds
    x = np.asarray(par.vector("full"))
    xg, J = inertia_about_com(x)
    I = np.asarray(par.inertia_com)
    np.testing.assert_allclose(xg[4:], [I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]],
                               atol=1e-12)
    h = 1e-6
    Jfd = np.stack([(inertia_about_com(x + h * e)[0] - inertia_about_com(x - h * e)[0]) / (2 * h)
                    for e in np.eye(10)], axis=1)
    np.testing.assert_allclose(J, Jfd, atol=1e-6)
    rep = identify_dataset(ds, inertia_about="G")
    assert rep.as_json()["inertia_about"] == "G (centre of mass), platform frame"
    np.testing.assert_allclose(rep.as_json()["parameters"]["Izz"]["value"], I[2, 2], rtol=0.05)


def test_physical_checks_and_constrained_fit(rng):
    from cdprid.core import physical_fit, physical_warnings, violations

    good = np.asarray(InertialParameters(4.5, [0.01, 0.0, -0.04],
                                         np.diag([0.03, 0.035, 0.05])).vector("full"))
    assert violations(good, "full") == []
    assert physical_warnings(good, "full", np.eye(10) * 1e-8) == ([], [])
    neg_m = good.copy()
    neg_m[0] = -1.0
    assert "m = -1 kg <= 0" in physical_warnings(neg_m, "full")[0][0]
    bad = good.copy()
    bad[9] = -0.2  # Izz about P far below zero: not positive definite
    w, _ = physical_warnings(bad, "full", np.eye(10) * 1e-8)
    assert len(w) == 1 and "not positive definite" in w[0]
    # within its (large) std the same violation is a note, not a warning
    w, n = physical_warnings(bad, "full", np.eye(10))
    assert w == [] and len(n) == 1
    # constrained fit: unchanged when realisable, realisable and no farther than needed otherwise
    A = rng.normal(size=(200, 10))
    R = np.linalg.qr(A, mode="r")
    x, _ = physical_fit(good, R, np.eye(10))
    np.testing.assert_array_equal(x, good)
    xp, cov = physical_fit(bad, R, np.eye(10) * 1e-6)
    assert violations(xp, "full") == []
    assert np.linalg.norm(R @ (xp - bad)) < np.linalg.norm(R @ (good - bad))
    assert np.all(np.isfinite(cov))


def test_cli_identify_refuses_to_overwrite(tmp_path, rotating_ds, capsys):
    from cdprid.cli import main

    ds, _ = rotating_ds
    out = tmp_path / "r.json"
    out.write_text("{}")
    assert main(["identify", str(ds.path), "--json", str(out)]) == 2
    assert out.read_text() == "{}"
    assert "--json" in capsys.readouterr().err
    assert main(["identify", str(ds.path), "--json", str(out), "--force", "--std", "iid"]) == 0
    import json

    j = json.loads(out.read_text())
    assert j["covariance"] == "iid" and j["model"] == "full" and j["warnings"] == []
    assert main(["identify", str(ds.path), "--wrench-filter", "delay"]) == 2
