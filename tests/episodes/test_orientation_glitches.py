"""Marker glitches that turn the platform (issue 38): a sample whose orientation jumps by a few
degrees while its position stays is a pose glitch too; a fast smooth rotation is not."""

from __future__ import annotations

import numpy as np


def _rotvec_quat(r):
    ang = np.linalg.norm(r, axis=1)
    s = np.where(ang > 1e-12, np.sin(ang / 2) / np.where(ang > 1e-12, ang, 1.0), 0.5)
    return np.column_stack([np.cos(ang / 2), r * s[:, None]])


def _qmul(a, b):
    aw, av, bw, bv = a[:, :1], a[:, 1:], b[:, :1], b[:, 1:]
    return np.concatenate([aw * bw - np.sum(av * bv, 1, keepdims=True),
                           aw * bv + bw * av + np.cross(av, bv)], 1)


def _swinging(rng, t):
    """A platform on a 1 m/s circle turning up to 25 deg at 0.5-0.8 Hz about a moving axis,
    with 0.2 mm / 0.2 mrad noise (quaternions from rotation vectors: exact, no integration)."""
    w = 2 * np.pi * 0.4
    x = np.column_stack([0.4 * np.cos(w * t), 0.4 * np.sin(w * t), 0.1 * np.sin(3 * w * t)])
    rv = np.column_stack([0.3 * np.sin(2 * np.pi * 0.5 * t), 0.2 * np.sin(2 * np.pi * 0.8 * t),
                          0.25 * np.cos(2 * np.pi * 0.6 * t)])
    q = _qmul(_rotvec_quat(2e-4 * rng.normal(size=(len(t), 3))), _rotvec_quat(rv))
    return x + 2e-4 * rng.normal(size=x.shape), q


def test_orientation_only_glitches_are_found_and_smooth_rotation_is_not():
    from cdprid.episodes import find_glitches

    rng = np.random.default_rng(5)
    t = np.arange(0.0, 20.0, 0.01)
    x, q = _swinging(rng, t)
    assert not find_glitches(x, None, q)[0].any()  # 25 deg at up to 0.8 Hz: no glitch
    idx = [300, 301, 755, 1110, 1111, 1112, 1640]
    turn = {300: [0.035, 0, 0], 301: [0.035, 0, 0], 755: [0, -0.05, 0.02],
            1110: [0.0, 0.0, 0.04], 1111: [0.0, 0.0, 0.04], 1112: [0.0, 0.0, 0.04],
            1640: [0.03, 0.03, 0.0]}  # 2-3 deg, positions untouched
    qg = q.copy()
    for i, r in turn.items():
        qg[i] = _qmul(_rotvec_quat(np.asarray([r], float)), q[i:i + 1])[0]
    assert not find_glitches(x)[0].any()  # the positions alone hold nothing
    g, size = find_glitches(x, None, qg)
    assert np.flatnonzero(g).tolist() == idx
    # a point 25 cm from P moves by about the lever times the angle (8.7-13.5 mm here)
    assert np.all((size[g] > 0.006) & (size[g] < 0.02))
