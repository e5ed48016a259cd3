"""cable_elasticity: the winch-encoder stream lengths.csv, simulated and diagnosed.

Oracles: noise-free data recover EA to ~1e-9; a realistic stiffness is named with its size on
a 6- and an 8-cable robot; no finding without the effect; the full diagnosis names it.
"""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.diagnosis import _lengths as LG
from cdprid.effects import Effect
from cdprid.io import read_dataset
from cdprid.model import CRAFT_LIKE, SIX_SUSPENDED, craft_like_truth, preset, robot_from_dict
from cdprid.simulation import SensorNoise, simulate, write_simulation


def test_fit_cable_recovers_stiffness_and_offset_exactly(rng):
    n = 2000
    L = 2.0 + 0.5 * np.sin(np.linspace(0, 20, n))
    tau = 25 + 10 * np.cos(np.linspace(0, 13, n))
    EA, c = 3e4, -0.0123
    c_hat, k, e, J = LG.fit_cable(c + L / (1 + tau / EA), L, tau)
    assert abs(1 / k - EA) < 1e-9 * EA and abs(c_hat - c) < 1e-12
    assert np.max(np.abs(e)) < 1e-13 and J.shape == (n, 2)


def _stage(robot_dict, effects, tmp_path, noise=None, seed=0, lengths=True):
    from cdprid.diagnosis._problem import prepare

    robot = robot_from_dict(robot_dict)
    sim = simulate(robot, preset("rich", robot, duration=30.0), craft_like_truth(),
                   effects=[Effect(*e) for e in effects], seed=seed, lengths=lengths,
                   noise=SensorNoise(3e-4, 2e-4, 0.7) if noise is None else noise)
    ds = read_dataset(write_simulation(sim, tmp_path / f"ds{seed}"))
    stream, notes = LG.lengths_stream(ds)
    assert notes == []
    prob = prepare(ds)
    return LG.elasticity_stage(prob, stream, 1e-3)


def test_noise_free_stiffness_recovered_to_1e_9(tmp_path):
    found, info = _stage(CRAFT_LIKE, [("cable_elasticity", {"cable": 5, "EA_N": 4e4})],
                         tmp_path, noise=SensorNoise.off())
    assert [f.parameters["cable"] for f in found] == [5]
    assert abs(found[0].parameters["EA_N"] - 4e4) < 1e-9 * 4e4
    assert all(abs(c["k_per_N"]) < 1e-12 for c in info["cables"] if c["cable"] != 5)


@pytest.mark.parametrize("robot_dict,cable", [(SIX_SUSPENDED, 2), (CRAFT_LIKE, 7)])
def test_realistic_stiffness_named_with_its_size(robot_dict, cable, tmp_path):
    """EA = 2e5 N (a stretch of about 0.1-0.5 mm) under 0.3 mm pose and 0.05 mm encoder noise."""
    found, info = _stage(robot_dict, [("cable_elasticity", {"cable": cable, "EA_N": 2e5})],
                         tmp_path, seed=1)
    assert [f.parameters["cable"] for f in found] == [cable], info
    f = found[0]
    lo, hi = f.interval["EA_N"]
    assert lo < 2e5 < hi and abs(f.parameters["EA_N"] - 2e5) < 0.25 * 2e5
    assert f.heldout_rms_after < f.heldout_rms_before


@pytest.mark.parametrize("robot_dict,scale", [(SIX_SUSPENDED, 1.0), (CRAFT_LIKE, 2.0)])
def test_no_finding_without_elasticity(robot_dict, scale, tmp_path):
    noise = SensorNoise(3e-4 * scale, 2e-4, 0.7 * scale, length_m=5e-5 * scale)
    found, info = _stage(robot_dict, [], tmp_path, noise=noise, seed=2)
    assert found == [], info


def test_malformed_stream_is_a_note_not_a_test(tmp_path):
    robot = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(robot, preset("rich", robot, duration=30.0), craft_like_truth(), seed=0,
                   lengths=True)
    out = write_simulation(sim, tmp_path / "ds")
    text = (out / "lengths.csv").read_text().replace("l_6", "l6", 1)
    (out / "lengths.csv").write_text(text)
    stream, notes = LG.lengths_stream(read_dataset(out))
    assert stream is None and "lengths.csv" in notes[0] and "l_6" in notes[0]


@pytest.mark.slow
def test_diagnose_names_cable_elasticity_and_nothing_else(tmp_path):
    import json

    from cdprid.cli import main

    sim = tmp_path / "sim"
    assert main(["simulate", "--preset", "rich", "--duration", "36", "--out", str(sim),
                 "--seed", "3", "--noise-pos", "3e-4", "--noise-tension", "0.7",
                 "--effect", "cable_elasticity", "--param", "cable=4",
                 "--param", "EA_N=1e5"]) == 0
    assert (sim / "lengths.csv").is_file()
    out = tmp_path / "d.json"
    assert main(["diagnose", str(sim), "--json", str(out), "--quiet"]) == 0
    res = json.loads(out.read_text())
    assert [f["effect"] for f in res["findings"]] == ["cable_elasticity"], res["findings"]
    f = res["findings"][0]
    assert f["parameters"]["cable"] == 4
    lo, hi = f["interval"]["EA_N"]
    assert abs(f["parameters"]["EA_N"] - 1e5) < 0.25e5 and lo < 1e5 < hi
    assert res["unexplained"] == []
