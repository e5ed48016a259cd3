"""Trajectories: exact derivatives, rest at both ends, presets, CSV round trip."""

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from cdprid.io import load_trajectory_csv, save_trajectory_csv  # noqa: E402
from cdprid.model import (  # noqa: E402  # noqa: E402
    Orbit,
    check_workspace,
    craft_like_robot,  # noqa: E402
    orbit_sequence,
    preset,
    quat_conjugate,
    quat_multiply,
    with_rotation,
)


def test_derivatives_match_autodiff_of_position(two_orbits):
    t = np.linspace(0.0, two_orbits.duration, 97)
    s = two_orbits.evaluate(t)
    d1 = jax.jacfwd(two_orbits.position)
    d2 = jax.jacfwd(d1)
    d3 = jax.jacfwd(d2)
    v, a, j = jax.jit(jax.vmap(lambda x: (d1(x), d2(x), d3(x))))(jnp.asarray(t))
    np.testing.assert_allclose(s.v, v, atol=1e-12)
    np.testing.assert_allclose(s.a, a, atol=1e-11)
    np.testing.assert_allclose(s.j, j, atol=1e-10)


def test_derivatives_match_finite_differences(two_orbits):
    t = np.linspace(0.05, two_orbits.duration - 0.05, 211) + 1e-3  # off the ramp boundaries
    h = 1e-5
    s, sp, sm = two_orbits.evaluate(t), two_orbits.evaluate(t + h), two_orbits.evaluate(t - h)
    np.testing.assert_allclose((sp.p - sm.p) / (2 * h), s.v, atol=1e-8)
    np.testing.assert_allclose((sp.v - sm.v) / (2 * h), s.a, atol=1e-7)
    np.testing.assert_allclose((sp.a - sm.a) / (2 * h), s.j, atol=1e-6)


def test_motion_vanishes_at_both_ends(two_orbits):
    s = two_orbits.evaluate([0.0, 0.3, two_orbits.duration - 0.3, two_orbits.duration])
    np.testing.assert_allclose(s.p, np.tile([0.0, 0.0, 1.2], (4, 1)), atol=1e-15)
    for x in (s.v, s.a, s.j):
        np.testing.assert_allclose(x, 0.0, atol=1e-11)
    mid = two_orbits.evaluate([3.0])
    assert np.linalg.norm(mid.v) > 0.1


def test_rotation_rates_match_quaternion_finite_differences(two_orbits):
    tr = with_rotation(two_orbits, 0.05)
    assert tr.has_rotation
    t = np.linspace(1.0, tr.duration - 1.0, 53)
    h = 1e-5
    s, sp, sm = tr.evaluate(t), tr.evaluate(t + h), tr.evaluate(t - h)
    qd = (np.asarray(sp.q) - np.asarray(sm.q)) / (2 * h)
    omega_fd = np.array(
        [2 * np.asarray(quat_multiply(qd[k], quat_conjugate(s.q[k])))[1:] for k in range(len(t))]
    )
    np.testing.assert_allclose(s.omega, omega_fd, atol=1e-8)
    np.testing.assert_allclose((sp.omega - sm.omega) / (2 * h), s.alpha, atol=1e-7)
    np.testing.assert_allclose(np.linalg.norm(s.q, axis=1), 1.0, atol=1e-14)
    ends = tr.evaluate([0.0, tr.duration])
    np.testing.assert_allclose(ends.omega, 0.0, atol=1e-15)
    np.testing.assert_allclose(ends.alpha, 0.0, atol=1e-15)
    assert np.max(np.abs(np.asarray(s.q)[:, 1:])) > 0.01


def test_csv_round_trip_exact_at_samples_and_close_between(tmp_path, two_orbits):
    tr = with_rotation(two_orbits, 0.05)
    path = save_trajectory_csv(tr, tmp_path / "two_orbits.csv", rate_hz=100.0)
    with pytest.raises(FileExistsError):
        save_trajectory_csv(tr, path)
    loaded = load_trajectory_csv(path)
    assert loaded.has_rotation
    t = np.asarray(loaded.t)
    a, b = loaded.evaluate(t[::7]), tr.evaluate(t[::7])
    for x, y in zip(a[1:], b[1:], strict=True):
        if x is a.j:
            continue
        np.testing.assert_allclose(x, y, atol=1e-12)
    tm = t[:-1:5] + 0.0037
    a, b = loaded.evaluate(tm), tr.evaluate(tm)
    np.testing.assert_allclose(a.p, b.p, atol=1e-8)
    np.testing.assert_allclose(a.a, b.a, atol=1e-3)
    np.testing.assert_allclose(a.q, b.q, atol=1e-8)
    np.testing.assert_allclose(a.omega, b.omega, atol=1e-5)


def test_presets_respect_the_workspace_and_the_paper_protocol():
    robot = craft_like_robot()
    tr = preset("paper-orbits", robot)
    assert tr.duration == pytest.approx(52.0)
    assert tr.radius.shape == (4,)
    assert np.all((tr.radius >= 0.3) & (tr.radius <= 0.4))
    np.testing.assert_allclose(tr.freq, 0.25)
    check_workspace(tr, robot)
    rich = preset("rich", robot)
    assert rich.duration == pytest.approx(52.0)
    assert float(rich.radius.max()) <= 0.9 * 1.2  # |P - centre| <= radius < half the box in y
    assert rich.freq.min() == pytest.approx(0.2) and rich.freq.max() == pytest.approx(0.6)
    with pytest.raises(ValueError, match="valid presets"):
        preset("nope", robot)


def test_workspace_violation_is_reported():
    robot = craft_like_robot()
    tr = orbit_sequence([Orbit(1.5, 0.2, 6.0)], [0.0, 0.0, 1.2])
    with pytest.raises(ValueError, match="leaves the workspace box"):
        check_workspace(tr, robot)
