"""Every finding must be stable (issue 37 item 3): estimates on halves of the recording and on
groups of cables agree, or the finding is withdrawn with what it resembled."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cdprid.diagnosis._candidates import Candidate
from cdprid.diagnosis._stability import _resembles, block_test, group_test, sensor_alternatives

N, M = 3000, 8


def _prob():
    return SimpleNamespace(train=np.ones(N, bool), lags=3, wrow=np.ones(6), m=M)


def _columns(rng):
    """Four platform-like columns and per-cable columns of one common effect (n, 6, m, 1)."""
    A = rng.normal(size=(N, 6, 4))
    pc = rng.normal(size=(N, 6, M, 1))
    return A, pc


def test_a_parameter_that_changes_half_way_is_unstable(rng):
    A, pc = _columns(rng)
    col = pc.sum(2)
    Z = np.concatenate([A, col], axis=2)
    beta = np.array([1.0, 2.0, -1.0, 0.5])
    base = np.einsum("nip,p->ni", A, beta) + 0.3 * rng.normal(size=(N, 6))
    step = np.where(np.arange(N) < N // 2, 0.2, 0.1)[:, None]  # the "effect" halves
    bad = block_test(_prob(), Z, base + step * col[:, :, 0], [4])
    good = block_test(_prob(), Z, base + 0.15 * col[:, :, 0], [4])
    assert bad["p"] < 1e-6 and good["p"] > 1e-3, (bad["p"], good["p"])
    assert abs(good["first"][0] - 0.15) < 4 * good["std_first"][0]


def test_an_effect_on_one_cable_is_not_a_common_effect(rng):
    """A 'clock offset' that lives on cable 3 only: the groups of cables disagree and the
    message says where it acts; a common effect passes."""
    A, pc = _columns(rng)
    col = pc.sum(2)
    Z = np.concatenate([A, col], axis=2)
    noise = 0.3 * rng.normal(size=(N, 6))
    one = 0.025 * 8 * pc[:, :, 2, 0] + noise
    common = 0.025 * col[:, :, 0] + noise
    r_one = group_test(_prob(), Z, one, [4], pc)
    r_common = group_test(_prob(), Z, common, [4], pc)
    assert r_one["p"] < 1e-6 and r_common["p"] > 1e-3, (r_one["p"], r_common["p"])
    text = _resembles(Candidate("time_delay"), SimpleNamespace(parameters={"delay_s": 0.025}),
                      r_one)
    assert "on cable 3 only" in text and "not a time_delay" in text, text
    assert np.allclose(r_common["per_cable"][:, 0], 0.025, atol=5 * r_common["per_cable_std"][:, 0])


def test_sensor_alternatives_of_a_geometry_error():
    """On the geometry finding's cable: offset, drift, gain, friction and their pairs; in
    common: the clock offset and friction on every pulley; never another geometry error."""
    from cdprid.diagnosis import candidate_list

    cands = candidate_list(M, False)
    alts = sensor_alternatives(Candidate("exit_point_error", 3), cands, ())
    singles = {a[0] for a in alts if len(a) == 1}
    assert Candidate("tension_offset", 3) in singles and Candidate("tension_gain", 3) in singles
    assert Candidate("time_delay") in singles and Candidate("pulley_friction_all") in singles
    assert (Candidate("tension_offset", 3), Candidate("tension_gain", 3)) in alts
    assert not any(a.cable not in (None, 3) for alt in alts for a in alt)
    assert not any(a.effect in ("exit_point_error", "anchor_point_error") for alt in alts
                   for a in alt)


def test_the_survey_tolerance_is_robot_tomls_or_its_default():
    from cdprid.diagnosis._stability import SURVEY_TOLERANCE_M, survey_tolerance_m
    from cdprid.model import SIX_SUSPENDED, robot_from_dict

    assert survey_tolerance_m(robot_from_dict(SIX_SUSPENDED)) == SURVEY_TOLERANCE_M == 0.02
    assert survey_tolerance_m(robot_from_dict(dict(SIX_SUSPENDED, survey_tolerance=0.1))) == 0.1


@pytest.fixture(scope="module")
def offset_on_cable_2(tmp_path_factory):
    """20 s of the 6-cable suspended robot with a 3 N offset on load cell 2 (sensor noise)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.diagnosis import base_fit, prepare, start
    from cdprid.effects import Effect
    from cdprid.io import read_dataset
    from cdprid.model import SIX_SUSPENDED, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    robot = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(robot, preset("rich", robot, duration=20.0),
                   effects=[Effect("tension_offset", {"cable": 2, "offset_N": 3.0})],
                   noise=SensorNoise(position_m=1e-4, tension_N=0.3), seed=4)
    ds = read_dataset(write_simulation(sim, tmp_path_factory.mktemp("off") / "d"))
    prob, base = base_fit(prepare(ds))
    return prob, start(prob, base)


@pytest.mark.slow
def test_a_replacing_finding_carries_its_own_test_not_the_replaced_one(offset_on_cable_2):
    """Issue 37: findings that replace a geometry error kept its p-value and statistic. The
    restated finding of the true offset is significant with its own Wald statistic (theta^2 /
    var from the refit's HAC covariance, Bonferroni over the candidates); an offset on a
    cable without one is not; each held-out rms before is that of the model without it."""
    from cdprid.diagnosis import Finding
    from cdprid.diagnosis._selection import refit
    from cdprid.diagnosis._stability import restated

    prob, s = offset_on_cable_2
    true, null = Candidate("tension_offset", 2), Candidate("tension_offset", 5)
    idx = [prob.layout.candidate_indices(c.effect, c.cable)[0] for c in (true, null)]
    t = refit(prob, s, active_idx=sorted(idx))
    old = Finding("exit_point_error", {"cable": 2}, {}, ["x"], 1.0, 0.9, 0.5, 1.0, 1e-5)
    f_true, f_null = restated(prob, t, (true, null), old, 40, 0.8)
    stat = t.theta[idx[0]] ** 2 / t.th_cov[idx[0], idx[0]]
    assert f_true.effect == "tension_offset" and f_true.statistic == pytest.approx(stat)
    assert f_true.p_value < 1e-10 and f_true.statistic > 100
    assert f_null.p_value > 1e-3, f_null  # 40 x a chi2(1) tail: no offset on cable 5
    assert f_true.heldout_rms_after == f_null.heldout_rms_after == 0.8
    assert f_true.heldout_rms_before > 1.5 * f_null.heldout_rms_before  # the true one matters
    assert f_true.threshold == old.threshold and f_true.aliases == old.aliases


def test_a_disagreement_must_be_material_to_withdraw():
    """Significant but small (real data's bias on split estimates) is kept; a parameter that
    differs significantly by more than MATERIAL of its size is not; an insignificant large
    difference is not material either."""
    from cdprid.diagnosis._stability import MATERIAL, material

    def res(b1, s1, b2, s2):
        return {"first": np.array(b1), "std_first": np.array(s1),
                "second": np.array(b2), "std_second": np.array(s2)}

    assert not material(res([-0.0239], [0.0006], [-0.0284], [0.001]))  # UACDPR's halves
    assert material(res([0.0], [0.001], [0.025], [0.001]))  # on one cable only
    assert not material(res([0.0], [0.02], [0.025], [0.02]))  # not significant
    big = 1.0 + 2 * MATERIAL
    assert material(res([1.0, 5.0], [0.01, 0.01], [big, 5.0], [0.01, 0.01]))


def test_the_clock_columns_per_cable_sum_to_the_models_clock_column(offset_on_cable_2):
    """The group test splits the clock's column per cable: with a delay and a wrong gain in
    the model, the per-cable columns sum to the column the search uses (same sign and scale,
    the gain included), to rounding."""
    import dataclasses

    from cdprid.diagnosis._profile import clock_index
    from cdprid.diagnosis._selection import linear_model
    from cdprid.diagnosis._stability import clock_columns

    prob, s = offset_on_cable_2
    di = clock_index(prob)
    gi = prob.layout.candidate_indices("tension_gain", 3)[0]
    theta = np.array(s.theta, float)
    theta[di], theta[gi] = 0.015, 0.25
    t = dataclasses.replace(s, theta=theta, active_idx=tuple(sorted((di, gi))))
    _, _, _, C = linear_model(prob, t)
    pc = clock_columns(prob, t)
    assert pc.shape == (prob.n, 6, prob.m)
    scale = np.max(np.abs(C[:, :, di]))
    np.testing.assert_allclose(pc.sum(2), C[:, :, di], atol=1e-6 * scale)


@pytest.mark.slow
def test_a_finding_left_implausible_is_withdrawn(offset_on_cable_2):
    """A finding at an implausible value (a gain of 3.5 beside the true offset) is taken back,
    the model refitted, and it is reported for unexplained; the true offset stays."""
    import dataclasses

    from cdprid.diagnosis import Finding
    from cdprid.diagnosis._selection import refit
    from cdprid.diagnosis._stability import plausibility_stage

    prob, s = offset_on_cable_2
    off, gain = Candidate("tension_offset", 2), Candidate("tension_gain", 5)
    oi = prob.layout.candidate_indices(off.effect, off.cable)[0]
    gi = prob.layout.candidate_indices(gain.effect, gain.cable)[0]
    t = refit(prob, s, active_idx=[oi])
    theta = np.array(t.theta, float)
    theta[gi] = 2.5
    f = Finding("x", {}, {}, [], 1.0, 0.9, 1e-9, 100.0, 1e-5)
    t = dataclasses.replace(t, theta=theta, active_idx=tuple(sorted((oi, gi))),
                            accepted=(off, gain), findings=(f, f))
    said = []
    u, out = plausibility_stage(prob, t, {}, said.append)
    assert u.accepted == (off,) and gi not in u.active_idx
    assert len(out) == 1 and out[0]["where"] == gain.label
    assert "gain 3.5" in out[0]["correlates_with"]
    assert abs(u.theta[oi] - 3.0) < 0.5, u.theta[oi]


def _losses_pair(rng, n, ratio):
    """Per-sample held-out squared errors of two models on the same samples: correlated
    (the same residual plus a small difference), the alternative's mean ``ratio`` times the
    geometry model's."""
    e = rng.normal(size=n)
    geo = e * e + 0.05 * rng.normal(size=n) ** 2
    alt = ratio * geo * np.exp(0.05 * rng.normal(size=n))
    alt *= ratio * geo.mean() / alt.mean()
    return geo, alt


@pytest.mark.parametrize("ratio, expected", [
    (0.998, "cannot tell"),  # floor8 seed 2: 0.2 % apart (p = 0.23): no swap on a coin toss
    (1.002, "cannot tell"),  # the geometry error better within the noise: not named either
    (0.80, "alternative"),   # the sensor side predicts much better: it is named instead
    (1.25, "geometry"),      # the geometry error beats every alternative: named
])
def test_geometry_against_its_sensor_side_alternative(ratio, expected):
    """Issue 37: a geometry error beyond the survey tolerance is named only when it beats its
    best sensor-side alternative; the alternative only when it is significantly better
    (one-sided Diebold-Mariano at 5 %); when neither is, neither is named ("cannot tell")."""
    from cdprid.diagnosis._competing import dm_p_worse
    from cdprid.diagnosis._stability import ALTERNATIVE_DM_LEVEL, geometry_verdict

    geo, alt = _losses_pair(np.random.default_rng(37), 4000, ratio)
    p = dm_p_worse(alt, geo, 3)
    rms_geo, rms_alt = float(np.sqrt(geo.mean())), float(np.sqrt(alt.mean()))
    if expected == "cannot tell":  # the series are within each other's sampling noise
        assert ALTERNATIVE_DM_LEVEL < p < 1 - ALTERNATIVE_DM_LEVEL, p
    assert geometry_verdict(rms_geo, rms_alt, p, 0.01) == expected
    assert geometry_verdict(rms_geo, None, 0.0, 0.01) == "geometry"  # nothing to weigh


def test_sensor_alternatives_of_a_frame_tilt():
    """Issue 37: a frame tilt is weighed against every per-cable sensor form (one at a time,
    on any cable) and the common forms on the readings; never a geometry error, never
    drag, cable mass or the pulley radius."""
    from cdprid.diagnosis import candidate_list
    from cdprid.diagnosis._stability import frame_geometry, tilt_alternatives

    cands = candidate_list(M, False)
    tilt = Candidate("frame_tilt")
    assert frame_geometry(tilt) and not frame_geometry(Candidate("exit_point_error", 3))
    alts = tilt_alternatives(cands, (tilt,))
    assert all(len(a) == 1 for a in alts)
    singles = {a[0] for a in alts}
    assert {Candidate("tension_offset", j) for j in range(1, M + 1)} <= singles
    assert Candidate("time_delay") in singles and Candidate("pulley_friction_all") in singles
    assert not {a.effect for a in singles} & {"exit_point_error", "anchor_point_error",
                                              "frame_tilt", "viscous_drag", "cable_mass",
                                              "pulley"}
    assert Candidate("tension_offset", 4) not in {
        a[0] for a in tilt_alternatives(cands, (tilt, Candidate("tension_offset", 4)))}


def _with_tilt(prob, s, others=()):
    """The model ``s`` refitted with a frame tilt (and ``others``) as its findings."""
    import dataclasses

    from cdprid.diagnosis import Finding
    from cdprid.diagnosis._selection import refit

    found = (Candidate("frame_tilt"),) + tuple(others)
    idx = sorted(i for c in found for i in prob.layout.candidate_indices(c.effect, c.cable))
    t = refit(prob, s, active_idx=idx)
    f = Finding("x", {}, {}, [], 1.0, 0.9, 1e-9, 100.0, 1e-5)
    return dataclasses.replace(t, accepted=found, findings=(f,) * len(found))


def test_a_tilt_standing_in_for_a_cells_offset_is_not_named(offset_on_cable_2):
    """Issue 37: a frame tilt was never weighed against the sensor side (floor8's clean twin
    of seed 2 named a 1.6 mrad tilt that is not there). With a tilt in the model in place of
    the 3 N offset on cell 2, the geometry stage does not keep the tilt: the offset predicts
    the held-out data better and is named in its place."""
    from cdprid.diagnosis import candidate_list
    from cdprid.diagnosis._stability import geometry_stage

    prob, s = offset_on_cable_2
    t = _with_tilt(prob, s)
    said = []
    u, out = geometry_stage(prob, t, candidate_list(prob.m, False), 0.01, {}, said.append)
    assert Candidate("frame_tilt") not in u.accepted, said
    assert u.accepted == (Candidate("tension_offset", 2),), (u.accepted, said)
    oi = prob.layout.candidate_indices("tension_offset", 2)[0]
    assert abs(u.theta[oi] - 3.0) < 0.5, u.theta[oi]


@pytest.fixture(scope="module")
def tilted(tmp_path_factory):
    """20 s of the 6-cable suspended robot on a frame tilted by [3, -2] mrad (sensor noise)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.diagnosis import base_fit, prepare, start
    from cdprid.effects import Effect
    from cdprid.io import read_dataset
    from cdprid.model import SIX_SUSPENDED, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    robot = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(robot, preset("rich", robot, duration=20.0),
                   effects=[Effect("frame_tilt", {"tilt_rad": [0.003, -0.002]})],
                   noise=SensorNoise(position_m=1e-4, tension_N=0.3), seed=4)
    ds = read_dataset(write_simulation(sim, tmp_path_factory.mktemp("tilt") / "d"))
    prob, base = base_fit(prepare(ds))
    return prob, start(prob, base)


def test_a_true_tilt_beats_the_sensor_side(tilted):
    """The other side of the same rule: a true 3.6 mrad tilt predicts the held-out data better
    than every sensor-side alternative and stays named, at its size."""
    from cdprid.diagnosis import candidate_list
    from cdprid.diagnosis._stability import geometry_stage

    prob, s = tilted
    t = _with_tilt(prob, s)
    said = []
    u, out = geometry_stage(prob, t, candidate_list(prob.m, False), 0.01, {}, said.append)
    assert u.accepted == (Candidate("frame_tilt"),) and not out, said
    ti = prob.layout.candidate_indices("frame_tilt", None)
    np.testing.assert_allclose(u.theta[ti], [0.003, -0.002], atol=4e-4)
