"""Causal differentiators on rotating data (issue 24): every regressor term and W tau pass one
linear filter (:mod:`cdprid.core._linear_match`), so a causal method is unbiased on
noise-free rotating data.

Before, on a noise-free 6-cable recording rotating 5 deg, the principal inertias came out
-302 % (sihd2-cascade), +10.6 % (sihd3) and -4.8 % (kalman). The oracle is the simulator's
truth; the FIR machinery is checked against a linear filter and polynomials."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.core import Motion, fit_linear_match, reference_rates
from cdprid.identify import identify_dataset
from cdprid.io import read_dataset
from cdprid.model import SIX_SUSPENDED, craft_like_robot, craft_like_truth, preset, robot_from_dict
from cdprid.signal import acceleration_filter, differentiate
from cdprid.simulation import SensorNoise, simulate, write_simulation


def _inertia_eigs(x):
    return np.linalg.eigvalsh(np.array([[x[4], x[5], x[6]], [x[5], x[7], x[8]],
                                        [x[6], x[8], x[9]]]))


@pytest.fixture(scope="module")
def six_sim():
    """The 6-cable robot rotating 5 deg, noise-free: simulated once for the batch and the
    online tests of this module (the simulator's programs compiled once)."""
    robot = robot_from_dict(SIX_SUSPENDED)
    return robot, simulate(robot, preset("rich", robot, rotation_amplitude=0.09),
                           noise=SensorNoise.off())


@pytest.fixture(scope="module")
def rotating_six(six_sim, tmp_path_factory):
    return read_dataset(write_simulation(six_sim[1], tmp_path_factory.mktemp("six") / "d"))


@pytest.fixture(scope="module")
def craft_sim():
    """The CRAFT-like robot rotating about 6 deg, noise-free (batch and online tests)."""
    robot = craft_like_robot()
    return robot, simulate(robot, preset("rich", robot, rotation_amplitude=0.1),
                           noise=SensorNoise.off())


def _signals(sim):
    return {"t": sim.pose_t, "position": sim.position, "quaternion": sim.quaternion,
            "tension": sim.tension}


@pytest.mark.parametrize("method", ["kalman", "sihd3", "sihd2-cascade", "levant"])
def test_causal_differentiators_unbiased_on_noise_free_rotation(rotating_six, method):
    rep = identify_dataset(rotating_six, model="full", differentiator=method, bound=False,
                           weighting="none")
    x = np.asarray(rep.result.x)
    truth = np.asarray(craft_like_truth().vector("full"))
    assert abs(x[0] / truth[0] - 1) < 0.005  # m
    assert abs(x[3] / truth[3] - 1) < 0.02  # m zG
    np.testing.assert_allclose(_inertia_eigs(x), _inertia_eigs(truth), rtol=0.05)
    assert any("rotation-consistent" in n for n in rep.notes)


def test_craft_like_robot_sihd2_cascade(craft_sim, tmp_path):
    """Same on the 8-cable robot with the eiv default weighting (6 deg)."""
    ds = read_dataset(write_simulation(craft_sim[1], tmp_path / "d"))
    x = np.asarray(identify_dataset(ds, model="full", differentiator="sihd2-cascade",
                                    bound=False).result.x)
    truth = np.asarray(craft_like_truth().vector("full"))
    assert abs(x[0] / truth[0] - 1) < 0.005
    assert abs(x[3] / truth[3] - 1) < 0.02
    np.testing.assert_allclose(_inertia_eigs(x), _inertia_eigs(truth), rtol=0.05)


def test_fir_reproduces_a_linear_causal_filter():
    """For a linear differentiator the fitted FIR is its impulse response: H[u] matches the
    method's own acceleration filter on a signal it never saw."""
    dt, n = 0.01, 3000
    t = np.arange(n) * dt
    rng = np.random.default_rng(3)
    p = np.stack([np.sin(2 * np.pi * f * t + ph) * 0.2 for f, ph in
                  zip(rng.uniform(0.2, 1.5, 3), rng.uniform(0, 6, 3), strict=True)], 1)
    _, a = differentiate(p, dt, method="euler-butter-causal")
    z = np.zeros((n, 3))
    mo = Motion(t, p, z, np.asarray(a), np.broadcast_to(np.eye(3), (n, 3, 3)), z, z,
                "euler-butter-causal")
    keep = (t > 1.0) & (t < t[-1] - 1.0)
    lm = fit_linear_match(mo, keep, 1.0)
    assert lm.fit_residual < 5e-3
    u = np.cos(2 * np.pi * 0.7 * t)[:, None] + 0.3 * np.sin(2 * np.pi * 1.1 * t)[:, None]
    ref = acceleration_filter(u, dt, method="euler-butter-causal")
    k = t > 2.0
    assert np.max(np.abs(lm(u)[k] - ref[k])) < 2e-2 * np.max(np.abs(u))  # one sample of lag: 7 %
    np.testing.assert_allclose(lm(np.full((n, 2), 4.0)), 4.0, atol=1e-9)  # DC passes


def test_reference_rates_match_the_trajectory_oracle():
    robot = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(robot, preset("rich", robot, duration=26.0, rotation_amplitude=0.05),
                   noise=SensorNoise.off())
    n = len(sim.pose_t)
    z = np.zeros((n, 3))
    mo = Motion(sim.pose_t, sim.position, z, z, np.broadcast_to(np.eye(3), (n, 3, 3)), z, z, "-")
    a, om, al = reference_rates(mo, sim.quaternion)
    k = slice(5, n - 5)
    tr = sim.motion
    for est, true in ((om, tr.omega), (al, tr.alpha), (a, tr.a)):
        true = np.asarray(true)
        np.testing.assert_allclose(est[k], true[k], atol=5e-3 * np.max(np.abs(true)))


@pytest.mark.parametrize("name", ["six", "craft"])
def test_online_full_model_unbiased_on_noise_free_rotation(name, six_sim, craft_sim):
    """The online path: rows of sample k - 3 through the FIR fitted to the SIHD cascade on a
    reference motion (was m -0.05 %, mzG -3.4 %, principal inertias +8 to +29 %). Issue 24 on
    the CRAFT-like and 6-cable robots: before, a causal filter's lag gave mzG -0.80 (truth
    -1.06) and Ixx -1.34 (inertia not positive definite) on the CRAFT-like robot (this test
    was tests/identify/test_online_rotation.py, on its own simulations)."""
    from cdprid.identify import online_identify

    robot, sim = six_sim if name == "six" else craft_sim
    x = np.asarray(online_identify(_signals(sim), robot, model="full").x_final)
    truth = np.asarray(craft_like_truth().vector("full"))
    assert abs(x[0] / truth[0] - 1) < 0.001  # m
    np.testing.assert_allclose(x[1:3], truth[1:3], atol=2e-3)  # mxG, myG
    assert abs(x[3] / truth[3] - 1) < 0.02  # mzG (was 9-24 % off)
    np.testing.assert_allclose(_inertia_eigs(x), _inertia_eigs(truth), rtol=0.05)


def test_fir_fit_is_well_conditioned():
    """The taps stay of the size of a second difference (a free 100-tap fit gave norm 1e9) and
    the acceleration response decays above the motion's band."""
    from cdprid.core import reference_fir
    from cdprid.signal import METHODS

    dt = 0.01
    c = reference_fir("sihd2-cascade", dict(METHODS["sihd2-cascade"].params), dt)
    assert np.linalg.norm(c) < 10.0 / dt ** 2
    j = np.arange(len(c))

    def gain(f):
        return abs(np.sum(c * np.exp(-2j * np.pi * f * dt * j))) / (2 * np.pi * f) ** 2

    assert abs(gain(0.02) - 1) < 0.01
    assert gain(10.0) < 0.25 and gain(25.0) < 0.25  # the free fit: 1654 at 2 Hz
    np.testing.assert_allclose([c.sum(), (j * c).sum()], 0.0, atol=1e-6 / dt ** 2)


def test_eight_cable_redundant_robot_rotating_10_deg(tmp_path):
    """A third robot (8 cables, redundant, 40 N pretension, a small 4.5 kg platform) rotating
    about 10 deg: kalman and online within the same tolerances."""
    from cdprid.identify import online_identify
    from cdprid.model import EIGHT_REDUNDANT, InertialParameters

    robot = robot_from_dict(EIGHT_REDUNDANT)
    truth = InertialParameters(4.5, np.array([0.01, -0.005, -0.04]),
                               np.diag([0.03, 0.035, 0.05]))
    sim = simulate(robot, preset("rich", robot, duration=26.0, rotation_amplitude=0.1), truth,
                   noise=SensorNoise.off(), tau_ref=40.0)
    t = np.asarray(truth.vector("full"))
    ds = read_dataset(write_simulation(sim, tmp_path / "d"))
    sig = {"t": sim.pose_t, "position": sim.position, "quaternion": sim.quaternion,
           "tension": sim.tension}
    for x in (np.asarray(identify_dataset(ds, model="full", differentiator="kalman",
                                          bound=False).result.x),
              np.asarray(online_identify(sig, robot, model="full").x_final)):
        assert abs(x[0] / t[0] - 1) < 0.005
        assert abs(x[3] / t[3] - 1) < 0.02
        np.testing.assert_allclose(_inertia_eigs(x), _inertia_eigs(t), rtol=0.05)


def test_up_fed_swivel_pulleys_rotating_noise_free(tmp_path):
    """The issue's case: a 6-cable robot whose swivel pulleys (3 cm) are fed from below,
    rotating 5 deg, no noise: the causal cascade and online identification within the
    acceptance tolerances (measured: every principal inertia within 0.5 %)."""
    from cdprid.identify import online_identify

    robot = robot_from_dict(SIX_SUSPENDED)
    robot = robot.replace(pulley_axis=np.tile([0.0, 0.0, 1.0], (robot.n_cables, 1)),
                          pulley_radius=np.full(robot.n_cables, 0.03))
    sim = simulate(robot, preset("rich", robot, rotation_amplitude=0.09), noise=SensorNoise.off())
    ds = read_dataset(write_simulation(sim, tmp_path / "d"))
    truth = np.asarray(craft_like_truth().vector("full"))
    x_batch = identify_dataset(ds, model="full", differentiator="sihd2-cascade",
                               bound=False).result.x
    sig = {"t": sim.pose_t, "position": sim.position, "quaternion": sim.quaternion,
           "tension": sim.tension}
    x_online = online_identify(sig, robot, model="full").x_final
    for x in (np.asarray(x_batch), np.asarray(x_online)):
        assert abs(x[0] / truth[0] - 1) < 0.005
        assert abs(x[3] / truth[3] - 1) < 0.02
        np.testing.assert_allclose(_inertia_eigs(x), _inertia_eigs(truth), rtol=0.05)
