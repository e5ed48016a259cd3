"""Geometry and dynamics: W against the cable-length Jacobian, regressors against Newton-Euler."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from cdprid.model import (
    InertialParameters,
    angular_rates_from_quat,
    cable_lengths,
    cable_vectors,
    leave_points,
    matrix_to_quat,
    platform_wrench,
    quat_multiply,
    quat_to_matrix,
    regressor_full,
    regressor_translation,
    robot_from_dict,
    robot_to_dict,
    rotvec_to_quat,
    skew,
    swivel_angles,
    wrench_matrix,
)


def random_pose(rng, scale=0.3):
    p = np.array([0.0, 0.0, 1.2]) + rng.uniform(-scale, scale, 3)
    R = np.asarray(quat_to_matrix(rotvec_to_quat(rng.normal(0, 0.3, 3))))
    return jnp.asarray(p), jnp.asarray(R)


def test_rotation_helpers(rng):
    r = rng.normal(size=3)
    R = np.asarray(quat_to_matrix(rotvec_to_quat(r)))
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.isclose(np.linalg.det(R), 1.0)
    # Rodrigues formula as independent oracle
    th = np.linalg.norm(r)
    K = np.asarray(skew(r / th))
    R2 = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K
    assert np.allclose(R, R2, atol=1e-13)
    q = matrix_to_quat(R)
    assert np.allclose(np.asarray(quat_to_matrix(q)), R, atol=1e-13)
    a, b = rng.normal(size=4), rng.normal(size=4)
    Ra = np.asarray(quat_to_matrix(a))
    Rb = np.asarray(quat_to_matrix(b))
    assert np.allclose(np.asarray(quat_to_matrix(quat_multiply(a, b))), Ra @ Rb, atol=1e-13)


def test_angular_rates_from_quaternion_match_finite_differences(rng):
    w0, w1 = rng.normal(size=3), rng.normal(size=3)

    def q_of_t(t):
        return rotvec_to_quat(w0 * jnp.sin(t) + w1 * t**2)

    t = 0.7
    q = q_of_t(t)
    qd = jax.jacfwd(q_of_t)(t)
    qdd = jax.jacfwd(jax.jacfwd(q_of_t))(t)
    om, al = angular_rates_from_quat(q, qd, qdd)
    # oracle: skew(omega) = Rdot R^T, alpha = d omega/dt by central differences
    R = lambda s: quat_to_matrix(q_of_t(s))  # noqa: E731
    Rd = jax.jacfwd(R)(t)
    S = np.asarray(Rd @ R(t).T)
    assert np.allclose([S[2, 1], S[0, 2], S[1, 0]], om, atol=1e-12)
    h = 1e-5

    def omega_at(s):
        return angular_rates_from_quat(q_of_t(s), jax.jacfwd(q_of_t)(s), jax.jacfwd(jax.jacfwd(q_of_t))(s))[0]

    al_fd = (omega_at(t + h) - omega_at(t - h)) / (2 * h)
    assert np.allclose(al, al_fd, atol=1e-8)


def test_wrench_matrix_is_minus_length_jacobian(robot, rng):
    for _ in range(5):
        p, R = random_pose(rng)

        def lengths(x):
            Rx = quat_to_matrix(rotvec_to_quat(x[3:])) @ R
            return cable_lengths(robot, p + x[:3], Rx)

        J = jax.jacfwd(lengths)(jnp.zeros(6))  # (m, 6)
        W = wrench_matrix(robot, p, R)
        assert np.allclose(np.asarray(W), -np.asarray(J).T, atol=1e-10)


def test_wrench_matrix_columns(robot, rng):
    p, R = random_pose(rng)
    W = np.asarray(wrench_matrix(robot, p, R))
    assert W.shape == (6, robot.n_cables)
    assert np.allclose(np.linalg.norm(W[:3], axis=0), 1.0)
    b = (np.asarray(R) @ np.asarray(robot.P_b).T).T
    assert np.allclose(W[3:].T, np.cross(b, W[:3].T), atol=1e-14)


def test_pulley_leave_point_geometry(rng):
    from conftest import SAMPLE_ROBOTS

    robot = robot_from_dict(SAMPLE_ROBOTS["four-pulleys"])
    p, R = random_pose(rng, 0.2)
    T = np.asarray(leave_points(robot, p, R))
    L = np.asarray(cable_vectors(robot, p, R))
    A = np.asarray(robot.B_A)
    k = np.asarray(robot.pulley_axis)
    r = np.asarray(robot.pulley_radius)
    b = p + (np.asarray(R) @ np.asarray(robot.P_b).T).T
    for i in range(4):
        # the pulley centre C lies at distance r from A, perpendicular to the axis, in the plane
        # holding the axis and B; T is on the rim and the straight cable is tangent there
        v = b[i] - A[i]
        e = v - (v @ k[i]) * k[i]
        e /= np.linalg.norm(e)
        C = A[i] + r[i] * e
        assert np.isclose(np.linalg.norm(T[i] - C), r[i], atol=1e-12)
        assert abs((T[i] - C) @ L[i]) < 1e-10
        assert abs(np.cross(k[i], e) @ (T[i] - A[i])) < 1e-12  # T in the pulley plane
    ang = np.asarray(swivel_angles(robot, p, R))
    assert ang.shape == (4,) and np.all(np.abs(ang) <= np.pi)


def test_zero_radius_pulley_equals_fixed_exit(rng):
    from conftest import SAMPLE_ROBOTS

    d = SAMPLE_ROBOTS["craft"]
    r0 = robot_from_dict(d)
    p, R = random_pose(rng)
    assert np.allclose(np.asarray(leave_points(r0, p, R)), np.asarray(r0.B_A), atol=0)
    rp = robot_from_dict(robot_to_dict(r0))
    assert np.allclose(np.asarray(wrench_matrix(rp, p, R)), np.asarray(wrench_matrix(r0, p, R)))


def random_params(rng):
    A = rng.normal(size=(3, 3))
    I_G = A @ A.T * 0.05 + 0.05 * np.eye(3)
    return InertialParameters(rng.uniform(2, 20), rng.normal(0, 0.1, 3), I_G)


@pytest.mark.parametrize("seed", range(20))
def test_regressors_match_newton_euler(seed):
    rng = np.random.default_rng(seed)
    par = random_params(rng)
    R = quat_to_matrix(rotvec_to_quat(rng.normal(0, 0.5, 3)))
    a, om, al = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    g = jnp.array([0.0, 0.0, -9.81])
    w = np.asarray(platform_wrench(par, R, a, om, al, g))
    Af = np.asarray(regressor_full(R, a, om, al, g))
    assert np.allclose(Af @ np.asarray(par.vector("full")), w, rtol=0, atol=1e-10)
    # translation regressor: exact when the platform does not rotate
    w0 = np.asarray(platform_wrench(par, R, a, jnp.zeros(3), jnp.zeros(3), g))
    At = np.asarray(regressor_translation(R, a, g))
    # the translation model has no inertia: compare force rows and the first-moment moments
    par_no_inertia = InertialParameters(par.mass, par.com, jnp.zeros((3, 3)))
    w00 = np.asarray(platform_wrench(par_no_inertia, R, a, jnp.zeros(3), jnp.zeros(3), g))
    assert np.allclose(At @ np.asarray(par.vector("translation")), w00, atol=1e-10)
    assert np.allclose(w0[:3], w00[:3], atol=1e-12)


def test_translation_regressor_is_paper_eq10():
    a = np.array([0.3, -0.2, 0.5])
    g = 9.81
    A = np.asarray(regressor_translation(jnp.eye(3), a, jnp.array([0, 0, -g])))
    ax, ay, az = a
    paper = np.array([
        [ax, 0, 0, 0],
        [ay, 0, 0, 0],
        [az + g, 0, 0, 0],
        [0, 0, az + g, -ay],
        [0, -az - g, 0, ax],
        [0, ay, -ax, 0],
    ])
    assert np.allclose(A, paper, atol=1e-15)


def test_inertial_parameter_vector_roundtrip(rng):
    par = random_params(rng)
    back = InertialParameters.from_vector(np.asarray(par.vector("full")), "full")
    assert np.allclose(back.mass, par.mass)
    assert np.allclose(back.com, par.com)
    assert np.allclose(back.inertia_com, par.inertia_com, atol=1e-12)
