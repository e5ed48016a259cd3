"""identify --source free-motion (issue 41): the dynamics on the free directions of locked
cables, homogeneous, the mass as reference."""

from __future__ import annotations

import os

import numpy as np
import pytest
from tests.identify import winch_sim  # noqa: E402

from cdprid.base import InputError  # noqa: E402
from cdprid.identify._free_motion import free_directions, projected_regressor  # noqa: E402
from cdprid.identify._scale import choose_reference, scaled_estimate  # noqa: E402
from cdprid.model import FOUR_POINT, regressor_full, robot_from_dict  # noqa: E402

A = np.array([[1.1, -1.2, 1.8], [1.1, 1.2, 1.8], [-1.1, 1.2, 1.8], [-1.1, -1.2, 1.8]])
B = np.array([[0.08, -0.08, 0.27], [0.08, 0.08, 0.27], [-0.08, 0.08, 0.27],
              [-0.08, -0.08, 0.27]])
MASS, SG, IG = 12.0, np.array([0.004, -0.003, 0.17]), np.diag([0.18, 0.12, 0.19])


def _consistent_samples(n=300, seed=0):
    """Poses, rates and accelerations for which W tau = Z x with positive tensions: the
    accelerations solved from random tensions through the independent Newton-Euler."""
    rng = np.random.default_rng(seed)
    p = rng.normal(0, 0.1, (n, 3)) + [0, 0, 0.6]
    R = np.array([winch_sim._expm(v) for v in rng.normal(0, 0.1, (n, 3))])
    om = rng.normal(0, 0.5, (n, 3))
    W = winch_sim.wrench_matrix(A, B, p, R)
    tau = rng.uniform(10, 60, (n, 4))
    w = np.einsum("nam,nm->na", W, tau)
    z = np.zeros((n, 3))
    bias = winch_sim.wrench(MASS, SG, IG, p, z, R, om, z)
    acc = np.empty((n, 6))
    for k in range(n):  # the wrench is affine in (a, alpha): its 6 x 6 matrix column by column
        M = np.empty((6, 6))
        for j in range(6):
            e = np.zeros(6)
            e[j] = 1.0
            M[:, j] = winch_sim.wrench(MASS, SG, IG, p[k:k + 1], e[None, :3], R[k:k + 1],
                                       om[k:k + 1], e[None, 3:])[0] - bias[k]
        acc[k] = np.linalg.solve(M, w[k] - bias[k])
    return p, R, om, acc[:, :3], acc[:, 3:], W


def test_free_directions_annihilate_the_cable_wrenches():
    rng = np.random.default_rng(1)
    W = rng.normal(size=(5, 6, 4))
    N = free_directions(W, 0.3)
    S = np.array([1.0] * 3 + [1 / 0.3] * 3)
    np.testing.assert_allclose(np.einsum("nai,a,nam->nim", N, S, W), 0, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nai,naj->nij", N, N), np.broadcast_to(np.eye(2),
                                                                               (5, 2, 2)),
                               atol=1e-12)


def test_projected_equations_give_the_truth_up_to_the_mass():
    p, R, om, a, al, W = _consistent_samples()
    import jax

    Z = np.asarray(jax.vmap(regressor_full, in_axes=(0, 0, 0, 0, None))(
        R, a, om, al, np.array([0.0, 0.0, -9.81])))
    P = projected_regressor(Z, W, 0.3).reshape(-1, 10)
    IP = IG + MASS * (SG @ SG * np.eye(3) - np.outer(SG, SG))
    x = np.array([MASS, *(MASS * SG), IP[0, 0], IP[0, 1], IP[0, 2], IP[1, 1], IP[1, 2],
                  IP[2, 2]])
    assert np.max(np.abs(P @ x)) < 1e-9 * np.max(np.abs(P))  # independent Newton-Euler
    phi = np.linalg.lstsq(P[:, 1:], -P[:, 0], rcond=None)[0]
    robot = robot_from_dict(dict(FOUR_POINT, platform={"mass": MASS, "mass_uncertainty": 0.0}))
    ref = choose_reference(None, robot, None, allow_drive=False)
    theta, cov = scaled_estimate(phi, np.zeros((9, 9)), ref, 0)
    np.testing.assert_allclose(theta, x, rtol=1e-7, atol=1e-9)


def test_free_motion_needs_few_cables_and_a_mass():
    from cdprid.identify import identify_free_motion
    from cdprid.model import SIX_SUSPENDED

    class Fake:
        robot = robot_from_dict(SIX_SUSPENDED)

    with pytest.raises(InputError, match="fewer than 6 cables"):
        identify_free_motion(Fake())
    Fake.robot = robot_from_dict({k: v for k, v in FOUR_POINT.items() if k != "platform"})
    with pytest.raises(InputError, match="no scale reference"):
        identify_free_motion(Fake())


@pytest.mark.slow
def test_uacdpr_free_motion_reports_zG_and_cells(tmp_path):
    """The real UACDPR recording (../shared): z_G from the poses alone, the load cells'
    gains and offsets with intervals. Measured, not asserted at the issue's 10 %: see
    docs/drives.md and results/free-motion-uacdpr.md (0.190-0.200 m against 0.173 m)."""
    from cdprid.identify import identify_free_motion, import_calibrated_uacdpr
    from cdprid.io import read_dataset
    from conftest import shared_dataset

    d = shared_dataset("uacdpr-freemotion02")
    out = import_calibrated_uacdpr(d / "FreeMotion02.txt", d / "FreeMotion02_exp.mat",
                                   d / "UACDPR_LAB3.mat", tmp_path / "u", nuisance=False)
    rep = identify_free_motion(read_dataset(out), reference="mass:12.966:0.05",
                               params={"cutoff_hz": 16.0})
    zG = rep.theta[3] / rep.theta[0]
    assert 0.1 < zG < 0.4 and rep.cells is not None
    assert len(rep.as_json()["load_cells"]) == 4
    print(os.linesep, f"z_G = {zG:.4f} m", rep.cells.table())


@pytest.fixture(scope="module")
def pushed_recording(tmp_path_factory):
    """A 4-cable platform swinging on locked elastic cables (tests/identify/free_sim.py, an
    independent simulator), pushed by hand twice, poses with noise, load cells with known
    gains and offsets."""
    from tests.identify.free_sim import FreePlatform, noisy

    from cdprid.io import write_dataset

    rng = np.random.default_rng(3)
    pushes = [{"start_s": 3.0, "end_s": 5.8, "force_N": [1.5, -1.6, 2.3],
               "moment_Nm": [0.36, 1.3, 0.95]},
              {"start_s": 11.0, "end_s": 13.9, "force_N": [-8.4, -15.2, -2.2],
               "moment_Nm": [-0.22, -1.25, -0.73]},
              {"start_s": 19.4, "end_s": 21.0, "force_N": [-6.5, -3.8, 1.5],
               "moment_Nm": [1.37, -0.67, 0.35]}]
    plant = FreePlatform(A, B, MASS, SG, IG, [0.0, 0.0, 0.6])
    t, P, Q, T = plant.run(28.0, pushes, p_start=[0.0, 0.0, 0.6], om_start=[0.6, -0.8, 0.3])
    Pn, Qn = noisy(P, Q, rng)
    gain, offset = np.array([0.9, 1.1, 1.0, 0.95]), np.array([2.0, -3.0, 0.0, 1.0])
    cells = gain * T + offset + 0.5 * rng.standard_normal(T.shape)
    rd = {"name": "sim4", "cable": [{"exit": a.tolist(), "anchor": b.tolist()}
                                    for a, b in zip(A, B, strict=True)],
          "platform": {"mass": MASS, "mass_uncertainty": 0.0}}
    out = write_dataset(tmp_path_factory.mktemp("free") / "ds", robot_from_dict(rd), t, Pn, t,
                        cells, quaternion=Qn)
    return out, gain, offset


@pytest.mark.slow
def test_pushes_are_left_out_and_the_truth_recovered(pushed_recording):
    """With the pushes kept, z_G is far off; the episodes stage (from the load cells) leaves
    them out and z_G comes back within 3 std of the truth, closer than with them; every load
    cell's gain and offset interval covers its truth. (At higher cutoffs the pose noise in the
    regressor biases z_G beyond its std: the cutoff check warns, docs/drives.md.)"""
    from cdprid.identify import identify_free_motion
    from cdprid.io import read_dataset

    out, gain, offset = pushed_recording
    ds = read_dataset(out)
    kw = dict(reference="mass", params={"cutoff_hz": 4.0}, check_cutoff=False)
    kept = identify_free_motion(ds, keep_episodes=True, **kw)
    zk = kept.theta[3] / kept.theta[0]
    assert abs(zk / SG[2] - 1) > 0.2, zk
    rep = identify_free_motion(ds, **kw)
    zG, s = rep.theta[3] / rep.theta[0], rep.std[3] / rep.theta[0]
    assert rep.episodes and rep.n_samples < kept.n_samples
    assert abs(zG - SG[2]) < 3 * s and abs(zG - SG[2]) < abs(zk - SG[2]), (zG, s, zk)
    c = rep.cells
    assert np.all(np.abs(c.gain - gain) < 1.96 * c.gain_std), (c.gain, c.gain_std)
    assert np.all(np.abs(c.offset - offset) < 1.96 * c.offset_std), (c.offset, c.offset_std)


@pytest.mark.slow
def test_pushes_are_located_without_load_cells(pushed_recording):
    """Poses alone: the free directions' residual scan locates the pushes; z_G within 3 std
    of the truth and within 5 %, and the command says that no load cell helped."""
    import dataclasses

    from cdprid.identify import identify_free_motion
    from cdprid.io import read_dataset

    out, _, _ = pushed_recording
    ds = dataclasses.replace(read_dataset(out), tension=None, tension_t=None)
    rep = identify_free_motion(ds, reference="mass", params={"cutoff_hz": 4.0},
                               check_cutoff=False)
    zG, s = rep.theta[3] / rep.theta[0], rep.std[3] / rep.theta[0]
    assert len(rep.episodes) >= 3 and rep.cells is None
    assert abs(zG - SG[2]) < 3 * s and abs(zG / SG[2] - 1) < 0.05, (zG, s)
    assert any("no load cells" in w for w in rep.warnings)


@pytest.mark.slow
def test_load_cell_intervals_cover_the_truth_monte_carlo(tmp_path):
    """Small Monte Carlo (4 seeds, independent simulator, two pushes each, random gains
    0.85-1.15 and offsets -5..5 N): the cells' 95 % intervals cover the truth in at least 28
    of the 32 gains and offsets (binomial: 30.4 expected; 28 or fewer has probability 0.04
    if the intervals are right).

    History: a strict xfail at 21 of 32, then 29, then 18 of 32 (0, 8, 2, 8) once the
    episodes' scan located both pushes exactly: the cells' std fell to 0.04 and the platform
    estimate sat 3.4-5.8 std off. Two causes, measured apart (benchmarks/free_motion_sim.py
    --mc, results/free-motion-eiv.md): the core's second-order difference stencils (1.3 % of
    a 2 Hz acceleration at 100 Hz: 2-50 std on a noise-free swing; now exact to degree 5,
    24 of 32) and the pose noise inside the regressor (errors in variables; now corrected
    from re-noised poses, 32 of 32). The command says so in a note; the old caveat is gone."""
    from tests.identify.free_sim import FreePlatform, noisy

    from cdprid.identify import identify_free_motion
    from cdprid.io import read_dataset, write_dataset

    rd = {"name": "sim4", "cable": [{"exit": a.tolist(), "anchor": b.tolist()}
                                    for a, b in zip(A, B, strict=True)],
          "platform": {"mass": MASS, "mass_uncertainty": 0.0}}
    covered, total = 0, 0
    for seed in range(4):
        rng = np.random.default_rng(100 + seed)
        pushes = [{"start_s": t0, "end_s": t0 + rng.uniform(1.5, 2.5),
                   "force_N": (rng.normal(0, 10, 3) * [1, 1, 0.3]).tolist(),
                   "moment_Nm": rng.normal(0, 1.0, 3).tolist()} for t0 in (3.0, 11.0)]
        plant = FreePlatform(A, B, MASS, SG, IG, [0.0, 0.0, 0.6])
        t, P, Q, T = plant.run(20.0, pushes, p_start=[0.0, 0.0, 0.6],
                               om_start=rng.normal(0, 0.5, 3))
        Pn, Qn = noisy(P, Q, rng)
        g, o = rng.uniform(0.85, 1.15, 4), rng.uniform(-5, 5, 4)
        out = write_dataset(tmp_path / f"s{seed}", robot_from_dict(rd), t, Pn, t,
                            g * T + o + 0.5 * rng.standard_normal(T.shape), quaternion=Qn)
        rep = identify_free_motion(read_dataset(out), reference="mass",
                                   params={"cutoff_hz": 4.0}, check_cutoff=False)
        c = rep.cells
        covered += int(np.sum(np.abs(c.gain - g) < 1.96 * c.gain_std))
        covered += int(np.sum(np.abs(c.offset - o) < 1.96 * c.offset_std))
        total += 8
        assert any(n.startswith("errors in variables") for n in rep.notes)
        assert not any("pose noise inside the regressor" in w for w in rep.warnings)
    print(f"load-cell intervals covering: {covered} of {total}")
    assert covered >= 28, f"load-cell intervals cover {covered} of {total} (>= 28 wanted)"


def test_cells_wrench_fit_recovers_gains_and_offsets():
    """Noise-free oracle of the wrench-space calibration: readings ``g tau + o`` of tensions
    whose cable wrench is the 'identified' one give back ``g`` and ``o`` to 1e-9; with
    reading noise the 95 % intervals hold them."""
    import types

    from cdprid.identify._cells import calibrate_cells_wrench
    from cdprid.signal import zero_phase_filter

    rng = np.random.default_rng(5)
    n, dt = 1500, 0.01
    t = np.arange(n) * dt
    p = np.stack([0.1 * np.sin(0.9 * t), 0.08 * np.cos(1.3 * t), 0.6 + 0.02 * np.sin(2.1 * t)], 1)
    R = np.array([winch_sim._expm(v) for v in np.stack([0.1 * np.sin(1.1 * t),
                                                        0.08 * np.sin(0.7 * t + 1),
                                                        0.05 * np.sin(1.7 * t)], 1)])
    W = winch_sim.wrench_matrix(A, B, p, R)
    tau = 40 + 10 * np.sin(np.outer(t, [1.0, 1.4, 0.8, 2.0]) + [0, 1, 2, 3])
    g, o = np.array([0.9, 1.1, 1.0, 1.2]), np.array([3.0, -2.0, 0.0, 5.0])

    def wf(y, scale=None):
        return zero_phase_filter(y, dt, 4.0, 2)

    idx = np.arange(100, n - 100)
    wrench = wf(np.einsum("nam,nm->na", W, tau))[idx]  # the regression holds the kept samples
    reg = types.SimpleNamespace(wrench_block=lambda i0, i1: (wrench[i0:i1, :, None],))
    for noise in (0.0, 0.5):
        meas = g * tau + o + noise * rng.standard_normal(tau.shape)
        c = calibrate_cells_wrench(reg, W, types.SimpleNamespace(tension=meas), wf, idx,
                                   np.array([1.0]), np.zeros((1, 1)), 4096, 0.3)
        if noise == 0.0:
            np.testing.assert_allclose(c.gain, g, atol=1e-9)
            np.testing.assert_allclose(c.offset, o, atol=1e-7)
        else:
            assert np.all(np.abs(c.gain - g) < 1.96 * c.gain_std), (c.gain, c.gain_std)
            assert np.all(np.abs(c.offset - o) < 1.96 * c.offset_std)
            assert np.all(c.gain_std < 0.05)


def test_widened_cutoff_is_the_widest_within_the_noise_budget():
    """The free motion's data-chosen cutoff on the 4-16 Hz grid (the core's 1-4 Hz grid on a
    stretched time axis): an independent numpy computation of the predicted attenuation
    (noise over signal power of the second differences through the zero-phase Butterworth)
    is within the 1e-3 budget at the chosen cutoff and above it 1 Hz wider."""
    import types

    from cdprid.identify._free_rows import widen_cutoff

    rng = np.random.default_rng(2)
    dt, n = 0.01, 4000
    t = np.arange(n) * dt
    s = 3e-4
    clean = np.stack([0.05 * np.sin(2 * np.pi * 2.0 * t), 0.02 * np.sin(2 * np.pi * 3.9 * t + 1),
                      0.01 * np.sin(2 * np.pi * 6.0 * t)], 1)
    pos = clean + s * rng.standard_normal(clean.shape)
    sig = types.SimpleNamespace(position=pos, quaternion=None, has_rotation=False, dt=dt, t=t,
                                segments=((0, n),))
    ds = types.SimpleNamespace(tension_t=t, tension=np.ones((n, 4)), quaternion=None)
    notes = ["core note"]
    c = widen_cutoff(ds, sig, {"cutoff_hz": 4.0}, notes)["cutoff_hz"]
    assert 4.0 < c <= 16.0 and "16 Hz" in notes[-1], c

    from cdprid.core import estimate_noise

    sn = float(np.median(estimate_noise(pos)))
    d2 = (pos[2:] - 2 * pos[1:-1] + pos[:-2]) / dt ** 2
    w = np.hanning(len(d2))[:, None]
    f = np.fft.rfftfreq(len(d2), dt)
    spec = np.abs(np.fft.rfft((d2 - d2.mean(0)) * w, axis=0)) ** 2
    psd = 2 * dt * np.sum(spec, 1) / np.sum(w ** 2)
    noise = 2 * dt * sn ** 2 * (4 * np.sin(np.pi * f * dt) ** 2 / dt ** 2) ** 2 * 3

    def ratio(fc):
        G = 1 / (1 + (f / fc) ** 4) ** 2
        return np.sum(noise * G) / np.sum((psd - noise) * G)

    assert ratio(c) <= 1e-3, ratio(c)
    assert c == 16.0 or ratio(c + 1.0) > 1e-3, (c, ratio(c + 1.0))


def test_com_over_thirds_gives_each_thirds_zG():
    """Exact free-motion rows (consistent samples, independent Newton-Euler): each third's
    z_G is the truth to 1e-9, spread 0; rows of a third with an added push make that third's
    z_G differ, and the sentence shows it."""
    import jax

    from cdprid.identify._free_rows import com_over_thirds
    from cdprid.model import PARAMETER_NAMES

    p, R, om, a, al, W = _consistent_samples(n=660, seed=4)
    Z = np.asarray(jax.vmap(regressor_full, in_axes=(0, 0, 0, 0, None))(
        R, a, om, al, np.array([0.0, 0.0, -9.81])))
    P = projected_regressor(Z, W, 0.3)
    names, t, idx = PARAMETER_NAMES["full"], np.arange(660) * 0.01, np.arange(660)
    s = com_over_thirds(P, idx, 0, names, 4096, t)
    zs = [float(x.split(" +-")[0]) for x in s.split(": ")[1:4]]
    np.testing.assert_allclose(zs, SG[2], atol=1e-9)
    assert "spread 0.0000 m" in s
    Zp = Z.copy()
    Zp[440:, :, 0] += [3.0, -2.0, 1.0, 0.2, 0.3, 0.1]  # a push on the last third (N/kg)
    s2 = com_over_thirds(projected_regressor(Zp, W, 0.3), idx, 0, names, 4096, t)
    zs2 = [float(x.split(" +-")[0]) for x in s2.split(": ")[1:4]]
    np.testing.assert_allclose(zs2[:2], SG[2], atol=1e-9)
    assert abs(zs2[2] - SG[2]) > 5e-3, zs2
    assert com_over_thirds(P, idx, 1, names, 4096, t) is None  # reference not the mass


def test_free_sim_brake_dissipates_exactly_its_power():
    """The simulator's hand brake (force -c v_G at G, moment -c_w omega) with undamped elastic
    cables: the platform's energy (kinetic, weight, cable springs) falls by the brake's work
    integral(c |v_G|^2 + c_w |omega|^2) dt, to the integrator's accuracy; without the brake it
    is conserved."""
    from tests.identify.free_sim import FreePlatform, G, _qmat

    plant = FreePlatform(A, B, MASS, SG, IG, [0.0, 0.0, 0.6], c=0.0)

    def energy(y):
        pG, vG, q, om = y[:3], y[3:6], y[6:10], y[10:]
        R = _qmat(q)
        L = np.linalg.norm(plant.A - pG - (R @ (plant.b - plant.sG).T).T, axis=1)
        return (0.5 * MASS * vG @ vG + 0.5 * om @ (R @ IG @ R.T) @ om - MASS * G @ pG
                + 0.5 * plant.k * np.sum(np.maximum(0.0, L - plant.L0) ** 2))

    for brake in ((0.0, 0.0), (15.0, 1.5)):
        y = np.concatenate([[0.02, -0.01, 0.6 + SG[2]], [0.1, 0.2, 0.0], [1.0, 0, 0, 0],
                            [0.6, -0.8, 0.3]])
        e0, work, h = energy(y), 0.0, 2.5e-4
        for _ in range(2000):
            p0 = brake[0] * y[3:6] @ y[3:6] + brake[1] * y[10:] @ y[10:]
            k1 = plant.deriv(y, np.zeros(6), brake)
            k2 = plant.deriv(y + h / 2 * k1, np.zeros(6), brake)
            k3 = plant.deriv(y + h / 2 * k2, np.zeros(6), brake)
            k4 = plant.deriv(y + h * k3, np.zeros(6), brake)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            y[6:10] /= np.linalg.norm(y[6:10])
            work += 0.5 * h * (p0 + brake[0] * y[3:6] @ y[3:6] + brake[1] * y[10:] @ y[10:])
        assert abs(energy(y) - e0 + work) < 1e-3 * max(work, 0.1), (energy(y) - e0, work)
        assert (work > 0.05) == (brake[0] > 0)


def test_free_rates_are_fourth_order():
    """The free motion's stencils (:mod:`cdprid.identify._free_rates`): exact on polynomials
    (second derivative to degree 5, first to degree 4) and, on a rotation about a tilted axis
    at a varying rate, errors that fall 16 times when the sampling period halves (the core's
    stencils: 4 times), against the analytic omega and alpha."""
    import types

    from cdprid.identify._free_rates import first_derivative, free_rates, second_derivative

    t = np.arange(200) * 0.01
    c = np.array([0.3, -1.2, 0.7, 2.0, -0.9, 0.4])
    x = sum(ck * t ** k for k, ck in enumerate(c))[:, None]
    d2 = sum(k * (k - 1) * ck * t ** (k - 2) for k, ck in enumerate(c) if k > 1)
    d1 = sum(k * ck * t ** (k - 1) for k, ck in enumerate(c[:5]) if k > 0)
    np.testing.assert_allclose(second_derivative(x, 0.01)[5:-5, 0], d2[5:-5], rtol=1e-9,
                               atol=1e-8)
    x4 = sum(ck * t ** k for k, ck in enumerate(c[:5]))[:, None]
    np.testing.assert_allclose(first_derivative(x4, 0.01)[2:-2, 0], d1[2:-2], rtol=1e-9,
                               atol=1e-9)
    u = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])

    def errors(dt):
        tt = np.arange(int(round(2.0 / dt))) * dt
        th, thd, thdd = (0.4 * np.sin(2 * np.pi * 2 * tt), 1.6 * np.pi * np.cos(2 * np.pi * 2 * tt),
                         -0.4 * (4 * np.pi) ** 2 * np.sin(2 * np.pi * 2 * tt))
        q = np.concatenate([np.cos(th / 2)[:, None], np.sin(th / 2)[:, None] * u], 1)
        pos = np.stack([0.05 * np.sin(2 * np.pi * 2 * tt)] * 3, 1)
        motion = types.SimpleNamespace(t=tt, position=pos, segments=((0, len(tt)),))
        a, om, al = free_rates(motion, q)
        k = slice(10, -10)
        a_true = -0.05 * (4 * np.pi) ** 2 * np.sin(2 * np.pi * 2 * tt)
        return (np.max(np.abs(a[k, 0] - a_true[k])), np.max(np.abs(om - thd[:, None] * u)[k]),
                np.max(np.abs(al - thdd[:, None] * u)[k]))

    coarse, fine = np.array(errors(0.01)), np.array(errors(0.005))
    assert np.all(coarse / fine > 12.0), coarse / fine
    assert np.all(coarse < [2e-3, 2e-3, 2e-2]), coarse  # 2e-4 of each amplitude


def test_pose_noise_bias_removes_the_attenuation():
    """A homogeneous errors-in-variables problem with a known answer: rows ``[x_n, y_n]`` read
    from noisy positions with ``x = 2 y`` true (``x - 2 y = 0``, ``b = -2``). Least squares
    attenuates ``b`` by ``sum y^2 / (sum y^2 + n sigma^2)`` (analytic, about 10 % here, tens
    of its std); the corrected estimate (:func:`cdprid.identify._free_eiv.pose_noise_bias`)
    is within 3 std of the truth, the bootstrap's first-order std matches the analytic
    ``sigma sqrt((1 + b^2) / sum y^2)`` within 35 % (32 pairs: its own spread is 12 %, and it
    is evaluated at the attenuated estimate), and the noise level is measured."""
    import dataclasses as dc

    from cdprid.identify._free_eiv import pose_noise_bias

    @dc.dataclass(frozen=True)
    class Sig:
        t: np.ndarray
        dt: float
        position: np.ndarray
        quaternion: np.ndarray
        has_rotation: bool = False

    @dc.dataclass(frozen=True)
    class Mo:
        t: np.ndarray
        position: np.ndarray
        B_R_P: np.ndarray
        segments: tuple

    rng = np.random.default_rng(11)
    n, s = 20000, 0.05
    t = np.arange(n) * 0.01
    y = 0.25 * np.sin(2 * np.pi * 0.3 * t) + 0.1 * np.sin(2 * np.pi * 0.71 * t)
    pos = np.stack([2 * y, y, 0 * y], 1) + s * rng.standard_normal((n, 3))
    q = np.tile([1.0, 0, 0, 0], (n, 1))
    sig = Sig(t, 0.01, pos, q)
    motion = Mo(t, pos, np.tile(np.eye(3), (n, 1, 1)), ((0, n),))
    ds = dc.make_dataclass("Ds", ["tension_t", "tension", "quaternion"])(t, np.ones((n, 1)),
                                                                         None)

    def rows(sg, mo):
        return np.asarray(sg.position)[:, None, :2]

    P, idx = rows(sig, motion), np.arange(n)
    ols = -np.sum(P[:, 0, 0] * P[:, 0, 1]) / np.sum(P[:, 0, 1] ** 2)
    pb = pose_noise_bias(ds, sig, motion, rows, idx, 0, P, bandwidth=1.0, pairs=32)
    sd = np.sqrt(s ** 2 * 5 / np.sum(y ** 2))
    assert abs(pb.s_pos / s - 1) < 0.05 and pb.s_rot is None
    assert abs(ols + 2) > 20 * sd, (ols, sd)
    assert abs(ols - pb.bias[0] + 2) < 3 * sd, (ols - pb.bias[0], sd)
    assert abs(np.sqrt(pb.cov_boot[0, 0]) / sd - 1) < 0.35, (np.sqrt(pb.cov_boot[0, 0]), sd)
    assert pb.inflation[0] > 0.5 and np.sqrt(pb.cov_mc[0, 0]) < sd


def test_too_few_free_samples_are_refused_in_one_sentence():
    """When the pushes and trimmed edges leave fewer samples than twice the parameters, the
    fit is refused with an InputError naming the recording (was an UnboundLocalError in the
    core's block factorisation when none were left)."""
    from cdprid.identify._free_motion import _fit
    from cdprid.model import PARAMETER_NAMES

    P = np.random.default_rng(0).normal(size=(40, 2, 10))
    for n in (0, 19):
        with pytest.raises(InputError, match=f"rec: only {n} samples of free motion"):
            _fit(P, np.arange(n), 0, PARAMETER_NAMES["full"], 4096, "rec")
    assert len(_fit(P, np.arange(20), 0, PARAMETER_NAMES["full"], 4096, "rec").x) == 9
