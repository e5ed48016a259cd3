"""Simulated winch drives (issue 41): currents and encoder lengths of the library simulator."""

from __future__ import annotations

import jax
import numpy as np

from cdprid.core import DriveParameters
from cdprid.model import SIX_SUSPENDED, cable_lengths, quat_to_matrix, robot_from_dict
from cdprid.simulation import simulate_drives


def _sim():
    """A stand-in for a SimResult: an independent numpy path (tests/identify/winch_sim.py) at
    100 Hz and made-up tensions (simulate_drives reads only these fields)."""
    from types import SimpleNamespace

    from tests.identify import winch_sim

    robot = robot_from_dict(SIX_SUSPENDED)
    path = winch_sim.Path(np.random.default_rng(0), [0.0, 0.0, 1.4], [0.25, 0.25, 0.15], 0.08)
    t = np.arange(0.0, 8.0, 0.01)
    p, v, a, R, om, al = winch_sim.rates(path, t)
    q = np.array([winch_sim._quat(r) for r in R])
    mt = SimpleNamespace(p=p, v=v, a=a, q=q, omega=om, alpha=al)
    tau = 30.0 + 5.0 * np.sin(np.outer(t, np.arange(1, 7)))
    return robot, SimpleNamespace(motion_tension=mt, tension_t=t, tension_true=tau,
                                  robot_true=robot)


def test_length_rates_match_finite_differences_and_currents_round_trip(tmp_path):
    robot, sim = _sim()
    m = robot.n_cables
    truth = DriveParameters(np.full(m, 20.0), np.full(m, 2.0), np.full(m, 5.0),
                            np.full(m, 4.0), np.full(m, 1.0))
    nominal = [{"drum_radius": 0.05, "gear_ratio": 10.0, "torque_constant": 0.1,
                "torque_constant_tolerance": 0.1}] * m
    d = simulate_drives(sim, truth, nominal, noise_A=0.0, noise_m=0.0)
    # the paid-out length's rate against a finite difference of the plant's cable lengths
    mt = sim.motion_tension
    R = jax.vmap(quat_to_matrix)(np.asarray(mt.q))
    L = np.asarray(jax.jit(jax.vmap(cable_lengths, in_axes=(None, 0, 0)))(
        sim.robot_true, np.asarray(mt.p), R))
    np.testing.assert_allclose(d.lengths, L, atol=1e-12)
    dt = 1.0 / 100.0
    fd = (L[:-4] - 8 * L[1:-3] + 8 * L[3:-1] - L[4:]) / (12 * dt)  # 5-point stencils
    from cdprid.simulation import length_derivatives

    _, L1, L2 = length_derivatives(sim.robot_true, np.asarray(mt.p), np.asarray(mt.v),
                                   np.asarray(mt.a), R, np.asarray(mt.omega),
                                   np.asarray(mt.alpha))
    np.testing.assert_allclose(L1[2:-2], fd, atol=1e-5)
    fd2 = (-L[:-4] + 16 * L[1:-3] - 30 * L[2:-2] + 16 * L[3:-1] - L[4:]) / (12 * dt ** 2)
    np.testing.assert_allclose(L2[2:-2], fd2, atol=1e-3)
    # current: the drum balance solved for i (positive pulls), offset c / k added
    tau = np.asarray(sim.tension_true)
    i = (tau - 2.0 * L2 - 5.0 * L1 - 4.0 * np.sign(L1)) / 20.0 + 1.0 / 20.0
    np.testing.assert_allclose(d.current, i, atol=1e-12)
    assert d.truth.k[0] == 20.0 and d.nominal[0]["drum_radius"] == 0.05
