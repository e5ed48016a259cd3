"""Tension distribution: exactness, bounds, QP fallback, infeasibility, LP certificate."""

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from cdprid.model import (  # noqa: E402
    InfeasibleTensionsError,
    closed_form_tensions,
    craft_like_robot,  # noqa: E402
    distribute_tensions,
    feasibility_margin,
    wrench_matrix,  # noqa: E402
)


@pytest.fixture(scope="module")
def W_w():
    robot = craft_like_robot()
    W = np.asarray(wrench_matrix(robot, np.array([0.3, 0.2, 1.2]), np.eye(3)))
    w = np.array([5.0, -3.0, 9.81 * 9.88, 2.0, -1.0, 0.5])
    return W, w


def test_closed_form_is_exact_and_closest(W_w):
    W, w = W_w
    tau = np.asarray(closed_form_tensions(W[None], w[None], np.full(8, 25.0)))[0]
    np.testing.assert_allclose(W @ tau, w, atol=1e-10)
    # tau - tau_ref is orthogonal to the null space of W (closest point)
    null = np.linalg.svd(W)[2][6:]
    np.testing.assert_allclose(null @ (tau - 25.0), 0.0, atol=1e-10)


def test_qp_fallback_respects_bounds_and_equality(W_w):
    W, w = W_w
    tau_cf = np.asarray(closed_form_tensions(W[None], w[None], np.full(8, 25.0)))[0]
    lo = tau_cf.min() + 0.6  # the closed form violates it, the QP must fix it
    tau, n_qp = distribute_tensions(W[None], w[None], lo, 150.0)
    assert n_qp == 1
    assert tau.min() >= lo - 1e-9
    np.testing.assert_allclose(W @ tau[0], w, atol=1e-9)


def test_infeasible_request_raises_a_clear_error(W_w):
    W, w = W_w
    Wn, wn = np.repeat(W[None], 5, 0), np.repeat(w[None], 5, 0)
    wn[3:] *= 20.0
    with pytest.raises(InfeasibleTensionsError) as exc:
        distribute_tensions(Wn, wn, 1.0, 150.0, t=np.arange(5) * 0.5)
    msg = str(exc.value)
    assert msg.startswith("tension distribution infeasible at 2 of 5 samples (first at t = 1.5 s)")
    assert "tension_max" in msg and "\n" not in msg
    np.testing.assert_array_equal(exc.value.indices, [3, 4])
    with pytest.raises(InfeasibleTensionsError, match="below tension_min"):
        distribute_tensions(W[None], -w[None], 1.0, 150.0)


def test_feasibility_margin_certificate(W_w):
    W = np.hstack([np.eye(6), -np.eye(6)])
    assert feasibility_margin(W, np.zeros(6), 1.0, 11.0) == pytest.approx(5.0)
    Wc, w = W_w
    m_ok = feasibility_margin(Wc, w, 1.0, 150.0)
    m_bad = feasibility_margin(Wc, 20 * w, 1.0, 150.0)
    assert m_ok > 0 > m_bad
    # the certificate agrees with the distribution: feasible at margin - eps, not above it
    distribute_tensions(Wc[None], w[None], 1.0 + m_ok - 1e-3, 150.0, tau_ref=75.0)
    with pytest.raises(InfeasibleTensionsError):
        distribute_tensions(Wc[None], w[None], 1.0 + m_ok + 1e-3, 150.0)
    both = feasibility_margin(np.stack([Wc, Wc]), np.stack([w, 20 * w]), 1.0, 150.0)
    np.testing.assert_allclose(both, [m_ok, m_bad], rtol=1e-6)


def test_block_lp_equals_per_sample_lps(W_w, monkeypatch):
    # many samples go through one block-diagonal LP per chunk; same margins as one LP per
    # sample, including infeasible samples, a wrench outside the range of W and a padded tail
    from cdprid.model import _tensions as T

    robot = craft_like_robot()
    rng = np.random.default_rng(4)
    n = 300
    P = rng.uniform([-0.5, -0.4, 0.8], [0.5, 0.4, 1.6], size=(n, 3))
    W = np.stack([np.asarray(wrench_matrix(robot, p, np.eye(3))) for p in P])
    w = np.array([0.0, 0.0, 9.81 * 9.88, 0.0, 0.0, 0.0]) + rng.normal(0, 1, size=(n, 6)) * [10, 10, 10, 1, 1, 1]
    w[::37] *= 15.0  # infeasible
    monkeypatch.setattr(T, "_BLOCK", 128)
    block = T.feasibility_margin(W, w, 1.0, 150.0)
    monkeypatch.setattr(T, "_BLOCK_MIN", 10**9)
    loop = T.feasibility_margin(W, w, 1.0, 150.0)
    assert (loop < 0).sum() >= 5 and (loop > 0).sum() >= 100
    np.testing.assert_allclose(block, loop, rtol=1e-7, atol=1e-7)
    # a 4-cable W: W tau = w has no solution for a generic w -> -inf, in a block too
    W4 = W[:20, :, :4]
    monkeypatch.setattr(T, "_BLOCK_MIN", 8)
    m4 = T.feasibility_margin(W4, w[:20], 1.0, 150.0)
    assert np.all(m4 == -np.inf)
