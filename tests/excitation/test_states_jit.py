"""The excitation trajectories' ``evaluate`` (one shared jit wrapper, issue 36) equals their
eager ``states`` to 1e-12, for the Fourier family's trajectory and the homed one."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

import cdprid.excitation as ex
from cdprid.model import CRAFT_LIKE, robot_from_dict


@pytest.fixture(scope="module")
def fourier_problem():
    craft = robot_from_dict(CRAFT_LIKE, source="craft")
    prob = ex.make_problem(craft, "fourier", duration=12.0)
    z = jnp.asarray(prob.family.from_params(prob.family.initial_params(craft))) + 0.1
    return prob, z


@pytest.mark.parametrize("kind", ["fourier", "homed"])
def test_evaluate_is_the_eager_states(fourier_problem, kind):
    prob, z = fourier_problem
    traj = prob.family.trajectory(z) if kind == "fourier" else prob.homed(z)
    assert type(traj).__name__ == {"fourier": "FourierTrajectory",
                                   "homed": "HomedTrajectory"}[kind]
    t = np.linspace(0.0, float(traj.t_end), 41)
    jitted, eager = traj.evaluate(t), traj.states(jnp.asarray(t))
    for name, a, b in zip(eager._fields, jitted, eager, strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12,
                                   err_msg=name)
    # a scalar time is one row (the wrapper's contract: atleast_1d)
    assert np.asarray(traj.evaluate(1.0).p).shape == (1, 3)
