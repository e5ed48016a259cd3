"""The wrench scan's null model holds the load-cell effects that persist over the whole
recording (issue 38): Coulomb friction on every pulley and a hysteretic cell leave a step at
every reversal of a cable's velocity or tension, which a rigid body alone takes for local
events; a push stays local and is still located.

The recordings come from a simulator written here (numpy only): a 12 kg point mass hanging
from four cables on a prescribed multi-sine path, tensions the least change from 40 N that
balance Newton's law (a push taken by the cables), cells on the winch side of the pulleys
(they read the platform side's tension minus the friction that opposes the sliding,
``tau - c sign(dl/dt)``), one cell hysteretic (a play operator written as a plain loop), a
zero offset, white + AR(1) tension noise and 0.2 mm marker noise.
"""

from __future__ import annotations

import numpy as np
import pytest

EXITS = np.array([[1.6, 1.4, 2.6], [-1.6, 1.4, 2.6], [-1.6, -1.4, 2.6], [1.6, -1.4, 2.6]])
MASS, G = 12.0, np.array([0.0, 0.0, -9.81])
DT, DURATION = 0.01, 30.0
#: Coulomb friction on every pulley, N; the hysteretic cell's width, N (issue 38's case)
COULOMB_N, HYSTERESIS_N = 1.9, 3.8
PUSH = (14.0, 15.0, np.array([6.0, -8.0, 0.0]))  # start, end (s), force (N): 10 N for 1 s


def _play(x, width):
    """Play operator: the reading holds while ``|x - y| <= width / 2``, else follows x at the
    band's edge."""
    y = np.empty_like(x)
    y[0] = x[0] - width / 2
    for k in range(1, len(x)):
        y[k] = min(max(y[k - 1], x[k] - width / 2), x[k] + width / 2)
    return y


def _push_force(t, push):
    """The push's force (n, 3), cosine ramps of 0.1 s at both ends."""
    if push is None:
        return np.zeros((len(t), 3))
    a, b, f = push
    ramp = np.clip(np.minimum(t - a, b - t) / 0.1, 0.0, 1.0)
    return (0.5 - 0.5 * np.cos(np.pi * ramp))[:, None] * f


def _recording(push=None, seed=0, zero=None, gain=None, noise=True, effects=True):
    """``(t, positions, readings)``; ``zero(t)`` (n, 4) a drift of the cells' zeros, N, and
    ``gain`` (4,) their gains, when given; ``noise``: marker and tension noise;
    ``effects``: friction, hysteresis and the offset."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, DURATION, DT)
    amp = np.array([[0.35, 0.30, 0.12], [0.12, 0.10, 0.05]])
    freq = np.array([[0.37, 0.29, 0.23], [0.83, 0.71, 0.61]])
    ph = rng.uniform(0, 2 * np.pi, (2, 3))
    p = np.array([0.0, 0.0, 1.0]) + sum(amp[i] * np.sin(2 * np.pi * freq[i] * t[:, None] + ph[i])
                                        for i in range(2))
    v = sum(amp[i] * 2 * np.pi * freq[i] * np.cos(2 * np.pi * freq[i] * t[:, None] + ph[i])
            for i in range(2))
    a = sum(-amp[i] * (2 * np.pi * freq[i]) ** 2
            * np.sin(2 * np.pi * freq[i] * t[:, None] + ph[i]) for i in range(2))
    d = EXITS[None] - p[:, None]
    u = d / np.linalg.norm(d, axis=2, keepdims=True)  # (n, 4, 3) towards the exits
    Wt = np.transpose(u, (0, 2, 1))  # (n, 3, 4): sum_j tau_j u_j
    w = MASS * (a - G) - _push_force(t, push)
    ref = np.full(4, 40.0)
    tau = ref + np.einsum("nmi,ni->nm", np.linalg.pinv(Wt), w - Wt @ ref)
    assert np.allclose(np.einsum("nim,nm->ni", Wt, tau), w) and tau.min() > 10.0
    ldot = -np.einsum("nmi,ni->nm", u, v)  # paying out: the length from the exit grows
    x = tau - COULOMB_N * np.sign(ldot) if effects else tau.copy()
    if effects:
        x[:, 2] = _play(x[:, 2], HYSTERESIS_N)
    ar = np.zeros_like(x)
    for k in range(1, len(t)):
        ar[k] = 0.9 * ar[k - 1] + 0.3 * np.sqrt(1 - 0.81) * rng.normal(size=4)
    if gain is not None:
        x = x * np.asarray(gain, float)
    if zero is not None:
        x = x + zero(t)
    if not noise:
        return t, p, x
    reading = x + np.array([0.0, 3.0, 0.0, 0.0]) + 0.4 * rng.normal(size=x.shape) + ar
    return t, p + 2e-4 * rng.normal(size=p.shape), reading


def _episodes(push, **kw):
    from cdprid.episodes import find_episodes
    from cdprid.io import Dataset, align
    from cdprid.model import robot_from_dict

    robot = robot_from_dict({"name": "null-four", "gravity": G.tolist(),
                             "cable": [{"exit": e.tolist(), "anchor": [0.0, 0.0, 0.0]}
                                       for e in EXITS]})
    t, pos, tension = _recording(push, **kw)
    ds = Dataset(None, robot, t, pos, None, t, tension)
    return find_episodes(robot, align(ds)).episodes


def test_friction_and_hysteresis_give_no_episode_and_a_push_is_located():
    """Friction on every pulley and a hysteretic cell: no episode on the clean recording; the
    10 N push of 1 s added to the same recording is one external_wrench episode, its edges
    within 0.25 s and its force within 25 % and 15 degrees."""
    clean = _episodes(None)
    assert clean == (), [e.describe() for e in clean]
    found = _episodes(PUSH)
    assert len(found) == 1, [e.describe() for e in found]
    e, (a, b, f) = found[0], PUSH
    assert e.kind == "external_wrench" and e.p_value < 1e-6
    assert abs(e.start_s - a) < 0.25 and abs(e.end_s - b) < 0.25
    assert e.size_N == pytest.approx(np.linalg.norm(f), rel=0.25)
    assert np.dot(e.force_N, f) / (e.size_N * np.linalg.norm(f)) > np.cos(np.radians(15))
