"""Differentiator tuning (cdprid.tuning, cdprid tune) and the higher-order SIHD."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from cdprid import tuning as T
from cdprid.cli import parse_params, build_parser, main
from cdprid.differentiators import METHODS, differentiate
from cdprid.geometry import robot_from_dict
from cdprid.io import write_dataset
from cdprid.sihd_high import differentiate_high, poly_gains, sihdn_channel
from conftest import ROBOT_CRAFT

SHORT = T.circle_signal(duration=12.0)


def _noisy(sig, std, seed):
    return sig.position + std * np.random.default_rng(seed).standard_normal(sig.position.shape)


@pytest.fixture(scope="module")
def noisy_ds(tmp_path_factory):
    """A 20 s circle dataset with 0.3 mm position noise, no truth needed by tune."""
    robot = robot_from_dict(ROBOT_CRAFT)
    sig = T.circle_signal(radius=0.2, duration=20.0)
    pos = _noisy(sig, 3e-4, 7)
    tau = 20 + np.random.default_rng(0).normal(0, 0.5, (sig.t.size, 8))
    return write_dataset(tmp_path_factory.mktemp("tune") / "ds", robot, sig.t, pos, sig.t, tau)


def test_internal_equations_equal_differentiate():
    y = _noisy(SHORT, 5e-4, 0)
    for m in ("sihd2-cascade", "sihd3"):
        p = dict(METHODS[m].params)
        th = jnp.asarray(T.theta_from_params(m, p))
        lams, alpha = T._theta_to_gains(m, th)
        a = jax.vmap(lambda c, m=m, lams=lams, alpha=alpha: T._acc_channel(m, c, 0.01, lams, alpha),
                     1, 1)(jnp.asarray(y))
        _, a_ref = differentiate(y, 0.01, m)
        assert np.max(np.abs(np.asarray(a) - a_ref)) < 1e-8 * max(1, np.abs(a_ref).max())


def test_sihd5_exact_on_quartics_and_n3_is_sihd3():
    t = np.arange(800) * 0.01
    y = 0.3 + 0.1 * t - 0.2 * t**2 + 0.05 * t**3 - 0.004 * t**4
    acc = -0.4 + 0.3 * t - 0.048 * t**2
    gains = {f"lambda{q}": v for q, v in enumerate(poly_gains(10.0, 5), 1)}
    _, a = differentiate_high(y, 0.01, "sihd5", alpha=1.0, **gains)
    assert np.max(np.abs(a - acc)[400:]) < 1e-6
    yn = _noisy(SHORT, 5e-4, 1)[:, 0]
    _, a3 = differentiate(yn, 0.01, "sihd3")
    _, a3n = sihdn_channel(jnp.asarray(yn), 0.01, (45.0, 675.0, 3375.0), 0.95, 1.0)
    assert np.max(np.abs(np.asarray(a3n) - a3)) < 1e-9


def test_gradient_through_scan_matches_finite_differences():
    sig = T.circle_signal(duration=3.0)
    sig = T.TrainingSignal(sig.t, sig.dt, sig.position, sig.acceleration, "c", t0=1.0)
    Y, acc = T._stack_train(sig, 5e-4, [0])
    args = (jnp.asarray(Y), jnp.asarray(acc), jnp.asarray(sig.mask.astype(float)),
            jnp.asarray(0.01))
    for m in ("sihd3", "sihd2-cascade"):
        f = jax.jit(T.sihd_loss_fn(m))
        p = dict(METHODS[m].params, alpha=0.97)
        th = jnp.asarray(T.theta_from_params(m, p))
        g = np.asarray(jax.grad(f)(th, args))
        assert np.all(np.isfinite(g))
        eps = 1e-5
        for i in range(th.size):
            e = jnp.zeros_like(th).at[i].set(eps)
            fd = (float(f(th + e, args)) - float(f(th - e, args))) / (2 * eps)
            assert abs(fd - g[i]) <= 1e-4 * abs(fd) + 1e-9 * float(f(th, args)), (m, i, fd, g[i])


def test_tuned_cascade_beats_paper_gains_on_heldout_seeds():
    res = T.tune("sihd2-cascade", 5e-4, signal=SHORT, train_seeds=[0, 1],
                 test_seeds=[50, 51, 52], max_steps=15)
    assert res.test_rmse < 0.8 * res.paper_rmse
    paper = T.evaluate("sihd2-cascade", T.PAPER_PARAMS, SHORT, 5e-4, [50, 51, 52]).mean()
    assert np.isclose(paper, res.paper_rmse)
    # held-out seeds within 10 % of the training ones: no overfitting to the noise draw
    assert abs(res.test_rmse - res.train_rmse) < 0.1 * res.train_rmse
    assert 0.5 < res.params["alpha"] <= 1 and res.params["mu"] == 1.0


def test_baseline_grid_tuning_improves_on_defaults():
    res = T.tune_baseline("euler-filtfilt", 1e-3, signal=SHORT, train_seeds=[0],
                          test_seeds=[60, 61], n_grid=9, refine=5)
    assert res.test_rmse <= res.default_rmse * 1.001
    assert 0.3 <= res.params["cutoff_hz"] <= 20


def _cli_tune(tmp_path, *extra):
    out = tmp_path / "tune.json"
    rc = main(["tune", "--quiet", "--json", str(out), "--duration", "8", "--seeds", "1", *extra])
    return rc, out


def test_cli_noise_std_roundtrip_through_differentiate_and_identify(tmp_path, noisy_ds, capsys):
    rc, out = _cli_tune(tmp_path, "--noise-std", "5e-4", "--method", "sihd3", "--max-steps", "3")
    assert rc == 0
    res = json.loads(out.read_text())
    assert {"method", "params", "noise_std", "train_rmse", "test_rmse", "paper_rmse"} <= set(res)
    assert res["method"] == "sihd3" and res["noise_std"] == 5e-4
    params = parse_params(str(out))  # the whole file is accepted as --params
    assert params == res["params"]
    y = _noisy(SHORT, 5e-4, 3)
    d1, d2 = differentiate(y, 0.01, "sihd3", **params)
    assert np.all(np.isfinite(d2))
    capsys.readouterr()
    assert main(["identify", str(noisy_ds), "--differentiator", "sihd3",
                 "--params", str(out)]) == 0
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    if "differentiate" in sub.choices:
        opts = {o for a in sub.choices["differentiate"]._actions for o in a.option_strings}
        if {"--method", "--params", "--out"} <= opts:
            d = tmp_path / "d.csv"
            rc = main(["differentiate", str(noisy_ds / "pose.csv"), "--method", "sihd3",
                       "--params", str(out), "--out", str(d)])
            assert rc == 0 and d.is_file()


def test_cli_dataset_estimates_noise_without_truth(tmp_path, noisy_ds):
    rc, out = _cli_tune(tmp_path, "--dataset", str(noisy_ds), "--method", "sihd3",
                        "--train-signal", "dataset", "--max-steps", "2")
    assert rc == 0
    res = json.loads(out.read_text())
    assert abs(res["noise_std"] - 3e-4) < 0.15 * 3e-4
    assert res["signal"] == "dataset (smoothed)" and res["method"] == "sihd3"


@pytest.mark.parametrize("argv", [
    [],
    ["--noise-std", "5e-4", "--dataset", "x"],
    ["--noise-std", "-1"],
    ["--noise-std", "5e-4", "--method", "nope"],
    ["--noise-std", "5e-4", "--train-signal", "dataset"],
    ["--noise-std", "5e-4", "--seeds", "0"],
    ["--dataset", "/nonexistent/dir"],
])
def test_cli_bad_input_exit_2(argv, capsys):
    assert main(["tune", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cdprid: error:")


def test_acceleration_response_matches_the_butterworth_and_flags_resonance():
    """euler-filtfilt: gain |H|^2 of the 4 Hz Butterworth, zero phase; kalman resonates."""
    from scipy import signal as sps

    from cdprid.tuning import acceleration_response

    f = np.array([0.2, 1.0, 2.0, 4.0])
    r = acceleration_response("euler-filtfilt", {"cutoff_hz": 4.0, "order": 2}, freqs_hz=f)
    b, a = sps.butter(2, 4.0, fs=100.0)
    _, h = sps.freqz(b, a, worN=f, fs=100.0)
    # the central second difference adds its own sinc-like factor: small below 4 Hz
    np.testing.assert_allclose(r.gain, np.abs(h) ** 2, rtol=0.02)
    np.testing.assert_allclose(r.phase_deg, 0.0, atol=0.5)
    assert r.ok and 1.0 <= r.bandwidth_hz <= 2.0
    k = acceleration_response("kalman", {"q": 0.3, "r": 2.5e-7})
    assert not k.ok and k.gain_max_above > 1.5
    j = k.as_json()
    assert j["within_bounds"] is False and len(j["gain"]) == len(j["freqs_hz"])


def test_cli_tune_reports_response_and_refuses_to_overwrite(tmp_path, capsys):
    import json

    from cdprid.cli import main

    out = tmp_path / "t.json"
    assert main(["tune", "--noise-std", "3e-4", "--method", "euler-filtfilt", "--json", str(out),
                 "--quiet"]) == 0
    d = json.loads(out.read_text())
    assert d["frequency_response"]["within_bounds"] is True and d["warnings"] == []
    assert (tmp_path / "t.response.png").is_file()
    assert main(["tune", "--noise-std", "3e-4", "--method", "euler-filtfilt", "--json", str(out),
                 "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
