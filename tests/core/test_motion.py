"""cdprid.core._motion: the jitted, block-by-block rotation functions against per-sample oracles."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from cdprid.core import BLOCK, angular_rates, differentiate_pose, estimate_motion, rotation_matrices
from cdprid.io import AlignedSignals
from cdprid.model import angular_rates_from_quat, quat_to_matrix
from cdprid.signal import differentiate


def _quaternions(n: int, seed: int = 0, unit: bool = True) -> np.ndarray:
    """Smooth, large rotations about a wandering axis (sign-continuous), optionally not unit."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 7.0, n)
    ang = 1.3 * np.sin(0.9 * t) + 0.4 * t
    axis = np.stack([np.cos(0.7 * t), np.sin(0.5 * t), 0.6 + 0.3 * np.cos(1.1 * t)], axis=1)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    q = np.concatenate([np.cos(ang / 2)[:, None], np.sin(ang / 2)[:, None] * axis], axis=1)
    if not unit:
        q *= rng.uniform(0.7, 1.4, (n, 1))
    return q


def _matrix_numpy(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of one quaternion, numpy (normalised first)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.concatenate([[a[0] * b[0] - a[1:] @ b[1:]],
                           a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:])])


def _rates_numpy(q, qd, qdd):
    """omega = 2 vec(qd q^-1), alpha = 2 vec(qdd q^-1), numpy, one sample."""
    qinv = np.array([q[0], -q[1], -q[2], -q[3]]) / (q @ q)
    return 2.0 * _hamilton(qd, qinv)[1:], 2.0 * _hamilton(qdd, qinv)[1:]


@pytest.mark.parametrize(("n", "block"), [(1, 8), (7, 8), (8, 8), (61, 8), (300, 64)])
def test_rotation_matrices_equal_the_per_sample_numpy_formula(n, block):
    q = _quaternions(n, seed=n, unit=False)
    R = rotation_matrices(q, block=block)
    ref = np.stack([_matrix_numpy(x) for x in q])
    assert R.shape == (n, 3, 3)
    np.testing.assert_allclose(R, ref, rtol=0, atol=1e-12)
    # and the per-sample JAX function it vmaps
    np.testing.assert_allclose(R, np.stack([np.asarray(quat_to_matrix(x)) for x in q]),
                               rtol=0, atol=1e-12)
    # orthonormal with det +1 (the normalisation happened)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", R, R), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)


@pytest.mark.parametrize(("n", "block"), [(1, 8), (13, 8), (61, 8), (300, 64)])
def test_angular_rates_equal_the_per_sample_numpy_formula(n, block):
    q = _quaternions(n, seed=n)
    rng = np.random.default_rng(n + 1)
    qd, qdd = rng.normal(0, 1.0, (n, 4)), rng.normal(0, 3.0, (n, 4))
    om, al = angular_rates(q, qd, qdd, block=block)
    ref = [_rates_numpy(*x) for x in zip(q, qd, qdd, strict=True)]
    np.testing.assert_allclose(om, np.stack([r[0] for r in ref]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(al, np.stack([r[1] for r in ref]), rtol=0, atol=1e-12)
    jref = [angular_rates_from_quat(*x) for x in zip(q, qd, qdd, strict=True)]
    np.testing.assert_allclose(om, np.stack([np.asarray(r[0]) for r in jref]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(al, np.stack([np.asarray(r[1]) for r in jref]), rtol=0, atol=1e-12)


def test_angular_rates_of_a_known_rotation():
    """q(t) = exp(theta(t) k / 2) about a fixed axis: omega = theta' k, alpha = theta'' k."""
    t = np.linspace(0.0, 3.0, 41)
    k = np.array([2.0, -1.0, 2.0]) / 3.0
    th, thd, thdd = 0.8 * t ** 2, 1.6 * t, np.full_like(t, 1.6)
    c, s = np.cos(th / 2), np.sin(th / 2)
    q = np.concatenate([c[:, None], s[:, None] * k], axis=1)
    qd = np.concatenate([(-s * thd / 2)[:, None], (c * thd / 2)[:, None] * k], axis=1)
    qdd = np.concatenate([(-c * thd ** 2 / 4 - s * thdd / 2)[:, None],
                          (-s * thd ** 2 / 4 + c * thdd / 2)[:, None] * k], axis=1)
    om, al = angular_rates(q, qd, qdd, block=16)
    np.testing.assert_allclose(om, thd[:, None] * k, atol=1e-12)
    np.testing.assert_allclose(al, thdd[:, None] * k, atol=1e-12)


def test_estimate_motion_equals_the_eager_per_sample_evaluation():
    """Two gap-free segments, a total length not a multiple of BLOCK, the default block size."""
    dt = 0.01
    n = BLOCK + 3011
    t = np.arange(n) * dt
    t[BLOCK - 500:] += 1.0  # a gap: two segments, each differentiated on its own
    segs = ((0, BLOCK - 500), (BLOCK - 500, n))
    q = _quaternions(n, seed=3)
    pos = np.stack([0.2 * np.sin(0.3 * t), 0.1 * np.cos(0.2 * t), 0.05 * t / t[-1]], axis=1)
    sig = AlignedSignals(t, dt, pos, q, np.ones((n, 4)), True, False, (), segs)
    mo = estimate_motion(sig, "euler-filtfilt", {"cutoff_hz": 4.0})
    # the previous implementation: eager vmaps over all samples / each segment
    np.testing.assert_allclose(mo.B_R_P, np.asarray(jax.vmap(quat_to_matrix)(q)), rtol=0,
                               atol=1e-12)
    for i0, i1 in segs:
        qd, qdd = differentiate(q[i0:i1], dt, method="euler-filtfilt", cutoff_hz=4.0)
        o, a = jax.vmap(angular_rates_from_quat)(q[i0:i1], qd, qdd)
        np.testing.assert_allclose(mo.omega[i0:i1], np.asarray(o), rtol=0, atol=1e-12)
        np.testing.assert_allclose(mo.alpha[i0:i1], np.asarray(a), rtol=0, atol=1e-12)
    assert np.abs(mo.omega).max() > 0.01 # the rotation is really there
    translation_only = estimate_motion(sig, "euler-filtfilt", {"cutoff_hz": 4.0}, angular=False)
    assert not translation_only.omega.any() and not translation_only.alpha.any()
    np.testing.assert_array_equal(translation_only.B_R_P, mo.B_R_P)


def test_differentiate_pose_never_spans_a_segment_edge_and_is_exact_on_a_line():
    """Each segment differentiated alone (a jump between segments leaves no trace), with the
    method and parameters that :func:`estimate_motion` records on its Motion."""
    dt = 0.01
    t = np.arange(600) * dt
    x = np.column_stack([2.0 + 0.3 * t, -1.0 + 0.0 * t])
    x[300:, 0] += 5.0  # a gap: the second segment starts elsewhere
    segs = ((0, 300), (300, 600))
    v, a = differentiate_pose(x, dt, segs, "euler-filtfilt", {"cutoff_hz": 4.0})
    inner = np.r_[100:200, 400:500]
    np.testing.assert_allclose(v[inner, 0], 0.3, atol=1e-9)
    np.testing.assert_allclose(a[inner], 0.0, atol=1e-8)
    for i0, i1 in segs:
        want = differentiate(x[i0:i1], dt, method="euler-filtfilt", cutoff_hz=4.0)
        np.testing.assert_array_equal(v[i0:i1], np.asarray(want[0]))
        np.testing.assert_array_equal(a[i0:i1], np.asarray(want[1]))
    sig = AlignedSignals(t, dt, np.column_stack([x, 0 * t]), np.tile([1.0, 0, 0, 0], (600, 1)),
                         np.ones((600, 4)), False, False, segments=segs)
    mo = estimate_motion(sig, "euler-filtfilt", {"cutoff_hz": 4.0})
    assert mo.method == "euler-filtfilt" and mo.params == {"cutoff_hz": 4.0}
    np.testing.assert_array_equal(mo.velocity[:, :2], v)

