"""The diagnosis on recordings that hold many effects at once (issue 23): friction on every
pulley (``"cable": "all"``), a clock offset of tens of ms, sensor and geometry errors and
rotations together; clean rotating data give no finding."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.effects import Effect, parse_effect


def _six_upfed():
    from cdprid.model import SIX_SUSPENDED, robot_from_dict

    d = dict(SIX_SUSPENDED, name="six-upfed")
    d["cable"] = [dict(c, pulley_radius=0.04, pulley_axis=[0.0, 0.0, 1.0])
                  for c in SIX_SUSPENDED["cable"]]
    return robot_from_dict(d)


def _diagnose(tmp_path, robot, effects, seed, noise=True, params=None):
    from cdprid.diagnosis import diagnose
    from cdprid.io import read_dataset
    from cdprid.model import preset
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    sn = (SensorNoise(position_m=3e-4, tension_N=0.7, orientation_rad=2e-4) if noise
          else SensorNoise.off())
    sim = simulate(robot, preset("rich", robot), params, effects=effects, noise=sn, seed=seed)
    return diagnose(read_dataset(write_simulation(sim, tmp_path / f"d{seed}", overwrite=True)))


def test_friction_on_every_pulley_is_one_effect():
    e = parse_effect("pulley_friction", ["cable=all", "coulomb_N=1.5", "viscous_Ns_per_m=0"])
    assert e.params["cable"] == "all"
    with pytest.raises(ValueError, match="or all"):
        parse_effect("pulley_friction", ["cable=some", "coulomb_N=1", "viscous_Ns_per_m=0"])
    with pytest.raises(ValueError, match="cable number"):  # no common form for an offset
        parse_effect("tension_offset", ["cable=all", "offset_N=1"])


def test_common_friction_reads_on_every_load_cell(rng):
    from cdprid.effects import load_cell_friction

    n, m = 30, 6
    W = rng.normal(size=(n, 6, m))
    v, om = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    common = load_cell_friction([Effect("pulley_friction", {"cable": "all", "coulomb_N": 2.0,
                                                            "viscous_Ns_per_m": 0.5})], W, v, om)
    each = load_cell_friction([Effect("pulley_friction", {"cable": i, "coulomb_N": 2.0,
                                                          "viscous_Ns_per_m": 0.5})
                               for i in range(1, m + 1)], W, v, om)
    assert np.array_equal(common, each)


def _check(res, expect: dict):
    """``expect``: effect -> (parameter, truth); each named once, inside its interval, and
    nothing else found."""
    got = {f.effect: f for f in res.findings}
    assert sorted(got) == sorted(expect), [(f.effect, f.parameters) for f in res.findings]
    for name, (key, truth) in expect.items():
        lo, hi = got[name].interval[key]
        assert lo - 0.05 * abs(truth) <= truth <= hi + 0.05 * abs(truth), (name, lo, hi, truth)


@pytest.mark.slow  # a full diagnosis, 35-45 s on 2 cores: with the slow tests (CI runs them all)
def test_six_cable_upfed_delay_and_friction_on_every_pulley(tmp_path):
    """The issue's 6-cable robot with up-fed swivel pulleys, rotating ~5 deg: a 12 ms clock
    offset and 1.5 N Coulomb friction on all six pulleys, with noise."""
    rob = _six_upfed()
    res = _diagnose(tmp_path, rob, [
        Effect("rotational_dynamics", {"amplitude_rad": 0.08}),
        Effect("time_delay", {"delay_s": 0.012}),
        Effect("pulley_friction", {"cable": "all", "coulomb_N": 1.5, "viscous_Ns_per_m": 0.0})],
        seed=1)
    _check(res, {"time_delay": ("delay_s", 0.012), "pulley_friction": ("coulomb_N", 1.5)})
    fr = next(f for f in res.findings if f.effect == "pulley_friction")
    assert fr.parameters["cable"] == "all"
    assert res.info["base_model"] == "full"  # the rotation is in the base model
    # a named clock offset says what its interval holds (issue 37: a bias over the whole
    # recording from the noise is not in it)
    assert sum("clock offset" in n and "95 % interval holds" in n for n in res.notes) == 1, \
        res.notes
    assert "interval_caveat" in res.info["clock_profile"]


@pytest.mark.slow
def test_clean_rotating_noise_free_data_give_no_finding(tmp_path):
    res = _diagnose(tmp_path, _six_upfed(),
                    [Effect("rotational_dynamics", {"amplitude_rad": 0.08})], seed=1, noise=False)
    assert res.findings == [] or res.findings == (), [f.effect for f in res.findings]
    assert res.unexplained == [], res.unexplained
    assert any("full 10-parameter model" in n for n in res.notes)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [2, 4])
def test_five_effects_at_once_on_the_craft_like_robot(tmp_path, seed):
    """Clock offset, friction on all 8 pulleys, an offset, a gain, 4-5 deg rotations."""
    from cdprid.model import craft_like_robot, craft_like_truth

    rng = np.random.default_rng(seed)
    delay = float(rng.uniform(0.015, 0.030))
    coulomb = float(rng.uniform(2, 5))
    c_off, c_gain = (int(c) for c in rng.permutation(8)[:2] + 1)
    offset = float(rng.choice([-1, 1]) * rng.uniform(3, 8))
    gain = float(1 + rng.choice([-1, 1]) * rng.uniform(0.04, 0.08))
    res = _diagnose(tmp_path, craft_like_robot(), [
        Effect("time_delay", {"delay_s": delay}),
        Effect("pulley_friction", {"cable": "all", "coulomb_N": coulomb,
                                   "viscous_Ns_per_m": 0.0}),
        Effect("tension_offset", {"cable": c_off, "offset_N": offset}),
        Effect("tension_gain", {"cable": c_gain, "gain": gain}),
        Effect("rotational_dynamics", {"amplitude_rad": 0.08})], seed=seed,
        params=craft_like_truth())
    _check(res, {"time_delay": ("delay_s", delay), "pulley_friction": ("coulomb_N", coulomb),
                 "tension_offset": ("offset_N", offset), "tension_gain": ("gain", gain)})
