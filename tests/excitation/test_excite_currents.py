"""``cdprid excite --source currents`` (issue 41): a design for the identification from motor
currents conditions the joint regressor of the platform and every drive.

Oracles: central differences of the cable lengths along the designed trajectory (the length
rates), NumPy's construction of the drive columns (``cdprid.core.drive_columns``) and of the
tensions (a per-sample least-norm solve), and the command's own before/after report.
"""

from __future__ import annotations

import copy
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import cdprid.excitation as ex
from cdprid.core import drive_columns, wrench_matrix_series
from cdprid.excitation._currents import SLIDE_M_S, currents_regressor, length_rates
from cdprid.io import drive_table
from cdprid.model import CRAFT_LIKE, cable_lengths, quat_to_matrix, robot_from_dict

DRIVES = [{"drum_radius": 0.04 + 0.002 * j, "gear_ratio": 10.0, "torque_constant": 0.25,
           "drive_reference": j == 2} for j in range(8)]


@pytest.fixture(scope="module")
def craft():
    return robot_from_dict(CRAFT_LIKE, source="craft")


@pytest.fixture(scope="module")
def fourier(craft):
    prob = ex.make_problem(craft, "fourier", "cond", source="currents",
                           drives=drive_table(DRIVES))
    z = jnp.asarray(prob.family.from_params(ex.initial_design(prob)[0]))
    t = jnp.linspace(2.0, 8.0, 31)
    return prob, z, t


@jax.jit
def _lengths_jit(robot, p, q):
    R = jax.vmap(quat_to_matrix)(q)
    return jax.vmap(lambda pk, Rk: cable_lengths(robot, pk, Rk))(p, R)


def _lengths(robot, states):
    return np.asarray(_lengths_jit(robot, states.p, states.q))


def test_length_rates_are_the_lengths_time_derivatives(fourier, craft):
    prob, z, t = fourier
    ld, ldd = (np.asarray(x) for x in jax.jit(length_rates)(craft, prob.family.states(z, t)))
    h = 1e-4
    L = [_lengths(craft, prob.family.states(z, t + s)) for s in (-h, 0.0, h)]
    np.testing.assert_allclose(ld, (L[2] - L[0]) / (2 * h), rtol=0, atol=1e-7)
    np.testing.assert_allclose(ldd, (L[2] - 2 * L[1] + L[0]) / h**2, rtol=0, atol=2e-5)
    assert np.abs(ldd).max() > 0.05  # the trajectory does move the cables


def test_joint_regressor_is_identifys_design(fourier, craft):
    """[Y, -D] with D from cdprid.core.drive_columns (identify's), the reference's k column
    out; tensions the least-norm ones about the middle of the range (NumPy solve)."""
    prob, z, t = fourier
    st = prob.family.states(z, t)
    Z = np.asarray(currents_regressor(craft, st, prob.model, prob.nominal.vector(prob.model),
                                      jnp.asarray(prob.drive_k), prob.reference,
                                      prob.limits.tension_min, prob.limits.tension_max))
    R = np.asarray(jax.vmap(quat_to_matrix)(st.q))
    W = wrench_matrix_series(craft, np.asarray(st.p), R)
    Y = np.asarray(ex.stacked_regressor(st, craft.gravity, prob.model)).reshape(len(t), 6, -1)
    w = Y @ np.asarray(prob.nominal.vector(prob.model))
    mid = np.full(8, 0.5 * (prob.limits.tension_min + prob.limits.tension_max))
    tau = np.array([mid + np.linalg.pinv(Wk) @ (wk - Wk @ mid) for Wk, wk in zip(W, w)])
    ld, ldd = (np.asarray(x) for x in length_rates(craft, st))
    D = drive_columns(W, tau / np.asarray(prob.drive_k), ld, ldd, np.tanh(ld / SLIDE_M_S))
    assert prob.reference == 2  # the drive marked drive_reference
    D = np.delete(D, prob.reference, axis=2)
    want = np.concatenate([Y, -D], axis=2).reshape(6 * len(t), -1)
    assert Z.shape == want.shape == (6 * len(t), 10 + 5 * 8 - 1)
    np.testing.assert_allclose(Z, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


def test_currents_needs_drive_fields_and_the_conditioning_objective(craft):
    from cdprid.base import InputError

    with pytest.raises(InputError, match="drive fields"):
        ex.make_problem(craft, "orbit", "cond", source="currents")
    with pytest.raises(InputError, match="column-scaled"):
        ex.make_problem(craft, "orbit", "dopt", source="currents", drives=drive_table(DRIVES))


def _robot_with_drives(tmp_path):
    import tomli_w

    d = copy.deepcopy(CRAFT_LIKE)
    for c, f in zip(d["cable"], DRIVES):
        c.update(f)
    path = tmp_path / "robot.toml"
    with open(path, "wb") as fh:
        tomli_w.dump(d, fh)
    return path


def test_cli_currents_without_drive_fields_exit_2(tmp_path, craft_robot_toml, capsys):
    from cdprid.cli import main

    rc = main(["excite", str(craft_robot_toml), "--source", "currents", "--out",
               str(tmp_path / "o"), "--no-dataset"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "drum_radius" in err[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_cli_currents_design_conditions_the_joint_regressor(tmp_path):
    from cdprid.cli import main

    robot = _robot_with_drives(tmp_path)
    rc = main(["excite", str(robot), "--source", "currents", "--family", "fourier",
               "--duration", "20", "--starts", "1", "--out", str(tmp_path / "run"),
               "--json", str(tmp_path / "r.json"), "--no-dataset"])
    assert rc == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["source"] == "currents" and rep["reference_drive"] == 3
    assert rep["optimised"]["certified"] is True
    # the joint regressor: 49 columns, its scaled conditioning lowered by the design
    assert rep["optimised"]["cond_scaled"] < rep["initial"]["cond_scaled"]
