"""Differentiator tuning (cdprid.tuning._tuning, cdprid tune) and the higher-order SIHD."""

from __future__ import annotations

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import cdprid.tuning as T
from cdprid.cli import build_parser, main, parse_params
from cdprid.io import write_dataset
from cdprid.model import robot_from_dict
from cdprid.signal import METHODS, differentiate, differentiate_high, poly_gains, sihdn_channel
from cdprid.tuning import _response as T_response
from cdprid.tuning import _sihd_params as T_sihd_params
from cdprid.tuning import _tuning as T_tuning
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
        lams, alpha = T_sihd_params._theta_to_gains(m, th)
        a = jax.vmap(lambda c, m=m, lams=lams, alpha=alpha:
                     T_sihd_params._acc_channel(m, c, 0.01, lams, alpha),
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
    Y, acc = T_tuning._stack_train(sig, 5e-4, [0])
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


@pytest.mark.slow
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
    rc, out = _cli_tune(tmp_path, "--noise-std", "5e-4", "--method", "sihd3", "--max-steps", "3",
                        "--train-signal", "circle")
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


# ----------------------------------------------------------------------------- response bounds

C8 = T.circle_signal(duration=8.0)


def _impulse_response_H(method, params, f, dt=0.01, n=4000):
    """Oracle: scipy.signal.freqz of the simulated impulse response (linear filters only)."""
    from scipy import signal as sps

    y = np.zeros(n)
    y[0] = 1.0
    # the SIHD starts at rest on y[0]: feed the impulse after a zero so the state starts at 0
    y = np.r_[0.0, y]
    _, a = T.any_differentiate(y, dt, method, **params)
    _, h = sps.freqz(a[1:], worN=np.asarray(f), fs=1.0 / dt)
    return h / -(2 * np.pi * np.asarray(f)) ** 2


@pytest.mark.parametrize("method", ["sihd2-cascade", "sihd3", "sihd5"])
def test_linear_response_matches_freqz_and_sinusoids(method):
    p = {**T.default_params(method), "alpha": 1.0}
    f = np.array([0.1, 0.5, 1.0, 3.0, 10.0])  # 0.1 Hz: 2 periods in the fitted half
    with jax.enable_x64(True):
        lams = [p[f"lambda{q}"] for q in range(1, 6) if f"lambda{q}" in p]
        H = np.asarray(T.sihd_linear_response(method, lams, 0.01, f))
    Hz = _impulse_response_H(method, p, f)
    np.testing.assert_allclose(H, Hz, rtol=1e-6, atol=1e-9)
    r = T.acceleration_response(method, p, freqs_hz=f, duration_s=40.0)
    np.testing.assert_allclose(r.gain, np.abs(Hz), rtol=1e-6)
    np.testing.assert_allclose(r.phase_deg, np.degrees(np.angle(Hz)), atol=1e-4)


def test_noise_gain_is_parseval_of_the_impulse_response():
    p = {**T.default_params("sihd3"), "alpha": 1.0}
    y = np.r_[0.0, 1.0, np.zeros(3000)]
    _, a = T.any_differentiate(y, 0.01, "sihd3", **p)
    with jax.enable_x64(True):
        g = float(T_response._noise_gain("sihd3", [p["lambda1"], p["lambda2"], p["lambda3"]], 0.01))
    assert np.isclose(g, np.sum(a[1:] ** 2), rtol=1e-6)


def test_constrained_tuning_of_resonant_gains_complies_by_an_oracle():
    """From lightly damped (resonant) sihd3 gains, the constrained BFGS ends within the bounds;
    the reported dense-grid response equals scipy freqz of the tuned filter's impulse
    response."""
    om, ze = 6.0, 0.1
    lam = np.real(np.poly([-om, -om * ze + 1j * om * np.sqrt(1 - ze**2),
                           -om * ze - 1j * om * np.sqrt(1 - ze**2)]))[1:]
    start = {f"lambda{q + 1}": float(lam[q]) for q in range(3)} | {"alpha": 1.0, "mu": 1.0}
    b = T.ResponseBounds(0.4)
    r0 = T.acceleration_response("sihd3", start, bounds=b)
    assert not r0.ok and r0.max_gain > 2
    res = T.tune("sihd3", 5e-4, signal=C8, train_seeds=[0], test_seeds=[9], max_steps=40,
                 bounds=b, init=start)
    assert res.params["alpha"] == 1.0
    r = res.response
    Hz = _impulse_response_H("sihd3", res.params, r.freqs_hz)
    np.testing.assert_allclose(r.gain, np.abs(Hz), rtol=1e-5, atol=1e-6)
    below = r.freqs_hz <= 0.4
    assert r.ok and res.warnings == [], r.violations
    assert np.max(np.abs(np.abs(Hz[below]) - 1)) <= b.gain_tol
    assert np.max(np.abs(np.degrees(np.angle(Hz[below])))) <= b.phase_max_deg
    assert np.max(np.abs(Hz[~below])) <= b.gain_max_above
    j = res.as_json()
    assert j["within_bounds"] is True and j["bandwidth_hz"] == 0.4
    assert j["max_gain"] == pytest.approx(np.max(np.abs(Hz)), rel=1e-5)


@pytest.mark.slow
def test_constraint_makes_a_resonant_tuning_comply():
    """Unconstrained, sihd5 tuned on one circle resonates; constrained, it complies."""
    b = T.ResponseBounds(0.5)
    free = T.tune("sihd5", 5e-4, signal=C8, train_seeds=[0, 1], test_seeds=[9], max_steps=40,
                  bounds=b, constrain=False)
    assert not free.response.ok and free.response.max_gain > 1.3
    assert free.warnings and "not within" in free.warnings[0]
    con = T.tune("sihd3", 5e-4, signal=C8, train_seeds=[0, 1], test_seeds=[9], max_steps=40,
                 bounds=b, init=free.params)
    assert con.response.ok and con.as_json()["within_bounds"] is True


def test_infeasible_bounds_are_reported_not_claimed(tmp_path, capsys):
    b = T.ResponseBounds(3.0, gain_tol=0.01, phase_max_deg=0.5)
    res = T.tune_baseline("euler-butter-causal", 5e-4, signal=C8, train_seeds=[0],
                          test_seeds=[9], n_grid=5, refine=2, bounds=b)
    j = res.as_json()
    assert j["within_bounds"] is False and j["frequency_response"]["within_bounds"] is False
    assert len(j["warnings"]) == 1 and "phase" in j["warnings"][0]
    assert j["max_phase_below_bandwidth_deg"] > 0.5
    out = tmp_path / "t.json"
    assert main(["tune", "--noise-std", "5e-4", "--method", "euler-butter-causal",
                 "--train-signal", "circle", "--duration", "8", "--seeds", "1",
                 "--bandwidth", "3", "--phase-max", "0.5", "--json", str(out), "--quiet"]) == 0
    d = json.loads(out.read_text())
    assert d["within_bounds"] is False and d["stated_bandwidth_hz"] == 3.0
    assert d["bandwidth_source"] == "--bandwidth" and d["response_bounds"]["phase_max_deg"] == 0.5
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("warning:")]
    assert len(err) == 1 and "not within the acceleration-response bounds" in err[0]


def test_levant_response_is_a_describing_response():
    r = T.acceleration_response("levant", {"L": 20.0}, freqs_hz=[0.2, 0.5], bounds=None)
    j = r.as_json()
    assert r.linear is False and "describing" in j["response_kind"]
    assert r.accel_amplitude == T.NONLINEAR_ACCEL_AMPLITUDE


def test_content_bandwidth_and_families():
    for f in (0.2, 0.5):
        bw = T.content_bandwidth([T.circle_signal(freq_hz=f, duration=30.0)])
        assert f <= bw <= f + 0.15
    tr, ho = T.trajectory_family("train", duration=10.0), T.trajectory_family("heldout",
                                                                               duration=10.0)
    assert not {s.name for s in tr} & {s.name for s in ho}
    assert len(ho) == len(T.HELDOUT_FAMILY) + 2
    for s in tr[:2] + ho[-2:-1]:  # accelerations are the positions' second derivative
        fd = (s.position[2:] - 2 * s.position[1:-1] + s.position[:-2]) / s.dt**2
        assert np.max(np.abs(fd - s.acceleration[1:-1])) < 1e-3 * np.abs(s.acceleration).max()
    freqs = sorted(r[0] for r in T.TRAIN_FAMILY)
    assert freqs[0] <= 0.1 and freqs[-1] >= 0.8


def test_cli_dataset_trains_on_its_own_signal_by_default(tmp_path, noisy_ds):
    rc, out = _cli_tune(tmp_path, "--dataset", str(noisy_ds), "--method", "euler-butter-causal")
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["signal"] == "dataset (smoothed)"
    assert d["bandwidth_source"].startswith("99 %") and 0.1 <= d["bandwidth_hz"] <= 1.0
    assert {"within_bounds", "max_gain", "peak_frequency_hz", "phase_at_stated_bandwidth_deg",
            "max_gain_error_below_bandwidth", "heldout", "heldout_rmse"} <= set(d)


@pytest.mark.parametrize("argv", [
    ["--noise-std", "5e-4", "--bandwidth", "0.01"],
    ["--noise-std", "5e-4", "--bandwidth", "80"],
    ["--noise-std", "5e-4", "--gain-tol", "0.7"],
    ["--noise-std", "5e-4", "--phase-max", "120"],
    ["--noise-std", "5e-4", "--gain-max-above", "0.9"],
])
def test_cli_bad_bound_options_exit_2(argv, capsys):
    assert main(["tune", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cdprid: error:")


def test_tune_result_is_frozen_and_carries_one_status():
    """Issue 22: results are immutable and every solver reports the package's one status."""
    import dataclasses

    import optimistix as optx

    from cdprid.base import Status
    from cdprid.tuning._tuning import TuneResult

    assert dataclasses.fields(TuneResult) and TuneResult.__dataclass_params__.frozen
    assert Status.of_optimistix(optx.RESULTS.successful) is Status.CONVERGED
    assert Status.of_optimistix(optx.RESULTS.nonlinear_max_steps_reached) is Status.MAX_STEPS
    assert Status.of_optimistix(optx.RESULTS.nonlinear_divergence) is Status.FAILED
    assert Status.CONVERGED.ok and not Status.MAX_STEPS.ok
    assert Status.MAX_STEPS.value == "max steps"
