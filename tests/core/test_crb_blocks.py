"""Issue 40 #5: the Cramer-Rao bound is summed block by block (no (n, 24, 24) arrays), equal
to the one-block evaluation."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from cdprid.core import crb


@pytest.mark.parametrize("rot", [pytest.param(True, marks=pytest.mark.slow), False])
def test_blockwise_bound_equals_one_block(rot):  # rotating: 26 s, with the slow tests
    import cdprid.model as M
    from cdprid.model import quat_to_matrix, rotvec_to_quat

    robot = M.robot_from_dict(M.EIGHT_REDUNDANT)
    n = 700
    t = np.arange(n) * 0.01
    w = 2 * np.pi * np.array([0.7, 0.9, 1.1])
    p = np.mean(np.asarray(robot.B_A), 0) * [1, 1, 0.5] + 0.1 * np.sin(w * t[:, None])
    a = -0.1 * w**2 * np.sin(w * t[:, None])
    phi = 0.05 * np.sin(w * t[:, None] + 1.0)
    om, al = 0.05 * w * np.cos(w * t[:, None] + 1.0), -0.05 * w**2 * np.sin(w * t[:, None] + 1)
    R = np.asarray(jax.vmap(lambda r: quat_to_matrix(rotvec_to_quat(r)))(phi))
    theta = np.array([8.0, 0.05, -0.02, -0.4, 0.2, 0.0, 0.01, 0.15, 0.0, 0.1])
    tension = 40.0 + np.random.default_rng(1).normal(0, 1, (n, robot.n_cables))
    s = np.linspace(0.3, 0.6, robot.n_cables)
    args = (robot, "full", theta, t, p, R, a, om, al, tension, s, 1e-3, 2e-3 if rot else None)
    one = crb(*args, knot_spacing_s=0.05)
    many = crb(*args, knot_spacing_s=0.05, chunk=97)  # 8 blocks, the last one short
    np.testing.assert_allclose(many.cov, one.cov, rtol=1e-9, atol=1e-12 * np.abs(one.cov).max())
    assert np.all(np.isfinite(one.std)) and np.all(one.std > 0)


def test_bound_and_weighting_trace_the_jacobians_once():
    """Issue 36 (identify < 2 s): the bound evaluates its Jacobians in CHUNK blocks whatever its
    information ``chunk``, the shapes the errors-in-variables weighting asks for, so the two
    share one trace (before: 97-sample blocks, one trace per block shape)."""
    from types import SimpleNamespace

    import cdprid.model as M
    from cdprid.core import whitening
    from cdprid.core._crb import _body_jacobians, _cable_jacobians

    cable, body = _cable_jacobians.__wrapped__, _body_jacobians.__wrapped__

    robot = M.robot_from_dict(M.EIGHT_REDUNDANT)
    n = 300
    t = np.arange(n) * 0.01
    w = 2 * np.pi * np.array([0.7, 0.9, 1.1])
    p = np.mean(np.asarray(robot.B_A), 0) * [1, 1, 0.5] + 0.1 * np.sin(w * t[:, None])
    a = -0.1 * w**2 * np.sin(w * t[:, None])
    R = np.broadcast_to(np.eye(3), (n, 3, 3))
    z = np.zeros((n, 3))
    theta = np.array([8.0, 0.05, -0.02, -0.4])
    tension = 40.0 + np.random.default_rng(1).normal(0, 1, (n, robot.n_cables))
    s = np.linspace(0.3, 0.6, robot.n_cables)
    cable.clear_cache()
    body.clear_cache()
    b = crb(robot, "translation", theta, t, p, R, a, z, z, tension, s, 1e-3, None,
            knot_spacing_s=0.05, chunk=97)  # 4 information blocks, the last one short
    assert np.all(np.isfinite(b.std)) and np.all(b.std > 0)
    assert cable._cache_size() == 1 and body._cache_size() == 1
    motion = SimpleNamespace(t=t, position=p, B_R_P=R, acceleration=a, omega=z, alpha=z)
    U = whitening(robot, "translation", motion, tension, 1.01 * theta, s, 1e-3, None,
                  np.eye(3))
    assert U.shape == (n, 6, 6) and np.all(np.isfinite(U))
    assert cable._cache_size() == 1 and body._cache_size() == 1


def test_cable_side_kept_only_for_the_same_samples():
    """The cable side of sample_jacobians is kept by content (the weighting, its bias and the
    bound ask for the same samples at three theta): a changed tension, position or robot
    recomputes it, and the kept one is the one a fresh evaluation gives, bit for bit."""
    import cdprid.core._crb as C
    import cdprid.model as M

    robot = M.robot_from_dict(M.EIGHT_REDUNDANT)
    rng = np.random.default_rng(5)
    n = 40
    p = np.mean(np.asarray(robot.B_A), 0) * [1, 1, 0.5] + 0.05 * rng.normal(size=(n, 3))
    R = np.broadcast_to(np.eye(3), (n, 3, 3))
    a, z = rng.normal(size=(n, 3)), np.zeros((n, 3))
    tau = 40.0 + rng.normal(size=(n, robot.n_cables))
    th1, th2 = np.array([8.0, 0.05, -0.02, -0.4]), np.array([9.0, 0.0, 0.01, -0.5])

    def fresh(theta, tau_, p_):
        C._KEPT.clear()
        return C.sample_jacobians(robot, "translation", theta, tau_, p_, R, a, z, z)

    G1, _, W1 = C.sample_jacobians(robot, "translation", th1, tau, p, R, a, z, z)
    G2, _, W2 = C.sample_jacobians(robot, "translation", th2, tau, p, R, a, z, z)
    np.testing.assert_array_equal(G2, fresh(th2, tau, p)[0])
    np.testing.assert_array_equal(W1, W2)
    np.testing.assert_array_equal(G1[:, :, :3], G2[:, :, :3])  # position columns: cable only
    tau2 = tau.copy()
    tau2[7, 2] += 1.0
    G3 = C.sample_jacobians(robot, "translation", th2, tau2, p, R, a, z, z)[0]
    np.testing.assert_array_equal(G3, fresh(th2, tau2, p)[0])
    assert not np.array_equal(G3[7], G2[7]) and np.array_equal(G3[6], G2[6])
    p2 = p.copy()
    p2[3, 0] += 1e-3
    G4 = C.sample_jacobians(robot, "translation", th2, tau, p2, R, a, z, z)[0]
    np.testing.assert_array_equal(G4, fresh(th2, tau, p2)[0])
    assert not np.array_equal(G4[3], G2[3])
