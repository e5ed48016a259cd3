"""The search's second start from the best pair (issue 23, item 3: search over models).

Oracles: the all-subsets held-out RMS equals the one-at-a-time criterion the search uses
(least squares per fold); the choice between two complete models follows its stated rule;
and a simulated CRAFT-like recording with an anchor error and a gain on cables whose partners
alias them (the detection benchmark's run ``pair|anchor+gain|craft8|3``), where the greedy path
names a gain on cable 5 and an anchor error on cable 7, is named on the right cables with
their sizes, the greedy model reported as a competing model.
"""

import tempfile
import types
from pathlib import Path

import numpy as np
import pytest

from cdprid.diagnosis._problem import heldout_rms, subset_heldout_rms
from cdprid.diagnosis._restart import keeps_first


@pytest.mark.parametrize("split", [False, True])
@pytest.mark.parametrize("lags", [0, 7, 150])
def test_subset_heldout_rms_equals_the_search_criterion(split, lags):
    rng = np.random.default_rng(lags)
    n, p = 700, 9
    Z = rng.normal(size=(n, 6, p))
    Z[:, :, 8] = Z[:, :, 7] + 1e-3 * rng.normal(size=(n, 6))  # nearly collinear pair
    y = np.einsum("nip,p->ni", Z, rng.normal(size=p)) + rng.normal(size=(n, 6))
    use = np.ones(n, bool)
    use[:25] = False
    use[400:420] = False
    train = use & (np.arange(n) < 500) if split else use
    test = use & (np.arange(n) >= 500) if split else None
    prob = types.SimpleNamespace(use=use, train=train, test=test, n_folds=5, lags=lags)
    subsets = [[0, 1], [0, 1, 2, 5], [3, 7, 8], list(range(p)), [4]]
    got = subset_heldout_rms(prob, Z, y, subsets)
    want = [heldout_rms(prob, Z[:, :, s], y) for s in subsets]
    np.testing.assert_allclose(got, want, rtol=1e-9)


def test_the_model_kept_predicts_better_or_is_smaller_within_the_gate():
    assert keeps_first(1.00, 2, 1.02, 2, 0.01)  # better
    assert not keeps_first(1.02, 2, 1.00, 2, 0.01)
    assert not keeps_first(1.005, 2, 1.000, 2, 0.01)  # same size: the better, however close
    assert keeps_first(1.005, 2, 1.000, 3, 0.01)  # within the gate: the smaller model
    assert not keeps_first(1.000, 3, 1.005, 2, 0.01)
    assert keeps_first(1.000, 3, 1.030, 2, 0.01)  # beyond the gate: the better one
    assert keeps_first(1.0, 2, 1.0, 2, 0.01)  # exact tie: the first


@pytest.mark.slow
def test_anchor_and_gain_on_aliasing_cables_named_on_the_right_cables():
    """Run as ``cdprid diagnose`` in a subprocess: its kernels are compiled there, not in the
    test process (a long in-process run that compiles many large diagnosis kernels can exhaust
    LLVM's memory: see benchmarks/diagnosis.py ``--max-runs``)."""
    import json
    import subprocess
    import sys

    from cdprid.effects import Effect
    from cdprid.model import craft_like_robot, craft_like_truth, preset
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    robot = craft_like_robot()
    truth = [("anchor_point_error", {"cable": 8, "displacement_m": [0.0063, -0.02057, 0.01273]}),
             ("tension_gain", {"cable": 1, "gain": 0.96})]
    sim = simulate(robot, preset("rich", robot), craft_like_truth(),
                   effects=[Effect(n, p) for n, p in truth],
                   noise=SensorNoise(position_m=3e-4, tension_N=0.7, orientation_rad=2e-4),
                   seed=3)
    with tempfile.TemporaryDirectory() as tmp:
        folder = write_simulation(sim, Path(tmp) / "pair")
        out = Path(tmp) / "d.json"
        proc = subprocess.run([sys.executable, "-m", "cdprid", "diagnose", str(folder),
                               "--json", str(out)], capture_output=True, text=True)
        assert proc.returncode == 0, proc.stderr[-2000:]
        res = json.loads(out.read_text())
    got = {(f["effect"], f["parameters"]["cable"]): f for f in res["findings"]}
    assert set(got) == {("anchor_point_error", 8), ("tension_gain", 1)}, proc.stderr[-3000:]
    lo, hi = got[("tension_gain", 1)]["interval"]["gain"]
    assert lo <= 0.96 <= hi
    d = np.asarray(got[("anchor_point_error", 8)]["parameters"]["displacement_m"])
    assert np.linalg.norm(d - truth[0][1]["displacement_m"]) < 0.01
    assert "from the best pair" in proc.stderr  # the progress says where the search restarted
    assert res["info"]["second_start"]["kept"] == "best pair"
    # the greedy path's model is reported as a competing model with both of its effects
    assert any(" + " in c["by"] and len(c["parameters"]) == 2
               for c in res["competing_models"]), res["competing_models"]


def test_a_competing_model_with_several_effects_prints_each_effects_parameters():
    from cdprid.report import format_values

    params = {"tension_gain:cable=5": {"cable": 5, "gain": 1.0305},
              "anchor_point_error:cable=7": {"cable": 7, "displacement_m": [0.009, -0.007]}}
    assert format_values(params) == ("tension_gain:cable=5 (cable 5, gain 1.03), "
                                     "anchor_point_error:cable=7 (cable 7, displacement_m "
                                     "[0.009, -0.007])")
