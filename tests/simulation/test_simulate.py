"""Simulator: Newton-Euler identity, every effect of the vocabulary, dataset writing, CLI."""

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import tomli_w  # noqa: E402

from cdprid.effects import Effect, effect_parameters_table  # noqa: E402
from cdprid.io import read_dataset  # noqa: E402
from cdprid.model import (  # noqa: E402  # noqa: E402  # noqa: E402  # noqa: E402
    CRAFT_LIKE,
    InertialParameters,
    InfeasibleTensionsError,  # noqa: E402
    craft_like_robot,
    craft_like_truth,
    leave_points,
    platform_wrench,
    preset,
    quat_to_matrix,  # noqa: E402
    regressor_translation,
    wrench_matrix,
)
from cdprid.simulation import SensorNoise, simulate, write_simulation  # noqa: E402

OFF = SensorNoise.off()


@pytest.fixture(scope="module")
def robot():
    return craft_like_robot()


def run(robot, two_orbits, effects=(), noise=OFF, **kw):
    return simulate(robot, two_orbits, effects=effects, noise=noise, **kw)


@pytest.fixture(scope="module")
def clean(robot, two_orbits):
    return run(robot, two_orbits)


@jax.jit
def _ne_residual(robot_true, params, g, p, q, a, omega, alpha, tau):
    def one(pk, qk, ak, wk, alk, tk):
        R = quat_to_matrix(qk)
        return wrench_matrix(robot_true, pk, R) @ tk - platform_wrench(params, R, ak, wk, alk, g)

    return jax.vmap(one)(p, q, a, omega, alpha, tau)


def newton_euler_residual(robot_true, params, res, gravity=None):
    """W(pose) tau - platform_wrench, recomputed from geometry and dynamics (every 7th sample)."""
    g = robot_true.gravity if gravity is None else gravity
    m = res.motion_tension
    k = slice(0, None, 7)
    return np.asarray(
        _ne_residual(
            robot_true, params, g, m.p[k], m.q[k], m.a[k], m.omega[k], m.alpha[k], res.tension[k]
        )
    )


def test_noise_free_data_satisfy_newton_euler(robot, clean):
    r = newton_euler_residual(robot, craft_like_truth(), clean)
    assert np.max(np.abs(r)) < 1e-9
    assert clean.quaternion is None
    np.testing.assert_array_equal(clean.position, clean.motion.p)
    assert 1.0 - 1e-9 <= clean.tension.min() and clean.tension.max() < 60.0  # robot limits 1..150 N


def test_rotational_dynamics_rotates_and_inertia_acts(robot, two_orbits, clean):
    res = run(robot, two_orbits, [Effect("rotational_dynamics", {"amplitude_rad": 0.05})])
    assert res.quaternion is not None
    angle = 2 * np.arccos(np.clip(res.quaternion[:, 0], -1, 1))
    assert 0.03 < angle.max() < 0.05 * np.sqrt(3) + 1e-9
    r = newton_euler_residual(robot, craft_like_truth(), res)
    assert np.max(np.abs(r)) < 1e-9
    # the same motion without inertia would need different tensions
    no_inertia = InertialParameters(9.88, craft_like_truth().com)
    assert np.max(np.abs(newton_euler_residual(robot, no_inertia, res))) > 1e-3


def test_time_delay_is_a_fractional_delay(robot, two_orbits, clean):
    from scipy.interpolate import CubicSpline
    from scipy.optimize import minimize_scalar

    d = 0.0237
    res = run(robot, two_orbits, [Effect("time_delay", {"delay_s": d})])
    np.testing.assert_array_equal(res.pose_t, clean.pose_t)
    spline = CubicSpline(clean.tension_t, clean.tension, axis=0)
    sl = slice(50, -50)

    def cost(x):
        return np.sum((res.tension[sl] - spline(res.tension_t[sl] - x)) ** 2)

    est = minimize_scalar(cost, bounds=(0.0, 0.05), method="bounded", options={"xatol": 1e-7}).x
    assert abs(est - d) < 0.02 * 0.01  # 2 % of a sample period


def test_tension_offset_and_gain(robot, two_orbits, clean):
    res = run(
        robot,
        two_orbits,
        [
            Effect("tension_offset", {"cable": 2, "offset_N": 1.5}),
            Effect("tension_gain", {"cable": 5, "gain": 1.05}),
        ],
    )
    diff = res.tension - clean.tension
    np.testing.assert_allclose(diff[:, 1], 1.5, atol=1e-12)
    np.testing.assert_allclose(res.tension[:, 4] / clean.tension[:, 4], 1.05, rtol=1e-12)
    others = [0, 2, 3, 5, 6, 7]
    np.testing.assert_array_equal(diff[:, others], 0.0)


def test_pulley_friction_reads_on_the_winch_side(robot, two_orbits, clean):
    e = Effect("pulley_friction", {"cable": 2, "coulomb_N": 1.5, "viscous_Ns_per_m": 4.0})
    res = run(robot, two_orbits, [e, Effect("tension_gain", {"cable": 2, "gain": 1.1})])
    W = np.asarray(res.W_true)
    mt = res.motion_tension
    ldot = -np.einsum("nim,ni->nm", W, np.concatenate([np.asarray(mt.v), np.asarray(mt.omega)],
                                                      axis=1))
    want = 1.1 * (clean.tension[:, 1] - 1.5 * np.sign(ldot[:, 1]) - 4.0 * ldot[:, 1])
    np.testing.assert_allclose(res.tension[:, 1], want, atol=1e-9)
    np.testing.assert_array_equal(res.tension[:, [0, 2]], clean.tension[:, [0, 2]])


@pytest.mark.parametrize("name,field", [("exit_point_error", "B_A"), ("anchor_point_error", "P_b")])
def test_geometry_errors_use_the_true_geometry(robot, two_orbits, name, field):
    dx = np.array([0.01, 0.0, -0.02])
    res = run(robot, two_orbits, [Effect(name, {"cable": 3, "displacement_m": "0.01,0,-0.02"})])
    true_pts = np.array(getattr(robot, field))
    true_pts[2] += dx
    robot_true = robot.replace(**{field: true_pts})
    assert np.max(np.abs(newton_euler_residual(robot_true, craft_like_truth(), res))) < 1e-9
    assert np.max(np.abs(newton_euler_residual(robot, craft_like_truth(), res))) > 1e-3
    np.testing.assert_array_equal(np.asarray(res.robot.B_A), np.asarray(robot.B_A))


def test_viscous_drag_force_residual_is_minus_c_v(robot, two_orbits):
    c = 3.0
    res = run(robot, two_orbits, [Effect("viscous_drag", {"coefficient_Ns_per_m": c})])
    r = newton_euler_residual(robot, craft_like_truth(), res)
    v = np.asarray(res.motion_tension.v)[::7]
    # W tau + (-c v) = m (a - g): the cable force exceeds the model by c v
    c_est = np.sum(r[:, :3] * v) / np.sum(v * v)
    assert c_est == pytest.approx(c, rel=1e-9)
    np.testing.assert_allclose(r[:, 3:], 0.0, atol=1e-9)


def test_frame_tilt_changes_the_gravity_direction(robot, two_orbits):
    rx, ry = 0.01, -0.02
    res = run(robot, two_orbits, [Effect("frame_tilt", {"tilt_rad": [rx, ry]})])
    m = craft_like_truth().mass
    W = res.W_true
    F = np.einsum("nij,nj->ni", W, res.tension)[:, :3]
    # pure translation: F = m (a - g)  ->  g = a - F / m
    g_est = np.asarray(res.motion_tension.a) - F / float(m)
    Rx = np.array([[1, 0, 0], [0, np.cos(rx), -np.sin(rx)], [0, np.sin(rx), np.cos(rx)]])
    Ry = np.array([[np.cos(ry), 0, np.sin(ry)], [0, 1, 0], [-np.sin(ry), 0, np.cos(ry)]])
    g_expected = (Ry @ Rx).T @ np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(g_est, np.tile(g_expected, (len(g_est), 1)), atol=1e-9)
    # the documented sense: g_pose = |g| [sin ry, -sin rx cos ry, -cos rx cos ry]
    np.testing.assert_allclose(
        g_expected,
        9.81 * np.array([np.sin(ry), -np.sin(rx) * np.cos(ry), -np.cos(rx) * np.cos(ry)]),
        atol=1e-14,
    )


def test_pulley_moves_the_leave_points(robot, two_orbits, clean):
    r = 0.05
    res = run(robot, two_orbits, [Effect("pulley", {"radius_m": r})])
    assert float(res.robot.pulley_radius.max()) == 0.0  # robot.toml omits the pulleys
    robot_true = robot.replace(pulley_radius=np.full(8, r))
    np.testing.assert_allclose(
        res.W_true[0],
        np.asarray(wrench_matrix(robot_true, res.motion_tension.p[0], np.eye(3))),
        atol=1e-14,
    )
    T = np.asarray(leave_points(robot_true, res.motion_tension.p[0], np.eye(3)))
    dist = np.linalg.norm(T - np.asarray(robot.B_A), axis=1)
    assert np.all(dist > 0.5 * r) and np.all(dist <= 2 * r + 1e-12)
    assert np.max(np.abs(newton_euler_residual(robot_true, craft_like_truth(), res))) < 1e-9
    assert np.max(np.abs(newton_euler_residual(robot, craft_like_truth(), res))) > 1e-3


def test_cable_mass_adds_half_the_cable_weight(robot, two_orbits):
    rho = 0.1
    res = run(robot, two_orbits, [Effect("cable_mass", {"linear_density_kg_per_m": rho})])
    k = np.arange(0, len(res.tension_t), 11)
    p = np.asarray(res.motion_tension.p)[k]
    B = p[:, None, :] + np.asarray(robot.P_b)[None]  # no rotation
    L = np.linalg.norm(np.asarray(robot.B_A)[None] - B, axis=2)
    F = np.einsum("nij,nj->ni", res.W_true[k], res.tension[k])
    model = res.wrench_required[k]
    np.testing.assert_allclose(F[:, 2] - model[:, 2], 0.5 * rho * 9.81 * L.sum(axis=1), rtol=1e-9)
    np.testing.assert_allclose(F[:, :2] - model[:, :2], 0.0, atol=1e-9)


def test_noise_and_rates_and_seed(robot, two_orbits, clean):
    noise = SensorNoise(
        position_m=2e-4, orientation_rad=1e-3, tension_N=0.5, tension_quantum_N=0.01
    )
    a = run(robot, two_orbits, noise=noise, rate_pose=100.0, rate_tension=80.0, seed=3)
    b = run(robot, two_orbits, noise=noise, rate_pose=100.0, rate_tension=80.0, seed=3)
    np.testing.assert_array_equal(a.tension, b.tension)
    assert a.tension_t.size != a.pose_t.size
    assert np.std(a.position - a.motion.p) == pytest.approx(2e-4, rel=0.1)
    e = a.tension - a.tension_true
    assert np.std(e) == pytest.approx(0.5, rel=0.1)
    np.testing.assert_allclose(a.tension / 0.01, np.round(a.tension / 0.01), atol=1e-6)
    assert a.quaternion is not None and np.max(np.abs(a.quaternion[:, 1:])) > 1e-4


def test_infeasible_request_raises(robot, two_orbits):
    with pytest.raises(
        InfeasibleTensionsError, match=r"^tension distribution infeasible at \d+ of \d+ samples"
    ):
        run(robot, two_orbits, tension_max=5.0)


def test_unknown_effects_and_parameters_are_rejected(robot, two_orbits):
    with pytest.raises(ValueError, match="valid effects: none, time_delay"):
        Effect("delay", {})
    with pytest.raises(ValueError, match="valid parameters: cable, gain"):
        Effect("tension_gain", {"cable": 1, "gian": 1.0})
    with pytest.raises(ValueError, match="has 8 cables"):
        run(robot, two_orbits, [Effect("tension_offset", {"cable": 9, "offset_N": 1.0})])


def test_written_dataset_reads_back(tmp_path, robot, two_orbits):
    effects = [
        Effect("time_delay", {"delay_s": 0.02}),
        Effect("tension_gain", {"cable": 3, "gain": 1.05}),
        Effect("rotational_dynamics", {"amplitude_rad": 0.03}),
    ]
    res = run(robot, two_orbits, effects, noise=SensorNoise())
    out = write_simulation(res, tmp_path / "ds")
    with pytest.raises(FileExistsError):
        write_simulation(res, tmp_path / "ds")
    ds = read_dataset(out)
    np.testing.assert_allclose(ds.position, res.position, atol=1e-9)
    np.testing.assert_allclose(ds.tension, res.tension, rtol=1e-9)
    assert ds.quaternion is not None
    truth = ds.truth
    assert truth["mass"] == pytest.approx(9.88)
    assert truth["effects"] == ["time_delay", "tension_gain", "rotational_dynamics"]
    assert truth["effect_parameters"]["delay_s"] == 0.02
    assert truth["effect_parameters"]["tension_gain"] == {"cable": 3, "gain": 1.05}
    assert ds.meta["source"] == "simulated"
    cols, vals = ds.extra["truth_motion"]
    assert cols[:10] == ["t", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az"]
    np.testing.assert_allclose(vals[:, 1:4], res.motion.p, atol=1e-9)
    assert effect_parameters_table([Effect("time_delay", {"delay_s": 0.025})]) == {"delay_s": 0.025}


def test_paper_orbits_identify_exactly(robot):
    from cdprid.core import least_squares

    res = simulate(robot, preset("paper-orbits", robot, duration=12.0), noise=OFF)
    m = res.motion_tension
    A = jax.jit(jax.vmap(regressor_translation, in_axes=(None, 0, None)))(
        np.eye(3), m.a, robot.gravity
    )
    A = np.asarray(A).reshape(-1, 4)
    Y = np.einsum("nij,nj->ni", res.W_true, res.tension).reshape(-1)
    ls = least_squares(A, Y)
    np.testing.assert_allclose(ls.x, np.asarray(craft_like_truth().vector()), rtol=1e-9, atol=1e-11)


# ----------------------------------------------------------------------------- CLI


def test_cli_simulate(tmp_path, capsys):
    from cdprid.cli import main

    out = tmp_path / "sim"
    args = [
        "simulate",
        "--out",
        str(out),
        "--duration",
        "11",
        "--rate-pose",
        "50",
        "--rate-tension",
        "40",
        "--effect",
        "tension_gain",
        "--param",
        "cable=3",
        "--param",
        "gain=1.05",
        "--effect",
        "exit_point_error",
        "--param",
        "cable=2",
        "--param",
        "displacement_m=[0.01,0,-0.02]",
    ]
    assert main(args) == 0
    assert "tension samples" in capsys.readouterr().out
    ds = read_dataset(out)
    assert ds.truth["effects"] == ["tension_gain", "exit_point_error"]
    assert ds.pose_t.size == 551 and ds.tension_t.size == 441
    assert main(args) == 2  # exists, no --force
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--force" in err[0]
    assert main(args + ["--force"]) == 0
    capsys.readouterr()
    assert main(["simulate", "--out", str(tmp_path / "x"), "--effect", "wind"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "valid effects" in err[0]
    assert (
        main(["simulate", "--out", str(tmp_path / "x"), "--effect", "pulley", "--param", "r=1"])
        == 2
    )
    assert "valid parameters: radius_m" in capsys.readouterr().err


def test_cli_infeasible_exits_2_with_one_line(tmp_path, capsys):
    from cdprid.cli import main

    data = dict(CRAFT_LIKE)
    data["limits"] = dict(CRAFT_LIKE["limits"], tension_max=5.0)
    (tmp_path / "robot.toml").write_bytes(tomli_w.dumps(data).encode())
    code = main(
        [
            "simulate",
            "--out",
            str(tmp_path / "o"),
            "--robot",
            str(tmp_path / "robot.toml"),
            "--duration",
            "11",
            "--rate-pose",
            "20",
            "--rate-tension",
            "20",
        ]
    )
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tension distribution infeasible" in err[0]
    assert not (tmp_path / "o" / "pose.csv").exists()


def test_cli_trajectory_file(tmp_path, robot, two_orbits):
    from cdprid.cli import main
    from cdprid.io import save_trajectory_csv

    f = save_trajectory_csv(two_orbits, tmp_path / "t.csv", rate_hz=100.0)
    assert (
        main(
            [
                "simulate",
                "--out",
                str(tmp_path / "d"),
                "--trajectory",
                str(f),
                "--noise-pos",
                "0",
                "--noise-tension",
                "0",
            ]
        )
        == 0
    )
    ds = read_dataset(tmp_path / "d")
    np.testing.assert_allclose(ds.position, np.asarray(two_orbits.evaluate(ds.pose_t).p), atol=1e-9)


def test_cable_elasticity_writes_the_encoder_stream(tmp_path, robot, two_orbits, clean):
    """lengths.csv: l = L / (1 + tau / EA) on the elastic cable, L on the others; no force."""
    e = Effect("cable_elasticity", {"cable": 3, "EA_N": 5e4})
    res = run(robot, two_orbits, [e])
    np.testing.assert_array_equal(res.tension, clean.tension)  # no force changes
    assert clean.lengths is None
    mt = res.motion_tension
    R = np.asarray(jax.vmap(quat_to_matrix)(mt.q))
    B = np.asarray(mt.p)[:, None, :] + np.einsum("nij,mj->nmi", R, np.asarray(robot.P_b))
    L = np.linalg.norm(np.asarray(robot.B_A)[None] - B, axis=2)  # no pulleys: straight
    want = L.copy()
    want[:, 2] = L[:, 2] / (1 + res.tension_true[:, 2] / 5e4)
    np.testing.assert_allclose(res.lengths, want, rtol=0, atol=1e-12)
    out = write_simulation(res, tmp_path / "ds")
    ds = read_dataset(out)
    cols, vals = ds.extra["lengths"]
    assert cols == ["t"] + [f"l_{i}" for i in range(1, 9)]
    np.testing.assert_allclose(vals[:, 1:], res.lengths, atol=1e-9)
    np.testing.assert_allclose(vals[:, 0], res.tension_t)
    # on request without the effect; encoder noise as stated
    noisy = run(robot, two_orbits, lengths=True, noise=SensorNoise(0.0, 0.0, 0.0, length_m=1e-4))
    d = noisy.lengths - L
    assert abs(d.std() - 1e-4) < 5e-6 and abs(d.mean()) < 5e-6
