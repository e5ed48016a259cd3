"""The scan's null model takes what persists in a real recording's load cells (issue 38): a
zero that drifts slowly over the recording and relative gains between the cells. Neither
raises an episode, and a push on top of them is still located. The recordings come from the
numpy simulator of ``test_persistent_null.py`` (a 12 kg point mass on four cables, friction
on every pulley, a hysteretic cell, white + AR(1) noise)."""

from __future__ import annotations

import numpy as np
import pytest
from tests.episodes.test_persistent_null import DURATION, PUSH, _episodes


def _drift(t):
    """The cells' zeros drift smoothly by 2.5 N (cell 1, a half cosine over the recording)
    and 2 N (cell 4, a full sine): what temperature and creep do to strain gauges."""
    z = np.zeros((len(t), 4))
    z[:, 0] = 2.5 * (0.5 - 0.5 * np.cos(np.pi * t / DURATION))
    z[:, 3] = 2.0 * np.sin(2 * np.pi * t / DURATION)
    return z


GAIN = np.array([1.0, 1.07, 1.0, 0.95])  # cells 2 and 4 read 7 % high, 5 % low


def _check_push(found):
    assert len(found) == 1, [e.describe() for e in found]
    e, (a, b, f) = found[0], PUSH
    assert e.kind == "external_wrench" and e.p_value < 1e-6
    assert abs(e.start_s - a) < 0.25 and abs(e.end_s - b) < 0.25
    assert e.size_N == pytest.approx(np.linalg.norm(f), rel=0.25)


def test_a_drifting_zero_gives_no_episode_and_a_push_on_it_is_located():
    clean = _episodes(None, zero=_drift)
    assert clean == (), [e.describe() for e in clean]
    _check_push(_episodes(PUSH, zero=_drift))


def test_relative_gains_give_no_episode_and_a_push_on_them_is_located():
    clean = _episodes(None, gain=GAIN)
    assert clean == (), [e.describe() for e in clean]
    _check_push(_episodes(PUSH, gain=GAIN))


def test_noise_free_gains_and_drift_are_recovered():
    """Noise-free, no friction or hysteresis: the fit of the null model recovers the relative
    gains (``1 - g_mean / g_j`` with ``g_mean`` the harmonic mean, the common scale going to
    the mass) and the wrench of the zeros (offset and drift; per cell they are known only up
    to the cables' internal force)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from tests.episodes.test_persistent_null import EXITS, MASS, G, _recording

    from cdprid.core import segment_mask
    from cdprid.episodes import _null, _stage
    from cdprid.io import Dataset, align
    from cdprid.model import robot_from_dict

    robot = robot_from_dict({"name": "null-four", "gravity": G.tolist(),
                             "cable": [{"exit": e.tolist(), "anchor": [0.0, 0.0, 0.0]}
                                       for e in EXITS]})
    def cubic(t):  # a drift inside the basis (degree 3 over 30 s), for an exact oracle
        x = 2.0 * t / DURATION - 1.0
        z = np.zeros((len(t), 4))
        z[:, 0], z[:, 3] = 2.5 * x ** 2, 2.0 * (x ** 3 - x)
        return z

    t, pos, tension = _recording(None, zero=cubic, gain=GAIN, noise=False, effects=False)
    sig = align(Dataset(None, robot, t, pos, None, t, tension))
    y, A, _, _, _, c = _stage._data(robot, sig, 4.0)
    rows = np.std(y, 0) > 1e-9 * np.std(y, 0).max()
    y, A = y[:, rows], A[:, rows]
    use = segment_mask(sig.t, sig.segments, 1.0)
    Z = np.concatenate([A, _null.columns(c)[:, rows]], axis=2)
    r, beta = _stage._fit(y, Z, use, np.eye(y.shape[1]))
    m, p, K = 4, A.shape[2], c.drift.shape[1]
    g_mean = 4.0 / np.sum(1.0 / GAIN)
    assert beta[0] == pytest.approx(g_mean * MASS, rel=1e-3)
    gam = beta[p + 3 * m + 1:p + 4 * m]
    np.testing.assert_allclose(gam, (1.0 - g_mean / GAIN)[:3], atol=2e-3)
    drift = c.drift @ beta[p + 4 * m:p + 4 * m + m * K].reshape(m, K).T + beta[p:p + m]
    truth = cubic(np.asarray(sig.t)) * (g_mean / GAIN)  # read through the gains' scale
    # per cell only up to the cables' internal force (W's null space): compare wrenches
    err = np.einsum("nim,nm->ni", np.asarray(c.W)[:, rows], drift - truth)[use]
    # the motion is differentiated (euler-filtfilt): 0.05 N is 2 % of the drift, 1e-3 of m g
    assert c.drift.shape[1] == 3 and np.max(np.abs(err)) < 0.05, np.abs(err).max(0)
