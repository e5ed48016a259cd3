"""The energy balance with the winches' lengths stream (issue 38): the work the cables carry
away through the winches (tension times reeling rate) is booked, and the stream decides when
the winches are locked."""

from __future__ import annotations

import types

import numpy as np
import pytest

from cdprid.episodes import find_episodes, winch_lengths
from cdprid.episodes._energy import outside_work, winch_power


def _lift(push_N: float):
    """A 12 kg mass hanging on one vertical cable, reeled in along z(t) = 0.2 (1 - cos(w t))
    while a hand pushes it up with ``push_N`` from 0.5 to 2 s (it rises then): written here
    from Newton's law, tau = m (g + z'') - push. Returns t, E, tension, reeled length, the
    push's work (J)."""
    m, g, w, dt = 12.0, 9.81, 1.3, 1e-3
    t = np.arange(0.0, 6.0, dt)
    z, zd, zdd = 0.2 * (1 - np.cos(w * t)), 0.2 * w * np.sin(w * t), 0.2 * w * w * np.cos(w * t)
    push = np.where((t >= 0.5) & (t < 2.0), push_N, 0.0)
    tau = m * (g + zdd) - push
    length = 2.0 - z  # the cable shortens as the mass rises
    E = 0.5 * m * zd ** 2 + m * g * z
    work = np.concatenate([[0.0], np.cumsum(0.5 * (push * zd)[1:] + 0.5 * (push * zd)[:-1])
                           * dt])
    return t, E, tau[:, None], length[:, None], work, dt


def test_the_winch_work_balances_a_reeled_lift():
    t, E, tau, length, _, dt = _lift(0.0)
    assert E[-1] - E[0] > 5.0  # lifted: the energy rises, yet nobody outside did work
    out = outside_work(E, winch_power(tau, length, dt), dt)
    assert np.max(np.abs(out)) < 1e-3 * (E.max() - E.min())


def test_the_outside_work_is_the_push_work():
    t, E, tau, length, work, dt = _lift(15.0)
    out = outside_work(E, winch_power(tau, length, dt), dt)
    assert work[-1] > 1.0
    assert np.max(np.abs(out - work)) < 1e-3 * work[-1]


def _ds(extra, n_cables=2):
    return types.SimpleNamespace(robot=types.SimpleNamespace(n_cables=n_cables), extra=extra)


def test_winch_lengths_reads_the_streams_and_never_extrapolates():
    tl = np.linspace(0.0, 10.0, 101)
    vals = np.column_stack([tl, 1.0 + 0.01 * tl, 2.0 - 0.02 * tl])
    t = np.array([0.5, 5.05, 9.0])
    got = winch_lengths(_ds({"lengths": (["t", "l_1", "l_2"], vals)}), t)
    assert got == pytest.approx(np.column_stack([1.0 + 0.01 * t, 2.0 - 0.02 * t]), abs=1e-12)
    got = winch_lengths(_ds({"cable_length": (["t", "dl_1", "dl_2"], vals)}), t)
    assert got is not None and got.shape == (3, 2)
    assert winch_lengths(_ds({"lengths": (["t", "l_1", "l_2"], vals)}), t + 2.0) is None
    assert winch_lengths(_ds({"lengths": (["t", "l_1"], vals[:, :2])}), t) is None
    assert winch_lengths(_ds({}), t) is None


def test_the_lengths_stream_decides_whether_the_winches_are_locked():
    """A simulated recording whose winches move (the 'rich' trajectory): with its own
    lengths stream the energy test does not run (no energy episode); told that the winches
    held still (a constant stream), the platform's energy then rises and falls with nobody
    booking the winches' work, and the test does run and reports outside work. Without a
    stream, the geometric lengths (decimetres of travel) keep it off."""
    from tests.episodes.test_episodes import _signals, _sim

    sim = _sim(4, duration=16.0)
    ds, sig = _signals(sim)
    true = _geometric(sim.robot, sig)
    assert np.ptp(true, axis=0).min() > 0.05  # the winches move
    kinds = {}
    for name, lengths in (("none", None), ("true", true),
                          ("locked", np.broadcast_to(true[:1], true.shape).copy())):
        eps = find_episodes(sim.robot, sig, lengths=lengths)
        kinds[name] = [e.kind for e in eps.episodes]
    assert "energy" not in kinds["none"] and "energy" not in kinds["true"]
    assert "energy" in kinds["locked"]
    with pytest.raises(ValueError, match="lengths"):
        find_episodes(sim.robot, sig, lengths=true[:, :2])


def _geometric(robot, sig):
    """The cables' geometric lengths at the pose times (numpy: exit to attachment)."""
    from scipy.spatial.transform import Rotation

    n = len(sig.t)
    q = sig.quaternion if sig.quaternion is not None else np.tile([1.0, 0, 0, 0], (n, 1))
    R = Rotation.from_quat(np.asarray(q, float)[:, [1, 2, 3, 0]]).as_matrix()
    a, b = np.asarray(robot.B_A), np.asarray(robot.P_b)
    return np.linalg.norm(a[None] - np.asarray(sig.position)[:, None]
                          - np.einsum("nij,mj->nmi", R, b), axis=2)


def test_the_study_measures_coverage_of_a_push_interval():
    """studies/real_uacdpr_episodes.py's acceptance figure: the share of a push interval the
    union of the episodes covers."""
    from studies.real_uacdpr_episodes import coverage

    eps = [{"start_s": 5.42, "end_s": 9.13}, {"start_s": 4.0, "end_s": 5.0}]
    assert coverage(eps, 4.9, 8.6) == pytest.approx((8.6 - 5.42 + 0.1) / 3.7, abs=2e-3)
    assert coverage([], 4.9, 8.6) == 0.0
    assert coverage([{"start_s": 0.0, "end_s": 40.0}], 12.0, 15.2) == 1.0



def _pendulum(brake: float, coulomb: float = 0.0):
    """An independent pendulum (RK4, 1.5 m, 10 kg, swinging from 0.4 rad), viscous damping
    0.05 1/s and a pivot friction ``coulomb`` (N at the bob); a hand opposing the motion with
    ``brake`` (N at the bob) over 20-22 s. ``(t, energy J, bob speed m/s)`` as measured
    (angle noise 0.1 mrad, differentiated)."""
    import math

    dt, ell, g, c, m = 0.01, 1.5, 9.81, 0.05, 10.0
    t = np.arange(0.0, 60.0, dt)
    from tests.episodes.pendulum import rk4_swing

    def accel(th, om, tk):
        u = brake if 20.0 <= tk < 22.0 else 0.0
        return (-g / ell * math.sin(th) - c * om
                - (u + coulomb) * np.tanh(om / 1e-3) / (m * ell))
    th = rk4_swing(accel, 0.4, t)[0] + 1e-4 * np.random.default_rng(3).normal(size=t.size)
    om = np.gradient(th, dt)
    return t, 0.5 * m * (ell * om) ** 2 + m * g * ell * (1 - np.cos(th)), np.abs(ell * om)


def test_a_hand_braking_the_swing_is_an_energy_episode_and_passive_losses_are_not():
    """Passive losses (viscous and pivot friction) are fitted and give no episode, though
    the energy falls all along (the rise test alone is silent, the fall is not tested
    without them); a hand opposing the motion with 1 N over 20-22 s is one stretch of
    negative outside work covering it."""
    from cdprid.episodes._energy import braking_runs, passive_loss

    for coulomb in (0.0, 0.3):
        t, E, v = _pendulum(0.0, coulomb)
        use, none = np.ones(t.size, bool), np.zeros(t.size, bool)
        assert braking_runs(t, E, v, use, none, 0.5) == []
        lost, coef = passive_loss(t, E, v, use)
        assert np.all(coef >= 0) and lost[-1] > 0.5 * (E[0] - E[-1])
        t, E, v = _pendulum(1.0, coulomb)
        found = braking_runs(t, E, v, use, none, 0.5)
        assert len(found) == 1, found
        a, b, work, p = found[0]
        assert t[a] < 20.5 and t[b - 1] > 21.5 and work < -0.5 and p < 1e-6
