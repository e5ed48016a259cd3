"""Episodes flagged online (issue 38 item 5): a push is flagged as it happens and kept out of
the recursive least squares; a payload step is reported as a step and tracked; clean data
give nothing. Data from the simulator's ``external_wrench`` effect (the cables take the push)
and from two simulations of different payloads joined end to end."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cdprid.cli import main
from cdprid.effects import Effect
from cdprid.identify import online_identify
from cdprid.model import InertialParameters, craft_like_robot, craft_like_truth, preset
from cdprid.simulation import simulate, write_simulation

PUSH = (7.0, 8.0, [12.0, 0.0, 16.0])  # 20 N for 1 s, partly vertical: it pulls the mass


@pytest.fixture(scope="module")
def robot():
    return craft_like_robot()


@pytest.fixture(scope="module")
def traj(robot):
    return preset("paper-orbits", robot, duration=14.0)


def _signals(res):
    n = res.pose_t.size
    return {"t": res.pose_t, "position": res.position,
            "quaternion": np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), "tension": res.tension}


@pytest.fixture(scope="module")
def clean(robot, traj):
    return _signals(simulate(robot, traj, seed=3))


@pytest.fixture(scope="module")
def pushed_sim(robot, traj):
    a, b, f = PUSH
    eff = [Effect("external_wrench", {"start_s": a, "end_s": b, "force_N": f,
                                      "moment_Nm": [0.0, 0.0, 0.0]})]
    return simulate(robot, traj, seed=3, effects=eff)


@pytest.fixture(scope="module")
def pushed(pushed_sim):
    return _signals(pushed_sim)


@pytest.fixture(scope="module")
def clean_plain(robot, clean):
    """The clean recording identified online without the episode detector."""
    return online_identify(clean, robot)


def test_clean_data_give_no_episode(robot, clean, clean_plain):
    res = online_identify(clean, robot, episodes=True)
    assert res.episodes == ()
    assert res.used[-1]  # never frozen
    # the detector changes nothing on clean data: the same estimate as without it
    np.testing.assert_allclose(res.x[-1], clean_plain.x[-1], rtol=1e-12, atol=1e-12)


def test_push_flagged_and_kept_out_of_the_update(robot, clean, clean_plain, pushed):
    ref = clean_plain.x[-1, 0]
    frozen = online_identify(pushed, robot, episodes=True)
    free = online_identify(pushed, robot, episodes={"freeze": False})
    (ep,) = frozen.episodes
    assert ep.kind == "external_wrench"
    assert abs(ep.start_s - PUSH[0]) <= 0.2
    assert PUSH[1] <= ep.end_s <= PUSH[1] + 1.0  # the matched filter's tail
    # the push's direction: along (12, 0, 16) (the residual is minus the push)
    d = np.asarray(ep.force_N) / np.linalg.norm(ep.force_N)
    assert d @ np.array([0.6, 0.0, 0.8]) > 0.95
    # impulse: 20 N over 1 s less half of the two 0.1 s ramps, within the filter's tail
    assert 0.8 * 19.0 <= np.linalg.norm(ep.detail["impulse_Ns"]) <= 1.05 * 19.0
    # frozen during the episode: the rows are out of the fit
    t = frozen.t
    inside = (t > ep.start_s + 0.2) & (t < ep.end_s)
    assert not frozen.used[inside].any() and free.used[inside].all()
    # the mass is not pulled: frozen within a fifth of the unfrozen pull
    pull_free, pull_frozen = abs(free.x[-1, 0] - ref), abs(frozen.x[-1, 0] - ref)
    assert pull_free > 0.05  # the push does pull the mass when it is fitted
    assert pull_frozen < 0.2 * pull_free
    # reporting alone (freeze=False) flags the same episode
    assert [e.kind for e in free.episodes] == ["external_wrench"]
    assert abs(free.episodes[0].start_s - ep.start_s) < 0.05


def test_payload_step_reported_and_tracked(robot, traj, clean):
    truth = craft_like_truth()
    heavy = InertialParameters(truth.mass + 2.5, truth.com * 0.8, truth.inertia_com)
    b = _signals(simulate(robot, traj, params=heavy, seed=4))
    # the payload grows mid-recording, the platform on the same path: the first half of the
    # clean recording, then the second half of the heavier one (the same length as the clean
    # recording, so the scans compiled by the tests above are reused)
    n1 = clean["t"].size // 2
    sig = {k: np.concatenate([clean[k][:n1], b[k][n1:]]) for k in clean}
    t_step = sig["t"][n1]
    res = online_identify(sig, robot, episodes=True)
    (ep,) = res.episodes
    assert ep.kind == "payload_step"
    assert abs(ep.start_s - t_step) <= 0.2
    assert abs(ep.detail["mass_change_kg"] - 2.5) < 0.1
    m_new = float(heavy.mass)
    assert abs(res.x[n1 - 1, 0] - float(truth.mass)) < 0.01 * float(truth.mass)
    after = sig["t"] >= t_step + 5.0  # tracked within 5 s
    assert np.all(np.abs(res.x[after, 0] - m_new) < 0.01 * m_new)
    # without the restart (reported only) the growing memory does not track (and the
    # discrepancy keeps being reported)
    stuck = online_identify(sig, robot, episodes={"freeze": False})
    assert stuck.episodes[0].kind == "payload_step"
    assert abs(stuck.x[-1, 0] - m_new) > 0.05 * m_new


def test_cli_online_json_has_the_episodes(pushed_sim, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    ds = write_simulation(pushed_sim, tmp_path / "ds")
    out = tmp_path / "res.json"
    assert main(["identify", str(ds), "--online", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "episode: external_wrench" in text and "update frozen" in text
    data = json.loads(out.read_text())
    (ep,) = data["episodes"]
    assert set(ep) >= {"start_s", "end_s", "kind", "p_value", "force_N", "moment_Nm", "size_N",
                       "size_Nm", "impulse_Ns"}
    assert ep["kind"] == "external_wrench" and ep["p_value"] is None
    assert abs(ep["start_s"] - PUSH[0]) <= 0.2
    m_frozen = data["parameters"]["m"]["value"]
    out2 = tmp_path / "kept.json"
    assert main(["identify", str(ds), "--online", "--keep-episodes", "--json", str(out2)]) == 0
    kept = json.loads(out2.read_text())
    assert len(kept["episodes"]) == 1 and any("--keep-episodes" in n for n in kept["notes"])
    assert abs(kept["parameters"]["m"]["value"] - 9.88) > abs(m_frozen - 9.88)
