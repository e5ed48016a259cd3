"""The diagnosis' faster paths equal the plain computations they replace (issue 37's speed).

The cable side's Jacobian in two parts (geometry kept while its blocks are unchanged, the
tension part recomputed), the model side's Jacobian differentiated only in the columns it
reads, and the blocked held-out CV from segments' Gram matrices: each against a dense
``jax.jacfwd`` or the per-sample prefix sums of :func:`cdprid.diagnosis._testing.cv_sse`.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

jax.config.update("jax_enable_x64", True)

from cdprid.diagnosis import _model as M  # noqa: E402
from cdprid.diagnosis._problem import heldout_rms  # noqa: E402
from cdprid.diagnosis._testing import blocks, cv_sse  # noqa: E402


@pytest.fixture(scope="module")
def data():
    from cdprid.model import robot_from_dict
    from conftest import SAMPLE_ROBOTS

    robot = robot_from_dict(SAMPLE_ROBOTS["craft"])
    rng = np.random.default_rng(11)
    n = 50
    t = np.arange(n) * 0.01
    p = np.column_stack([0.2 * np.sin(t), 0.1 * np.cos(t), 1.2 + 0.05 * t])
    ang = 0.05 * np.sin(3 * t)
    R = np.stack([[[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]]
                  for a in ang])
    tau = 20 + rng.normal(size=(n + 20, 8))
    d = M.DiagData(robot, jnp.asarray(t), jnp.asarray(p), jnp.asarray(R),
                   jnp.asarray(rng.normal(size=(n, 3))), jnp.asarray(rng.normal(size=(n, 3))),
                   jnp.asarray(rng.normal(size=(n, 3))), jnp.asarray(rng.normal(size=(n, 3))),
                   jnp.asarray(tau), jnp.asarray(rng.normal(size=(n, 8)) * 0.1),
                   jnp.asarray(3.0 + t), -0.1, 0.01)
    return d, M.ThetaLayout(8), rng


@jax.jit
def _dense_cable_jacobian(d, th):
    """jacfwd of cable_contribution in every local parameter at once (the old path)."""
    layout = M.ThetaLayout(d.robot.n_cables)
    thd = layout.unpack(th)
    loc = M.cable_locals(d, thd, layout)
    tau_c, taud_c = M._tension_inputs(d, thd)
    rob = d.robot

    def per_sample(p, R, tc, tdc, ld, clk):
        def per_cable(lc, A, b, r, k, ref, ti, tdi, li):
            def f(z):
                return M.cable_contribution(z, A, b, r, k, ref, p, R, ti, tdi, rob.gravity, lc,
                                            li, clk)
            return jax.jacfwd(f)(lc)
        return jax.vmap(per_cable)(loc, rob.B_A, rob.P_b, rob.pulley_radius, rob.pulley_axis,
                                   rob.pulley_reference, tc, tdc, ld)

    return jax.vmap(per_sample)(d.p, d.R, tau_c, taud_c, d.ldot, d.clock)  # (n, m, 6, len)


@pytest.mark.slow  # compiles the pulley geometry's Jacobian three ways: 55 s at load 14
def test_geometry_part_reused_across_sensor_side_changes_gives_the_plain_jacobian(data):
    d, layout, rng = data
    th1 = rng.normal(size=layout.size) * 0.01
    th1[layout.slices["pulley_flip"]] = 0.0  # measured_side has no flipped pulley
    th2 = th1.copy()
    for name in ("offset", "gain", "coulomb", "delay"):  # sensor side only
        th2[layout.slices[name]] += rng.normal(size=th2[layout.slices[name]].shape) * 0.01
    geo = M.geometry_jac(d, jnp.asarray(th1), layout)  # kept from theta 1
    y, J = M.assemble_jac(layout, geo, M.tension_jac(d, jnp.asarray(th2), layout))
    Jl = np.asarray(_dense_cable_jacobian(d, jnp.asarray(th2)))
    # the dense per-cable Jacobian on theta's layout: per-cable blocks cable-major
    o = 0
    cols = []
    for name, size in M.LOCAL_BLOCKS:
        blk = Jl[..., o:o + size]  # (n, m, 6, size)
        if layout.block_shapes[name][0]:
            cols.append(np.moveaxis(blk, 1, 2).reshape(blk.shape[0], 6, -1))
        else:
            cols.append(blk.sum(1))
        o += size
    J_ref = np.concatenate(cols, axis=2)
    assert set(M.geometry_blocks()) >= {"exit", "anchor", "radius"}
    assert not set(M.geometry_blocks()) & {"offset", "gain", "delay"}
    scale = np.max(np.abs(J_ref))
    assert np.max(np.abs(np.asarray(J) - J_ref)) <= 1e-12 * scale
    # the measured side against the independent whole-robot implementation
    y_ref = jax.jit(lambda z: M.measured_side(d, layout.unpack(z)))(jnp.asarray(th2))
    assert np.allclose(np.asarray(y), np.asarray(y_ref), atol=1e-10)


@pytest.mark.slow  # four compilations of the model side's Jacobian: 76 s at load 14
def test_model_jacobian_in_its_read_columns_equals_the_dense_one(data):
    d, layout, rng = data
    th = jnp.asarray(rng.normal(size=layout.size) * 0.01)
    for rot in (True, False):
        x = jnp.asarray(rng.normal(size=10 if rot else 4))
        dense = jax.jit(jax.jacfwd(lambda z, x=x, rot=rot: M.model_side(
            d, layout.unpack(z), x, rot)))(th)
        fast = M.model_jac_jit(d, th, x, layout, rot)
        assert np.max(np.abs(np.asarray(dense))) > 0
        assert np.allclose(np.asarray(fast), np.asarray(dense), rtol=0, atol=1e-12)
        idx = M.model_theta_indices(d, layout, rot)
        assert layout.slices["tilt"].start in idx and layout.slices["offset"].start not in idx


def test_heldout_rms_from_segment_grams_equals_prefix_sum_cv(rng):
    class Prob:
        test = None
        n_folds = 5
        lags = 7

    n, p = 400, 6
    Z = rng.normal(size=(n, 6, p)) * np.logspace(-2, 2, p)
    y = Z[..., 0] * 3.0 + rng.normal(size=(n, 6))
    prob = Prob()
    prob.use = rng.random(n) > 0.1
    u = prob.use
    sse, cnt = cv_sse(Z[u], y[u], blocks(int(u.sum()), 5), 7)
    assert heldout_rms(prob, Z, y) == pytest.approx(math.sqrt(sse / cnt), rel=1e-12)
