"""The independent test simulator against cdprid's model: two derivations, one robot.

Swivel-pulley geometry (leave points, wrap, lengths), the wrench matrix, the cable rate
``dl/dt = -W^T [v; omega]`` (a finite difference of the total length in the test simulator),
and Newton-Euler against cdprid's regressor (the full 10-parameter model)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from tests._testbench import Sensors, record, robot
from tests._testbench._geometry import pulley_geometry

from cdprid.model import cable_lengths, regressor_full, robot_from_dict, wrench_matrix


def _rec(name="floor8"):
    rob = robot(name)
    m = rob.m
    s = Sensors(500.0, 0.0, 0.01, 100.0, 0.0, 0.0, 0.0, (0.0,) * m, (1.0,) * m, (0.0,) * m,
                (0.0,) * m, True, (0.0,) * m, 0.0, 0.0)
    return rob, record(rob, s, seed=2, duration_s=3.0, drag_Ns_per_m=0.0, noise=False)


def test_floor_winch_robot_wraps_100_to_130_deg():
    _, rec = _rec()
    assert 100.0 <= rec.wrap_deg.min() and rec.wrap_deg.max() <= 130.0
    assert 0.055 <= robot("floor8").r.min() and robot("floor8").r.max() <= 0.065


def test_geometry_and_cable_rates_agree_with_cdprid():
    from tests._testbench._motion import motion

    rob, rec = _rec()
    cd = robot_from_dict(rob.toml())
    mo = motion(rec.path, rec.tension_t[::50])
    W_cd = np.asarray(jax.vmap(wrench_matrix, (None, 0, 0))(cd, jnp.asarray(mo.p),
                                                            jnp.asarray(mo.R)))
    B = mo.p[:, None, :] + np.einsum("nij,mj->nmi", mo.R, rob.b)
    _, beta, free, u = pulley_geometry(rob.A, rob.k, rob.r, B)
    assert np.allclose(W_cd[:, :3], np.transpose(u, (0, 2, 1)), atol=1e-10)
    L_cd = np.asarray(jax.vmap(cable_lengths, (None, 0, 0))(cd, jnp.asarray(mo.p),
                                                            jnp.asarray(mo.R)))
    assert np.allclose(L_cd, rob.r * beta + free, atol=1e-10)
    ldot_cd = -np.einsum("nim,ni->nm", W_cd, np.concatenate([mo.v, mo.w], 1))
    assert np.allclose(rec.ldot[::50], ldot_cd, atol=1e-6)


def test_newton_euler_agrees_with_cdprids_regressor():
    from tests._testbench._motion import motion, newton_euler

    rob, rec = _rec()
    mo = motion(rec.path, rec.tension_t[::100])
    w = newton_euler(mo, rob.mass, rob.com, rob.inertia_G, rob.gravity)
    ms = rob.mass * rob.com
    IP = rob.inertia_G + rob.mass * (rob.com @ rob.com * np.eye(3) - np.outer(rob.com, rob.com))
    x = np.array([rob.mass, *ms, IP[0, 0], IP[0, 1], IP[0, 2], IP[1, 1], IP[1, 2], IP[2, 2]])
    g = jnp.asarray(rob.gravity)
    Y = np.asarray(jax.vmap(lambda R, a, om, al: regressor_full(R, a, om, al, g))(
        jnp.asarray(mo.R), jnp.asarray(mo.a), jnp.asarray(mo.w), jnp.asarray(mo.al)))
    assert np.allclose(np.einsum("nij,j->ni", Y, x), w, atol=1e-9 * np.abs(w).max())


def test_friction_sign_follows_where_the_cell_sits(rng):
    """A cell on the winch side reads tau - F (F = coulomb sign(dl/dt) + viscous dl/dt, paying
    out dl/dt > 0); at the platform it reads tau. cdprid's sensor chain agrees (its
    pulley_friction is the winch-side cell)."""
    import dataclasses

    from tests._testbench._sensors import cell_reading

    from cdprid.effects import Effect, load_cell_reading

    k, m = 300, 4
    tau = 30 + rng.normal(size=(k, m))
    W = rng.normal(size=(k, 6, m))
    v, om = rng.normal(size=(k, 3)), rng.normal(size=(k, 3))
    ldot = -np.einsum("nim,ni->nm", W, np.concatenate([v, om], 1))
    s = Sensors(500.0, 0.0, 0.0, 100.0, 0.0, 0.0, 0.0, (0.0,) * m, (1.0,) * m, (2.0,) * m,
                (3.0,) * m, True, (0.0,) * m, 0.0, 0.0)
    winch = cell_reading(s, tau, ldot, rng, noise=False)
    assert np.all(winch[ldot > 0] < tau[ldot > 0]) and np.all(winch[ldot < 0] > tau[ldot < 0])
    at_platform = cell_reading(dataclasses.replace(s, cell_at_winch=False), tau, ldot, rng,
                               noise=False)
    assert np.array_equal(at_platform, tau)
    cd = load_cell_reading([Effect("pulley_friction", {"cable": "all", "coulomb_N": 2.0,
                                                       "viscous_Ns_per_m": 3.0})],
                           tau, W, v, om, np.arange(k) * 0.002)
    assert np.allclose(cd, winch, atol=1e-12)


def test_ar1_noise_has_its_stated_std_and_correlation():
    from tests._testbench import ar1_noise

    e = ar1_noise(np.random.default_rng(5), 200_000, 2, 0.4, 0.3, 0.95)
    assert np.allclose(e.std(0), np.hypot(0.4, 0.3), rtol=0.03)
    lag1 = np.mean(e[1:] * e[:-1], 0) / e.var(0)
    assert np.allclose(lag1, 0.95 * 0.09 / 0.25, atol=0.02)
