"""Typed results of the real-data identification (issue 36): the weight at rest and the
residual rms, checked on a platform held in static equilibrium (no ../shared needed)."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import lsq_linear

from cdprid.identify import RestWeight, prepare_real, weight_at_rest
from cdprid.identify._real import ResidualRms, _rms
from cdprid.io import read_dataset, write_dataset
from cdprid.model import robot_from_dict

MASS = 7.5  # kg, centre of mass at P


def _static_tensions(robot, pos):
    """Tensions (>= 5 N) holding MASS at each position without rotation: W tau = (0, 0, m g,
    0, 0, 0) solved by bounded least squares (exact: 8 cables, a feasible pose)."""
    from cdprid.model import wrench_matrix

    g = np.asarray(robot.gravity)
    out = []
    for p in pos:
        W = np.asarray(wrench_matrix(robot, p, np.eye(3)))
        sol = lsq_linear(W, np.r_[-MASS * g, 0, 0, 0], bounds=(5.0, np.inf), tol=1e-14)
        out.append(sol.x)
    return np.array(out)


def test_weight_at_rest_is_typed_and_recovers_the_mass(tmp_path):
    from conftest import ROBOT_CRAFT

    robot = robot_from_dict(ROBOT_CRAFT)
    t = np.arange(0, 8, 0.02)
    s = np.clip((t - 3.0) / 2.0, 0, 1)
    s = s * s * (3 - 2 * s)  # rest, a smooth move of 0.2 m in x, rest
    pos = np.column_stack([0.2 * s, 0 * t, 1.2 + 0 * t])
    tau = _static_tensions(robot, pos)
    ds = write_dataset(tmp_path / "ds", robot, t, pos, t, tau,
                       quaternion=np.tile([1.0, 0, 0, 0], (len(t), 1)))
    rest = weight_at_rest(prepare_real(read_dataset(ds)))
    assert isinstance(rest, RestWeight)
    assert len(rest.windows) == 2 and rest.windows[0][1] < 3.1 and rest.windows[1][0] > 4.9
    assert len(rest.per_window) == 2 and rest.n > 100
    np.testing.assert_allclose(rest.per_window, MASS, rtol=1e-9)
    assert abs(rest.mass - MASS) < 1e-9 * MASS and rest.std < 1e-9
    try:
        rest.mass = 0.0
    except dataclasses.FrozenInstanceError:
        pass
    else:
        raise AssertionError("RestWeight is not frozen")


def test_residual_rms_matches_numpy_and_is_nan_when_empty(rng):
    e = rng.normal(size=(50, 6)) * [1, 2, 3, 0.1, 0.2, 0.3]
    mask = rng.uniform(size=50) < 0.5
    r = _rms(e, mask)
    assert isinstance(r, ResidualRms)
    assert r.force_N == np.sqrt(np.mean(e[mask][:, :3] ** 2))
    assert r.moment_Nm == np.sqrt(np.mean(e[mask][:, 3:] ** 2))
    assert list(dataclasses.asdict(r)) == ["force_N", "moment_Nm"]  # RealResult.summary keys
    empty = _rms(e, np.zeros(50, bool))
    assert np.isnan(empty.force_N) and np.isnan(empty.moment_Nm)
