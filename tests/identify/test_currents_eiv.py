"""The pose noise's errors-in-variables bias of ``identify --source currents`` (output error),
removed by re-noising the poses (``cdprid.identify._currents_pose``), against the independent
winch simulator (tests/identify/winch_sim.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from tests.identify import winch_sim

import cdprid.identify._currents_pose as pose
from cdprid.identify import identify_currents
from cdprid.io import read_dataset
from cdprid.model import SIX_SUSPENDED

SIX = dict(SIX_SUSPENDED, home=[0.0, 0.0, 1.4])
PLATFORM = (6.0, np.array([0.01, -0.005, -0.05]), np.diag([0.06, 0.07, 0.09]))
MSG = 6.0 * PLATFORM[1]  # m s_G, kg m


DESIGN = Path(__file__).resolve().parents[2] / "results/currents-designed/six-trajectory.csv"


def _fits(tmp_path, noise_pos, monkeypatch, seed=0, path=None, params=None):
    """``(uncorrected, corrected)`` reports on one simulated recording with pose (position)
    noise only."""
    sim = winch_sim.simulate(SIX, PLATFORM, seed=seed, duration=16.0 if path is None else
                             path.duration, rate_drive=200.0, noise_pos=noise_pos, noise_rot=0,
                             noise_A=0, noise_len=0, path=path)
    ds = read_dataset(winch_sim.write(tmp_path / "d", SIX, sim), require_tensions=False)
    kw = dict(reference="drive:1", bound=False, params=params, model="full")
    monkeypatch.setattr(pose, "PAIRS", 0)
    plain = identify_currents(ds, **kw)
    monkeypatch.setattr(pose, "PAIRS", 2)
    return plain, identify_currents(ds, **kw)


def test_pose_noise_bias_is_removed(tmp_path, monkeypatch):
    """The six-cable design of results/currents-designed.md (32 s), 0.2 mm position noise
    only, seed 0: uncorrected, m z_G is 0.49 % of |m s_G| off (3 std, the pose noise's
    errors in variables); corrected, m s_G's error is at most a fifth of that, the note and
    the warning say so, and the std grows by less than 30 % (the Monte-Carlo spread)."""
    plain, corr = _fits(tmp_path, 2e-4, monkeypatch,
                        path=winch_sim.path_from_csv(str(DESIGN)))
    e0 = np.linalg.norm(plain.theta[1:4] - MSG)
    e1 = np.linalg.norm(corr.theta[1:4] - MSG)
    assert e0 > 2.5 * plain.std[3]  # the bias is there to remove
    assert e1 < e0 / 5.0, (e0, e1)
    assert abs(corr.theta[3] - MSG[2]) < corr.std[3]
    assert any(n.startswith("pose noise (errors in variables)") for n in corr.notes)
    assert not any(n.startswith("pose noise (errors in variables)") for n in plain.notes)
    assert any("the pose noise biased" in w for w in corr.warnings)
    assert np.all(corr.std[:4] < 1.3 * plain.std[:4])
    sh = corr.compared["pose_shift"]
    np.testing.assert_allclose(corr.theta, plain.theta - sh, rtol=0, atol=1e-12)
    # what benchmarks/currents.py's `oe-uncorrected` rows take back from one fit
    np.testing.assert_allclose(corr.cov - corr.compared["pose_shift_cov"], plain.cov, rtol=0,
                               atol=1e-9 * np.max(np.abs(plain.cov)))


def test_noise_free_recording_is_unchanged(tmp_path, monkeypatch):
    """Exact poses: the re-noising (at the tiny level their 4th differences show) moves no
    platform parameter by more than 1e-4 of its scale, and adds no warning."""
    plain, corr = _fits(tmp_path, 0.0, monkeypatch, params={"cutoff_hz": 4.0})
    scale = np.r_[6.0, np.full(3, np.linalg.norm(MSG)), np.full(6, 0.1)]
    assert np.max(np.abs(corr.theta[:10] - plain.theta[:10]) / scale) < 1e-4
    assert not any("the pose noise biased" in w for w in corr.warnings)


@pytest.mark.parametrize("pairs", [0, -1])
def test_no_pairs_no_correction(tmp_path, monkeypatch, pairs):
    """``PAIRS`` 0 (or below) switches the correction off: no shift, no note."""
    from cdprid.identify._currents_pose import pose_noise_shift

    assert pose_noise_shift(None, None, None, None, 10, None, None,
                            {"position_m": 1e-3}, pairs=pairs) is None
