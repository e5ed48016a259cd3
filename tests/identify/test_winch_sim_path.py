"""The independent winch simulator's given-path option (tests/identify/winch_sim.py, issue 41):
a recording along a given trajectory (``cdprid excite``'s trajectory.csv) instead of the
seed's own sum of sines.

Oracles: the analytic sum of sines the samples are taken from, cdprid's own quintic Hermite
interpolation of a trajectory CSV (``cdprid.io.load_trajectory_csv``), central differences,
and the simulator's default recording of the same seed.
"""

from __future__ import annotations

import numpy as np
from tests.identify import winch_sim  # noqa: E402

from cdprid.model import SIX_SUSPENDED  # noqa: E402

SIX = dict(SIX_SUSPENDED, home=[0.0, 0.0, 1.4])
PLATFORM = (6.0, np.array([0.01, -0.005, -0.05]), np.diag([0.06, 0.07, 0.09]))
COLUMNS = ("t,x,y,z,vx,vy,vz,ax,ay,az,qw,qx,qy,qz,wx,wy,wz,alx,aly,alz")


def _samples(seed=11, duration=4.0, rate=100.0):
    """100 Hz samples (t, p, v, a, q, omega, alpha) of the seed's analytic sum of sines."""
    path = winch_sim.Path(np.random.default_rng(seed), SIX["home"], [0.25, 0.25, 0.15], 0.08)
    t = np.arange(0.0, duration + 1e-9, 1.0 / rate)
    p, v, a, R, om, al = winch_sim.rates(path, t, h=1e-3)
    q = np.array([winch_sim._quat(Rk) for Rk in R])
    return path, (t, p, v, a, q, om, al)


def test_recording_follows_the_given_path():
    path, (t, p, v, a, q, om, al) = _samples()
    sp = winch_sim.SampledPath(t, p, v, a, q, om, al)
    sim = winch_sim.simulate(SIX, PLATFORM, seed=3, duration=4.0, noise_pos=0.0,
                             noise_rot=0.0, path=sp)
    tp, pp, qq = sim["pose"]
    np.testing.assert_allclose(tp, t[:-1], rtol=0, atol=1e-12)
    # the poses are the path at the pose times (samples of it: exactly the samples)
    np.testing.assert_allclose(pp, p[:-1], rtol=0, atol=1e-12)
    sign = np.sign(np.sum(qq * q[:-1], axis=1))[:, None]
    np.testing.assert_allclose(sign * qq, q[:-1], rtol=0, atol=1e-9)
    # between the samples: the analytic path it was sampled from
    td = sim["drives"][0]
    np.testing.assert_allclose(sp.p(td), path.p(td), rtol=0, atol=2e-8)
    np.testing.assert_allclose(sp.pdd(td), path.pdd(td), rtol=0, atol=2e-4)
    np.testing.assert_allclose(sp.R(td), path.R(td), rtol=0, atol=2e-8)
    # pdd is the interpolant's own second derivative (central differences, inside segments)
    tm, h = td[3:-3:7] + 1e-3, 1e-4
    d2 = (sp.p(tm + h) - 2 * sp.p(tm) + sp.p(tm - h)) / h**2
    np.testing.assert_allclose(sp.pdd(tm), d2, rtol=0, atol=1e-5)
    # the cable lengths the drives pay out follow the given path, not the seed's own
    own = winch_sim.simulate(SIX, PLATFORM, seed=3, duration=4.0)
    assert np.abs(sim["drives"][2] - own["drives"][2]).max() > 0.05


def test_the_seeds_own_path_given_is_the_default_recording():
    seed = 7
    own = winch_sim.Path(np.random.default_rng(seed), SIX["home"], [0.25, 0.25, 0.15], 0.08)
    a = winch_sim.simulate(SIX, PLATFORM, seed=seed, duration=3.0)
    b = winch_sim.simulate(SIX, PLATFORM, seed=seed, duration=3.0, path=own)
    for key in ("pose", "drives"):
        for x, y in zip(a[key], b[key], strict=True):
            np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a["truth"], b["truth"])  # same drive draws
    np.testing.assert_array_equal(a["tension"], b["tension"])


def test_csv_path_matches_cdprids_interpolation(tmp_path):
    from cdprid.io import load_trajectory_csv

    _, cols = _samples(duration=2.0, rate=50.0)
    f = tmp_path / "trajectory.csv"
    np.savetxt(f, np.column_stack(cols), delimiter=",", header=COLUMNS, comments="",
               fmt="%.17g")
    sp = winch_sim.path_from_csv(f)
    ref = load_trajectory_csv(f).evaluate(np.linspace(0.0, 2.0, 37))
    tt = np.asarray(ref.t)
    np.testing.assert_allclose(sp.p(tt), np.asarray(ref.p), rtol=0, atol=1e-12)
    # cdprid clips time at the ends (its derivatives there are of the clipped position)
    np.testing.assert_allclose(sp.pdd(tt)[1:-1], np.asarray(ref.a)[1:-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sp.pdd(cols[0]), cols[3], rtol=0, atol=1e-9)
    Rq = winch_sim._qmat(np.asarray(ref.q))
    np.testing.assert_allclose(sp.R(tt), Rq, rtol=0, atol=1e-12)
    assert sp.duration == 2.0


def test_repeated_csv_path_plays_the_trajectory_again(tmp_path):
    t = np.arange(0.0, 2.0 + 1e-9, 0.01)
    s = np.sin(np.pi * t / 2.0) ** 4  # at rest at both ends (to the 3rd derivative)
    sd = 2 * np.pi * np.sin(np.pi * t / 2) ** 3 * np.cos(np.pi * t / 2)
    sdd = np.pi**2 * (3 * np.sin(np.pi * t / 2) ** 2 * np.cos(np.pi * t / 2) ** 2
                      - np.sin(np.pi * t / 2) ** 4)
    cols = np.column_stack([t, 0.1 * s, 0 * s, 1.0 + 0 * s, 0.1 * sd, 0 * s, 0 * s,
                            0.1 * sdd, 0 * s, 0 * s])
    f = tmp_path / "trajectory.csv"
    np.savetxt(f, cols, delimiter=",", header="t,x,y,z,vx,vy,vz,ax,ay,az", comments="",
               fmt="%.17g")
    one, three = winch_sim.path_from_csv(f), winch_sim.path_from_csv(f, repeat=3)
    assert three.duration == 6.0
    tt = np.linspace(0.0, 2.0, 41)[1:-1] + 0.003
    for k in range(3):
        np.testing.assert_allclose(three.p(tt + 2.0 * k), one.p(tt), rtol=0, atol=1e-12)
        np.testing.assert_allclose(three.pdd(tt + 2.0 * k), one.pdd(tt), rtol=0, atol=1e-9)
    np.testing.assert_allclose(three.pdd(t), 0.1 * sdd[:, None] * [1, 0, 0], atol=1e-9)
