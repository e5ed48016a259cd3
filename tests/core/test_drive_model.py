"""The drive model's signs against an independent winch: an ODE of motor, gear and drum."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from cdprid.core import DriveParameters, drive_columns, drive_tension

# a winch: motor K_t (N m/A), rotor J_m (kg m^2), gear N, drum r (m) and J_d, bearing viscous
# b (N m s) and Coulomb T_c (N m) on the drum, current sensor offset i_0 (A)
KT, JM, N, R, JD, B, TC, I0 = 0.1, 1e-4, 10.0, 0.05, 2e-3, 0.01, 0.05, 0.1


def tension(t):
    """The cable's pull on the drum (N): what the platform side imposes."""
    return 40.0 + 10.0 * np.sin(2.0 * t) + 4.0 * np.sin(7.0 * t + 0.3)


def current(t):
    """The true motor current (A); positive winds the cable in."""
    return 2.0 + 0.5 * np.sin(3.0 * t + 1.0)


def winch(t, y):
    """Drum angle theta (rad, positive paying out) and its rate: torques about the drum axis.
    The cable's tension turns the drum the paying-out way, the motor winds in through the gear,
    friction opposes the drum's rotation."""
    th, w = y
    torque = tension(t) * R - N * KT * current(t) - B * w - TC * np.sign(w)
    return [w, torque / (N * N * JM + JD)]


def test_drive_model_signs_match_a_winch_ode():
    sol = solve_ivp(winch, (0.0, 6.0), [0.0, 0.5], rtol=1e-11, atol=1e-12, dense_output=True,
                    max_step=1e-3)
    t = np.linspace(0.2, 5.8, 400)
    th, w = sol.sol(t)
    wdot = np.array([winch(tk, [a, b])[1] for tk, a, b in zip(t, th, w, strict=True)])
    l_dot, l_ddot = R * w, R * wdot  # paid-out length l = r theta
    assert np.any(l_dot > 0.01) and np.any(l_dot < -0.01)  # pays out and winds in
    ok = np.abs(l_dot) > 1e-6  # the Coulomb sign is defined
    p = DriveParameters(k=np.array([N * KT / R]), J=np.array([(N * N * JM + JD) / R ** 2]),
                        fv=np.array([B / R ** 2]), fc=np.array([TC / R]),
                        c=np.array([N * KT / R * I0]))
    i_read = current(t) + I0  # the drive reports the current with its offset
    tau = drive_tension(p, i_read[:, None], l_dot[:, None], l_ddot[:, None])[:, 0]
    np.testing.assert_allclose(tau[ok], tension(t)[ok], rtol=1e-7, atol=1e-7)
    # a flipped inertia sign would be visible: the check can fail
    flipped = DriveParameters(p.k, -p.J, p.fv, p.fc, p.c)
    bad = drive_tension(flipped, i_read[:, None], l_dot[:, None], l_ddot[:, None])[:, 0]
    assert np.max(np.abs(bad - tension(t))) > 1.0


def test_drive_columns_are_the_linear_form_of_the_model():
    rng = np.random.default_rng(0)
    n, m = 7, 4
    W = rng.normal(size=(n, 6, m))
    cur, ld, ldd = rng.normal(size=(3, n, m))
    s = np.sign(ld)
    p = DriveParameters(*rng.uniform(0.5, 3.0, size=(5, m)))
    D = drive_columns(W, cur, ld, ldd, s)
    lhs = np.einsum("nam,nm->na", W, drive_tension(p, cur, ld, ldd, s))
    np.testing.assert_allclose(D @ p.vector(), lhs, rtol=1e-12, atol=1e-12)
    assert DriveParameters.from_vector(p.vector()).k == pytest.approx(p.k)
