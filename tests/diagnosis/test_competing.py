"""Model-level ambiguity (issue 23, item 3): complete alternative models within the noise.

Oracles: the held-out residuals reproduce the held-out RMS the search uses; the
Diebold-Mariano test's size by Monte Carlo; and a simulated 4-cable recording whose hidden
gain the search does not name (it names a frame tilt that moves the forces alike): the true
effect, with its size, is among the competing models.
"""

import re
import tempfile
import types
from pathlib import Path

import numpy as np
import pytest

from cdprid.diagnosis._competing import DM_LEVEL, dm_p_worse
from cdprid.diagnosis._problem import heldout_residuals, heldout_rms


@pytest.mark.parametrize("split", [False, True])
def test_heldout_residuals_give_the_heldout_rms(split):
    rng = np.random.default_rng(0)
    n, p = 900, 5
    Z = rng.normal(size=(n, 6, p))
    y = np.einsum("nip,p->ni", Z, rng.normal(size=p)) + rng.normal(size=(n, 6))
    use = np.ones(n, bool)
    use[:30] = False
    train = use & (np.arange(n) < 600) if split else use
    test = use & (np.arange(n) >= 600) if split else None
    prob = types.SimpleNamespace(use=use, train=train, test=test, n_folds=5, lags=7)
    idx, r = heldout_residuals(prob, Z, y)
    assert np.isclose(np.sqrt(np.mean(r * r)), heldout_rms(prob, Z, y), rtol=1e-10)
    assert len(idx) == (test.sum() if split else use.sum())


def test_diebold_mariano_size_and_power():
    rng = np.random.default_rng(1)
    assert dm_p_worse(np.ones(50), np.ones(50), 3) == 0.5
    n, rho, reps = 2000, 0.9, 400
    rejected = 0
    for _ in range(reps):  # equal accuracy, losses correlated over ~20 samples
        e = rng.normal(size=n)
        d = np.empty(n)
        d[0] = e[0]
        for k in range(1, n):
            d[k] = rho * d[k - 1] + np.sqrt(1 - rho**2) * e[k]
        base = 5.0 + rng.normal(size=n) ** 2
        rejected += dm_p_worse(base + d, base, 80) < DM_LEVEL
    assert 0.02 <= rejected / reps <= 0.10
    worse = 5.0 + rng.normal(size=n) ** 2
    assert dm_p_worse(worse + 0.5, worse, 20) < 1e-6
    assert dm_p_worse(worse - 0.5, worse, 20) > 1 - 1e-6


@pytest.mark.slow  # a full diagnosis, 50-75 s on 2 cores: with the slow tests (CI runs them all)
def test_the_hidden_gain_is_a_competing_model_when_a_tilt_is_named(monkeypatch):
    """4-cable point mass, a 4 % gain on cable 4 (the detection benchmark's run
    ``single|tension_gain 0.04|four|2``): the search picks a frame tilt (an alias on this
    robot); named, the gain competes with its size; withdrawn (a tilt must beat the sensor
    side), nothing is named and the gain is its "cannot tell" reading."""
    from cdprid.diagnosis import diagnose
    from cdprid.effects import Effect
    from cdprid.io import read_dataset
    from cdprid.model import FOUR_SUSPENDED, InertialParameters, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    robot = robot_from_dict(FOUR_SUSPENDED)
    sim = simulate(robot, preset("rich", robot),
                   InertialParameters(6.0, [0.0, 0.0, 0.0], np.eye(3) * 0.05),
                   effects=[Effect("tension_gain", {"cable": 4, "gain": 0.96})],
                   noise=SensorNoise(position_m=3e-4, tension_N=0.7, orientation_rad=0.0),
                   seed=2)
    with tempfile.TemporaryDirectory() as tmp:
        ds = read_dataset(write_simulation(sim, Path(tmp) / "four-gain"))
        res = diagnose(ds)
        # the stage leaves the final model as it is: the same result without it
        import cdprid.diagnosis._pipeline as P

        monkeypatch.setattr(P, "competing_models", lambda *a, **k: ([], 0))
        res0 = diagnose(ds)
    assert [f.as_json() for f in res0.findings] == [f.as_json() for f in res.findings]
    assert res0.extended_parameters == res.extended_parameters
    assert res0.extended_heldout_rms == res.extended_heldout_rms
    assert res0.unexplained == res.unexplained
    found = {(f.effect, f.parameters.get("cable")) for f in res.findings}
    competing = [c for c in res.competing if c["by"] == "tension_gain:cable=4"]
    tied = [u for u in res.unexplained if u.get("withdrawn_finding") == "frame_tilt"]
    if ("frame_tilt", None) in found:  # the tilt named: the gain, with its size, competes
        assert ("tension_gain", 4) in found or competing
    else:  # since session 9 a tilt must beat the sensor side: here it cannot ("cannot tell"),
        # so nothing is named and the entry carries a gain of the hidden size as the other
        # reading (on this symmetric 4-cable robot a +4 % gain on cable 2 predicts as well)
        assert not found and tied, (found, res.unexplained)
        assert "tension_gain" in tied[0]["correlates_with"], tied
        gains = [float(g) for g in re.findall(r"'gain': ([0-9.]+)", tied[0]["correlates_with"])]
        assert gains and all(0.03 < abs(g - 1.0) < 0.05 for g in gains), tied
    for c in competing:
        assert abs(c["parameters"]["gain"] - 0.96) < 0.005
    aliases = {a for f in res.findings for a in f.aliases}
    for c in res.competing:  # every competitor is an alias, within the noise
        assert c["by"] in aliases
        assert c["relative_difference"] < 0.01 or c["p_worse"] > DM_LEVEL
    assert res.as_json()["competing_models"] == res.competing
