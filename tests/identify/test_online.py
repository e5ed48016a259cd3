"""Online identification (streaming SIHD + recursive least squares): oracles and the CLI."""

from __future__ import annotations

import argparse
import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from cdprid.base import UserError
from cdprid.cli import main, run_online_cli
from cdprid.core import estimate_motion, least_squares
from cdprid.identify import (
    OnlineSample,
    online_identify,
    online_init,
    online_step,
    recursive_least_squares,
)
from cdprid.io import align, read_dataset
from cdprid.model import (
    InertialParameters,
    craft_like_robot,
    craft_like_truth,
    preset,
    regressor_full,
    regressor_translation,
    wrench_matrix,
)
from cdprid.signal import differentiate
from cdprid.simulation import SensorNoise, simulate, write_simulation


@pytest.fixture(scope="module")
def robot():
    return craft_like_robot()


@pytest.fixture(scope="module")
def sim_clean(robot):
    return simulate(robot, preset("paper-orbits", robot, duration=14.0), noise=SensorNoise.off())


@pytest.fixture(scope="module")
def sim_noisy(robot):
    return simulate(robot, preset("paper-orbits", robot, duration=14.0), seed=3)


def _signals(res):
    n = res.pose_t.size
    q = res.quaternion if res.quaternion is not None else np.tile([1.0, 0, 0, 0], (n, 1))
    return {"t": res.pose_t, "position": res.position, "quaternion": q, "tension": res.tension}


def _exact_rows(robot, res, model="translation"):
    """Rows from the TRUE motion (exact derivatives) and the measured wrench."""
    m = res.motion
    g = robot.gravity

    def one(p, q, a, om, al, tau):
        from cdprid.model import quat_to_matrix

        R = quat_to_matrix(q)
        A = (regressor_translation(R, a, g) if model == "translation"
             else regressor_full(R, a, om, al, g))
        return A, wrench_matrix(robot, p, R) @ tau

    A, y = jax.jit(jax.vmap(one))(*(jnp.asarray(v) for v in (m.p, m.q, m.a, m.omega, m.alpha,
                                                              res.tension)))
    return np.asarray(A), np.asarray(y)


# ----------------------------------------------------------------------------- RLS kernel


@pytest.mark.parametrize("forgetting", [1.0, 0.99])
def test_rls_equals_weighted_batch_least_squares(forgetting, rng):
    n, p = 400, 4
    A = rng.normal(size=(n, 6, p)) * np.array([10.0, 1.0, 1.0, 0.3])
    x_true = np.array([9.9, -0.06, 0.02, -1.06])
    y = np.einsum("nrp,p->nr", A, x_true) + 0.3 * rng.normal(size=(n, 6))
    r = recursive_least_squares(A, y, forgetting=forgetting, prior_weight=0.0)
    # oracle: batch QR least squares on the same rows, sample k weighted sqrt(lambda^(n-1-k))
    w = np.repeat(np.sqrt(forgetting ** np.arange(n - 1, -1, -1)), 6)
    b = least_squares(A.reshape(-1, p), y.reshape(-1), weights=w)
    np.testing.assert_allclose(r.x[-1], b.x, rtol=1e-8, atol=1e-10)
    if forgetting == 1.0:
        np.testing.assert_allclose(r.sigma_rho[-1], b.sigma_rho, rtol=1e-8)
        np.testing.assert_allclose(r.sigma[-1], b.std_iid, rtol=1e-8)
        np.testing.assert_allclose(r.cov, b.cov_iid, rtol=1e-7, atol=1e-14)
    # every intermediate estimate is the batch estimate of the rows seen so far
    k = 37
    bk = least_squares(A[:k].reshape(-1, p), y[:k].reshape(-1),
                       weights=np.repeat(np.sqrt(forgetting ** np.arange(k - 1, -1, -1)), 6))
    np.testing.assert_allclose(r.x[k - 1], bk.x, rtol=1e-8, atol=1e-10)


def test_rls_with_prior_starts_at_prior(rng):
    A = rng.normal(size=(5, 6, 4))
    y = rng.normal(size=(5, 6))
    x0 = np.array([10.0, 0.0, 0.0, -1.0])
    r = recursive_least_squares(A * 0.0, y * 0.0, x0=x0, prior_weight=1.0)
    np.testing.assert_allclose(r.x, np.tile(x0, (5, 1)), atol=1e-14)


# ----------------------------------------------------------------------------- data path


@pytest.fixture(scope="module")
def noisy_plain(robot, sim_noisy):
    """The noisy recording identified online with the defaults (no episode detector)."""
    return online_identify(_signals(sim_noisy), robot)


def test_online_motion_equals_batch_differentiator(noisy_plain, sim_noisy):
    res = noisy_plain
    v, a = differentiate(sim_noisy.position, 0.01, method="sihd2-cascade")
    np.testing.assert_allclose(res.velocity, v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.acceleration, a, rtol=0, atol=1e-12)


def test_online_batch_identity_on_the_same_rows(robot, sim_noisy):
    """lambda = 1: the final online estimate is the batch LS of the rows it produced."""
    res = online_identify(_signals(sim_noisy), robot)
    u = res.used
    b = least_squares(res.A[u].reshape(-1, 4), res.y[u].reshape(-1))
    np.testing.assert_allclose(res.x_final, b.x, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(res.std_final, b.std_iid, rtol=1e-6)
    np.testing.assert_allclose(res.cond, b.cond, rtol=1e-6)
    np.testing.assert_allclose(res.cond_scaled, b.cond_scaled, rtol=1e-6)
    assert res.n_samples == u.sum() == len(u) - 100  # 1 s warm-up at 100 Hz


def test_exact_rows_recover_truth(robot, sim_clean):
    A, y = _exact_rows(robot, sim_clean)
    r = recursive_least_squares(A, y)
    x_true = np.asarray(craft_like_truth().vector("translation"))
    np.testing.assert_allclose(r.x[-1], x_true, rtol=1e-7, atol=1e-9)
    assert r.sigma_rho[-1] < 1e-4  # tension distribution solved to ~1e-6 N


def test_online_noise_free_matched_filter_close_to_truth(robot, sim_clean):
    """The causal SIHD pipeline on noise-free data: the matched wrench filter removes the
    lag bias of m zG (to within the SIHD's nonlinearity)."""
    x_true = np.asarray(craft_like_truth().vector("translation"))
    good = online_identify(_signals(sim_clean), robot).x_final
    bad = online_identify(_signals(sim_clean), robot, wrench_filter="none").x_final
    np.testing.assert_allclose(good, x_true, rtol=0.03, atol=2e-3)
    # short ramped orbits: m zG off by ~2 % with the matched filter, ~40 % without
    assert abs(bad[3] - x_true[3]) > 5 * abs(good[3] - x_true[3])


@pytest.mark.slow  # over 20 s on 2 cores: with the slow tests (CI runs them all)
def test_full_model_angular_rates_match_batch_motion(robot):
    tr = preset("paper-orbits", robot, duration=12.0, rotation_amplitude=0.05)
    sim = simulate(robot, tr, noise=SensorNoise.off())
    sig = {"t": sim.pose_t, "position": sim.position, "quaternion": sim.quaternion,
           "tension": sim.tension}
    res = online_identify(sig, robot, model="full")
    from cdprid.io import AlignedSignals

    al = AlignedSignals(sim.pose_t, 0.01, sim.position, sim.quaternion, sim.tension, True, False)
    mot = estimate_motion(al, "sihd2-cascade", angular=True)
    np.testing.assert_allclose(res.omega, mot.omega, atol=1e-11)
    np.testing.assert_allclose(res.alpha, mot.alpha, atol=1e-9)
    assert res.x.shape == (sim.pose_t.size, 10) and np.all(np.isfinite(res.x_final))
    # exact-derivative rows of the rotating motion recover all 10 parameters
    A, y = _exact_rows(robot, sim, "full")
    r = recursive_least_squares(A, y)
    np.testing.assert_allclose(r.x[-1], np.asarray(craft_like_truth().vector("full")),
                               rtol=1e-5, atol=1e-6)


# ----------------------------------------------------------------------------- tracking


@pytest.fixture(scope="module")
def sim_heavy(robot):
    """The noisy recording's path with a payload 2.5 kg heavier (its centre of mass 20 % closer
    to P): the second half of a mid-recording payload step."""
    truth = craft_like_truth()
    heavy = InertialParameters(truth.mass + 2.5, truth.com * 0.8, truth.inertia_com)
    return heavy, simulate(robot, preset("paper-orbits", robot, duration=14.0), params=heavy,
                           seed=4)


def _payload_step(sim_noisy, sim_heavy):
    """The payload grows mid-recording, the platform on the same path: the first half of the
    noisy recording, then the second half of the heavier one (the recordings' length, so the
    scans compiled by the other tests of the module are reused). Returns the signals and the
    index of the step."""
    a, b = _signals(sim_noisy), _signals(sim_heavy[1])
    n1 = a["t"].size // 2
    return {k: np.concatenate([a[k][:n1], b[k][n1:]]) for k in a}, n1


def test_mass_step_tracked_with_forgetting(robot, sim_noisy, sim_heavy):
    truth = craft_like_truth()
    sig, n1 = _payload_step(sim_noisy, sim_heavy)
    m_new = float(sim_heavy[0].mass)
    track = online_identify(sig, robot, forgetting=0.995)
    m = track.x[:, 0]
    assert abs(m[n1 - 1] - float(truth.mass)) < 0.02 * float(truth.mass)  # before the step
    assert abs(m[-1] - m_new) < 0.02 * m_new
    # follows within a few seconds (memory dt / (1 - lambda) = 2 s): from 6 s after the step
    assert np.all(np.abs(m[n1 + 600:] - m_new) < 0.02 * m_new)
    # growing memory does not track: still far from the new mass at the end
    stuck = online_identify(sig, robot, forgetting=1.0).x[-1, 0]
    assert abs(stuck - m_new) > 0.05 * m_new


def test_excitation_flag_false_on_static_segment(robot, sim_noisy, rng):
    a = _signals(sim_noisy)
    n_static = 800
    hold = {
        "position": a["position"][-1] + 2e-4 * rng.normal(size=(n_static, 3)),
        "quaternion": np.tile([1.0, 0, 0, 0], (n_static, 1)),
        "tension": a["tension"][-1] + 0.5 * rng.normal(size=(n_static, 8)),
    }
    sig = {k: np.concatenate([a[k], hold[k]]) for k in hold}
    n1 = a["t"].size
    sig["t"] = np.arange(n1 + n_static) * 0.01
    res = online_identify(sig, robot, forgetting=0.995)
    mid = slice(300, n1 - 100)
    assert res.excitation_ok[mid].mean() > 0.9
    assert not res.excitation_ok[n1 + 400:].any()  # 4 s after the motion stopped
    # covariance wind-up with forgetting: the m zG sigma grows during the static segment
    assert res.sigma[-1, 3] > 5 * res.sigma[n1 - 1, 3]


# ----------------------------------------------------------------------------- step / scan


def test_scan_equals_python_loop_and_no_recompilation(robot, sim_noisy):
    n = 160
    a = _signals(sim_noisy)
    sig = {k: v[:n] for k, v in a.items()}
    ref = online_identify(sig, robot, forgetting=0.99, warmup=0.5)
    st = online_init(robot, 0.01, forgetting=0.99, warmup=0.5)
    outs = []
    for k in range(n):
        st, o = online_step(st, OnlineSample(jnp.asarray(sig["position"][k]),
                                             jnp.asarray(sig["quaternion"][k]),
                                             jnp.asarray(sig["tension"][k])))
        outs.append(o)
        if k == 1:
            size = online_step._cache_size()
    assert online_step._cache_size() == size  # compiled once, whatever the sample
    x = np.array([np.asarray(o.x) for o in outs])
    s = np.array([np.asarray(o.sigma) for o in outs])
    acc = np.array([np.asarray(o.acceleration) for o in outs])
    np.testing.assert_allclose(x[50:], ref.x[50:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(s[60:], ref.sigma[60:], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(acc, ref.acceleration, rtol=0, atol=1e-12)


@pytest.mark.parametrize("model", ["translation", "full"])
def test_stepper_equals_online_step(robot, sim_noisy, model):
    from cdprid.identify import OnlineStepper

    n = 120
    sig = _signals(sim_noisy)
    st = online_init(robot, 0.01, model=model, forgetting=0.995, warmup=0.3)
    stepper = OnlineStepper(st)
    for k in range(n):
        smp = (sig["position"][k], sig["quaternion"][k], sig["tension"][k])
        st, ref = online_step(st, OnlineSample(*(jnp.asarray(v) for v in smp)))
        got = stepper.step(*smp)
        for name, r, g in zip(ref._fields, ref, got, strict=True):
            r = np.asarray(r)
            assert g.shape == r.shape and g.dtype == r.dtype, name
            np.testing.assert_allclose(g, r, rtol=1e-12, atol=1e-12, err_msg=name)
    with pytest.raises(ValueError, match="tension must have 8 values, got 3"):
        stepper.step(sig["position"][0], sig["quaternion"][0], [1.0, 2.0, 3.0])
    # the unpacked state is the online_step state
    for a, b in zip(jax.tree_util.tree_leaves(stepper.state), jax.tree_util.tree_leaves(st),
                    strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-12)


def test_bad_options_raise():
    r = craft_like_robot()
    with pytest.raises(ValueError, match="forgetting"):
        online_init(r, 0.01, forgetting=1.5)
    with pytest.raises(ValueError, match="wrench filter"):
        online_init(r, 0.01, wrench_filter="kalman")
    with pytest.raises(ValueError, match="model"):
        online_init(r, 0.01, model="inertia")


# ----------------------------------------------------------------------------- CLI


@pytest.fixture(scope="module")
def ds_path(sim_noisy, tmp_path_factory):
    return write_simulation(sim_noisy, tmp_path_factory.mktemp("online") / "ds")


def test_cli_identify_online(ds_path, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "res.json"
    assert main(["identify", str(ds_path), "--online", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "mzG" in text and "online RLS" in text
    data = json.loads(out.read_text())
    assert set(data) >= {"model", "parameters", "sigma_rho", "cond", "cond_scaled", "n_samples",
                         "online"}
    assert set(data["parameters"]["m"]) == {"value", "std", "rel_std_percent", "std_iid"}
    assert data["warnings"] == [] and data["covariance"] == "hac"
    assert abs(data["parameters"]["m"]["value"] - 9.88) < 0.05
    on = data["online"]
    assert on["forgetting"] == 1.0
    csv, png = tmp_path / on["csv"], tmp_path / on["figure"]
    assert csv.is_file() and png.is_file() and png.suffix == ".png"
    header = csv.read_text().splitlines()[0].split(",")
    assert header[:9] == ["t", "m", "mxG", "myG", "mzG", "sigma_m", "sigma_mxG", "sigma_myG",
                          "sigma_mzG"]
    # a second run never overwrites the CSV the user did not name
    before = csv.read_text()
    assert main(["identify", str(ds_path), "--online", "--json", str(out)]) == 2  # no --force
    assert main(["identify", str(ds_path), "--online", "--json", str(out), "--force"]) == 0
    on2 = json.loads(out.read_text())["online"]
    assert on2["csv"] != on["csv"] and csv.read_text() == before


@pytest.mark.slow  # over 20 s on 2 cores: with the slow tests (CI runs them all)
def test_online_json_has_the_batch_guards_when_auto_picks_the_model(robot, tmp_path, capsys,
                                                                    monkeypatch):
    """--model auto on rotating data: the online JSON names the model, rotation, inertia point
    and the same guard sentences as batch identify (excitation, physics), filled the same way."""
    from cdprid.identify import _batch as pipeline

    # cond_scaled is ~2 here: a threshold of 1 makes the excitation guard fire in both paths
    monkeypatch.setattr(pipeline, "COND_WARN", 1.0)
    sim = simulate(robot, preset("paper-orbits", robot, duration=11.0, rotation_amplitude=0.05),
                   seed=4)
    path = write_simulation(sim, tmp_path / "rot")
    b, o = tmp_path / "b.json", tmp_path / "o.json"
    assert main(["identify", str(path), "--json", str(b)]) == 0
    assert main(["identify", str(path), "--online", "--json", str(o),
                 "--out-csv", str(tmp_path / "o.csv")]) == 0
    capsys.readouterr()
    jb, jo = json.loads(b.read_text()), json.loads(o.read_text())
    assert jb["model"] == jo["model"] == "full"
    assert jo["rotation_deg"] == pytest.approx(jb["rotation_deg"]) and jo["rotation_deg"] > 1.0
    assert jo["inertia_about"] == jb["inertia_about"] == "P, platform frame"
    assert jo["wrench_filter"] == "matched"
    for j in (jb, jo):
        assert [w.split(":")[0] for w in j["warnings"]].count("too little excitation") == 1


def test_run_online_cli_forgetting_and_out_csv(ds_path, tmp_path, capsys):
    ds = read_dataset(ds_path)
    args = argparse.Namespace(model="translation", differentiator="sihd2-cascade", t_start=2.0,
                              t_end=None, json=str(tmp_path / "o.json"), forgetting=0.998,
                              out_csv=str(tmp_path / "traj.csv"))
    assert run_online_cli(ds, args, {}) == 0
    data = json.loads((tmp_path / "o.json").read_text())
    assert data["online"]["forgetting"] == 0.998
    assert (tmp_path / "traj.csv").is_file() and (tmp_path / "traj.png").is_file()
    n = len((tmp_path / "traj.csv").read_text().splitlines()) - 1
    assert n == len(align(ds, 2.0, None).t)
    args.differentiator = "savgol"
    with pytest.raises(UserError, match="not available on line"):
        run_online_cli(ds, args, {})


# ----------------------------------------------------------------------------- episodes
# Episodes flagged online (issue 38 item 5): a push is flagged as it happens and kept out of
# the recursive least squares; a payload step is reported as a step and tracked; clean data
# give nothing. Data from the simulator's ``external_wrench`` effect (the cables take the push)
# and from the payload step above (this was tests/identify/test_online_episodes.py; here the
# module's simulations and compiled scans are shared).

PUSH = (7.0, 8.0, [12.0, 0.0, 16.0])  # 20 N for 1 s, partly vertical: it pulls the mass


@pytest.fixture(scope="module")
def pushed_sim(robot):
    from cdprid.effects import Effect

    a, b, f = PUSH
    eff = [Effect("external_wrench", {"start_s": a, "end_s": b, "force_N": f,
                                      "moment_Nm": [0.0, 0.0, 0.0]})]
    return simulate(robot, preset("paper-orbits", robot, duration=14.0), seed=3, effects=eff)


@pytest.fixture(scope="module")
def pushed(pushed_sim):
    return _signals(pushed_sim)


def test_clean_data_give_no_episode(robot, sim_noisy, noisy_plain):
    clean = _signals(sim_noisy)
    res = online_identify(clean, robot, episodes=True)
    assert res.episodes == ()
    assert res.used[-1]  # never frozen
    # the detector changes nothing on clean data: the same estimate as without it
    np.testing.assert_allclose(res.x[-1], noisy_plain.x[-1], rtol=1e-12, atol=1e-12)


def test_push_flagged_and_kept_out_of_the_update(robot, noisy_plain, pushed):
    ref = noisy_plain.x[-1, 0]
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


def test_payload_step_reported_and_tracked(robot, sim_noisy, sim_heavy):
    truth = craft_like_truth()
    sig, n1 = _payload_step(sim_noisy, sim_heavy)
    t_step = sig["t"][n1]
    res = online_identify(sig, robot, episodes=True)
    (ep,) = res.episodes
    assert ep.kind == "payload_step"
    assert abs(ep.start_s - t_step) <= 0.2
    assert abs(ep.detail["mass_change_kg"] - 2.5) < 0.1
    m_new = float(sim_heavy[0].mass)
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
