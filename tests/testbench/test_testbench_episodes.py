"""The test simulator's pushes and marker glitches (issue 38): what they do to the streams.

A push enters the Newton-Euler: the cables' wrench (true geometry, platform-side tensions)
drops by exactly the push's wrench, nothing else changes; a glitch moves exactly its samples
by its displacement and rotation; the truth reaches meta.toml."""

from __future__ import annotations

import numpy as np
from tests._testbench import Glitch, Push, Sensors, push_wrench, record, robot
from tests._testbench._geometry import pulley_geometry
from tests._testbench._motion import motion


def _sensors(m):
    return Sensors(500.0, 0.0, 0.01, 100.0, 0.0, 0.0, 0.0, (0.0,) * m, (1.0,) * m, (0.0,) * m,
                   (0.0,) * m, True, (0.0,) * m, 0.0, 0.0)


PUSH = Push(1.0, 2.2, (12.0, -20.0, 5.0), (1.5, -0.5, 3.0), 0.25)
GLITCHES = (Glitch(0.7, 2, (0.04, -0.01, 0.02), (0.0, 0.05, 0.03)),
            Glitch(2.5, 1, (-0.03, 0.0, 0.0), (0.0, 0.0, 0.0)))


def _pair():
    rob = robot("floor8")
    s = _sensors(rob.m)
    clean = record(rob, s, seed=3, duration_s=3.0, noise=False)
    hit = record(rob, s, seed=3, duration_s=3.0, noise=False, path=clean.path,
                 pushes=(PUSH,), glitches=GLITCHES)
    return rob, clean, hit


def test_push_profile_ramps_smoothly_between_its_edges():
    t = np.linspace(0.0, 3.0, 3001)
    s = PUSH.profile(t)
    assert np.all(s[(t <= PUSH.start_s) | (t >= PUSH.end_s)] == 0.0)
    assert np.allclose(s[(t >= PUSH.start_s + PUSH.ramp_s) & (t <= PUSH.end_s - PUSH.ramp_s)],
                       1.0)
    assert np.max(np.abs(np.diff(s))) < 1.01 * np.pi / 2 * (t[1] - t[0]) / PUSH.ramp_s


def test_push_takes_its_wrench_off_the_cables():
    rob, clean, hit = _pair()
    mo = motion(clean.path, clean.tension_t)
    B = mo.p[:, None, :] + np.einsum("nij,mj->nmi", mo.R, rob.b)
    _, _, _, u = pulley_geometry(rob.A, rob.k, rob.r, B)
    W = np.concatenate([np.transpose(u, (0, 2, 1)),
                        np.transpose(np.cross(B - mo.p[:, None, :], u), (0, 2, 1))], axis=1)

    def wrench(rec):
        return np.einsum("nim,nm->ni", W, rec.tau_platform)

    d = wrench(hit) - wrench(clean)
    assert np.allclose(d, -push_wrench((PUSH,), clean.tension_t), atol=1e-8)
    inside = (clean.tension_t > PUSH.start_s + PUSH.ramp_s) & (
        clean.tension_t < PUSH.end_s - PUSH.ramp_s)
    assert np.allclose(d[inside, :3], -np.asarray(PUSH.force_N), atol=1e-8)
    assert np.array_equal(hit.ldot, clean.ldot)  # the path is prescribed: the motion is the same


def test_glitches_move_exactly_their_samples():
    _, clean, hit = _pair()
    moved = np.flatnonzero(np.any(hit.position != clean.position, axis=1))
    assert moved.tolist() == [70, 71, 250]
    assert np.allclose(hit.position[70] - clean.position[70], GLITCHES[0].displacement_m)
    # the rotation between the two quaternions is the glitch's (0.058 rad) on samples 70, 71
    for i, ang in ((70, np.linalg.norm(GLITCHES[0].rotation_rad)), (250, 0.0), (69, 0.0)):
        c = abs(float(np.dot(hit.quaternion[i], clean.quaternion[i])))
        assert abs(2 * np.arccos(min(1.0, c)) - ang) < 1e-6


def test_truth_reaches_meta_toml(tmp_path):
    import tomllib
    from tests._testbench import write

    _, _, hit = _pair()
    write(hit, tmp_path / "d")
    eps = tomllib.loads((tmp_path / "d" / "meta.toml").read_text())["truth"]["episodes"]
    assert [e["kind"] for e in eps] == ["external_wrench", "pose_glitches", "pose_glitches"]
    assert eps[0]["start_s"] == PUSH.start_s and eps[0]["end_s"] == PUSH.end_s
    assert abs(eps[0]["size_N"] - np.linalg.norm(PUSH.force_N)) < 1e-12
    assert eps[1]["n_samples"] == 2 and abs(eps[2]["size_m"] - 0.03) < 1e-12
