"""tension_drift: an effect added by one module (effects/_tension_drift.py), the load-cell
sensor chain declared once, and one clock for time-dependent effects (issue 22)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from cdprid.effects import DIAGNOSIS, VOCABULARY, Effect, parse_effect


def test_drift_is_in_the_vocabulary_and_validated():
    assert VOCABULARY["tension_drift"] == {"cable": "cable", "rate_N_per_s": "float"}
    e = parse_effect("tension_drift", ["cable=3", "rate_N_per_s=-0.05"])
    assert e.params == {"cable": 3, "rate_N_per_s": -0.05}
    with pytest.raises(ValueError, match="rate_N_per_s"):
        Effect("tension_drift", {"cable": 1, "rate_N_per_s": "fast"})
    with pytest.raises(ValueError, match="rate_N_per_s"):
        Effect("tension_drift", {"cable": 1})


def _chain(rng, k=50, m=4):
    t = 7.0 + np.arange(k) * 0.01
    tau = 20 + rng.normal(size=(k, m))
    W = rng.normal(size=(k, 6, m))
    v, om = rng.normal(size=(k, 3)), rng.normal(size=(k, 3))
    effects = [Effect("tension_drift", {"cable": 2, "rate_N_per_s": 0.3}),
               Effect("tension_offset", {"cable": 2, "offset_N": 1.5}),
               Effect("tension_gain", {"cable": 2, "gain": 1.2}),
               Effect("pulley_friction", {"cable": 2, "coulomb_N": 2.0, "viscous_Ns_per_m": 4.0})]
    return t, tau, W, v, om, effects


def test_sensor_chain_reads_in_physical_order(rng):
    """gain * (tau + friction) + offset + drift (t - t0): written out here independently."""
    from cdprid.effects._sensor import load_cell_reading

    t, tau, W, v, om, effects = _chain(rng)
    r = load_cell_reading(effects, tau, W, v, om, t)
    ldot = np.array([-W[k].T @ np.concatenate([v[k], om[k]]) for k in range(len(t))])[:, 1]
    expect = 1.2 * (tau[:, 1] - 2.0 * np.sign(ldot) - 4.0 * ldot) + 1.5 + 0.3 * (t - t[0])
    assert np.allclose(r[:, 1], expect, atol=1e-12)
    assert np.array_equal(r[:, [0, 2, 3]], tau[:, [0, 2, 3]])


def test_diagnosis_hooks_undo_the_sensor_chain(rng):
    """The diagnosis's tension hooks, in table order, give back the platform-side tension
    from what the simulator's sensor chain reads (the order is physics, not dict order)."""
    from cdprid.effects._sensor import load_cell_reading

    t, tau, W, v, om, effects = _chain(rng)
    r = load_cell_reading(effects, tau, W, v, om, t)
    ldot = -np.einsum("nim,ni->nm", W, np.concatenate([v, om], axis=1))
    q = {"delay": 0.0, "offset": 1.5, "drift": 0.3, "gain": 0.2, "coulomb": 2.0, "pvisc": 4.0}
    out = []
    for k in range(len(t)):
        c = {"at": {"delay": 0.0}, "taud": 0.0, "ldot": ldot[k, 1], "t": t[k] - t[0]}
        x = jnp.asarray(r[k, 1])
        for form in DIAGNOSIS.values():
            if form.tension is not None and all(b in q for b, _ in form.blocks):
                x = form.tension(x, q, c)
        out.append(float(x))
    assert np.allclose(out, tau[:, 1], atol=1e-12)


def test_subset_clock_keeps_each_block_real_time():
    from cdprid.diagnosis import subset
    from cdprid.io import Dataset
    from cdprid.model import robot_from_dict
    from conftest import ROBOT_CRAFT

    t = 3.0 + np.arange(20000) * 0.01  # 200 s
    ds = Dataset(path=None, robot=robot_from_dict(ROBOT_CRAFT), pose_t=t,
                 position=np.zeros((len(t), 3)), quaternion=None, tension_t=t,
                 tension=np.ones((len(t), 8)))
    sub = subset(ds, max_samples=6000, n_blocks=3, min_block_s=5.0)
    assert sub is not None and len(sub.windows) == 3
    pt = np.asarray(sub.dataset.pose_t)
    assert np.all(np.diff(pt) > 0)  # one continuous joined axis
    real = sub.clock(pt) + t[0]
    # every joined sample maps back to a time stamp of the original recording, in its block
    assert np.allclose(real, t[np.round((real - t[0]) / 0.01).astype(int)], atol=1e-9)
    per = len(pt) // 3
    for k, (a, b) in enumerate(sub.windows):
        assert real[k * per] == pytest.approx(a, abs=1e-9)
        assert real[(k + 1) * per - 1] == pytest.approx(b, abs=1e-9)
    assert real[-1] > 190.0  # the clock reaches the end of the recording, the joined axis not
    assert pt[-1] < 70.0


def _drift_dataset(tmp_path, duration, rate):
    from cdprid.io import read_dataset
    from cdprid.model import SIX_SUSPENDED, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    rob = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(rob, preset("rich", rob, duration=duration), None,
                   effects=[Effect("tension_drift", {"cable": 3, "rate_N_per_s": rate})],
                   noise=SensorNoise(position_m=2e-4, tension_N=0.5), seed=4)
    return read_dataset(write_simulation(sim, tmp_path / "d", overwrite=True))


def _named(res, rate):
    names = [(f.effect, f.parameters.get("cable")) for f in res.findings]
    assert names == [("tension_drift", 3)], names
    lo, hi = res.findings[0].interval["rate_N_per_s"]
    assert lo <= rate <= hi, (lo, hi)


def test_drift_named_with_its_size_on_a_six_cable_robot(tmp_path):
    from cdprid.diagnosis import diagnose

    ds = _drift_dataset(tmp_path, 30.0, 0.1)
    _named(diagnose(ds), 0.1)


def test_drift_named_on_the_real_clock_above_the_sample_budget(tmp_path):
    """A recording analysed on joined blocks: the drift is evaluated on each block's real
    time stamps (on the joined axis it would come out too large)."""
    from cdprid.diagnosis import diagnose

    ds = _drift_dataset(tmp_path, 120.0, 0.05)
    res = diagnose(ds, max_samples=4000)
    assert "subset" in res.info
    _named(res, 0.05)
