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
