"""Online identification on rotating, noise-free data (issue 24): the first moment is right
and the inertia has the right sign on the CRAFT-like and 6-cable robots. Before, a causal
filter's lag gave mzG -0.80 (truth -1.06) and Ixx -1.34 on the CRAFT-like robot. The full
model now takes the rotation-consistent path (tests/identify/test_rotation_consistent.py holds
the 5 % inertia check)."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.identify import online_identify
from cdprid.model import SIX_SUSPENDED, craft_like_robot, craft_like_truth, preset, robot_from_dict
from cdprid.simulation import SensorNoise, simulate


@pytest.mark.parametrize("name, amplitude", [("craft", 0.1), ("six", 0.05)])
def test_online_full_model_on_rotating_noise_free_data(name, amplitude):
    robot = craft_like_robot() if name == "craft" else robot_from_dict(SIX_SUSPENDED)
    sim = simulate(robot, preset("rich", robot, rotation_amplitude=amplitude),
                   noise=SensorNoise.off())
    sig = {"t": sim.pose_t, "position": sim.position, "quaternion": sim.quaternion,
           "tension": sim.tension}
    x = online_identify(sig, robot, model="full").x_final
    truth = np.asarray(craft_like_truth().vector("full"))
    assert abs(x[0] / truth[0] - 1) < 0.001  # m
    np.testing.assert_allclose(x[1:3], truth[1:3], atol=2e-3)  # mxG, myG
    assert abs(x[3] / truth[3] - 1) < 0.04  # mzG (was 9-24 % off)
    inertia = np.array([[x[4], x[5], x[6]], [x[5], x[7], x[8]], [x[6], x[8], x[9]]])
    assert np.all(np.linalg.eigvalsh(inertia) > 0)  # was not positive definite
