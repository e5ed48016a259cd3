"""The output-error estimator of ``identify --source currents`` (``estimator="oe"``), against
the independent winch simulator (tests/identify/winch_sim.py: its own Newton-Euler, geometry,
tension distribution and drum torque balance)."""

from __future__ import annotations

import numpy as np
import pytest
from tests.identify import winch_sim

from cdprid.identify._currents_oe import _residual_fn, fit_output_error
from cdprid.model import SIX_SUSPENDED
from conftest import ROBOT_CRAFT

SIX = dict(SIX_SUSPENDED, home=[0.0, 0.0, 1.4])
EIGHT = dict(ROBOT_CRAFT, home=[0.0, 0.0, 1.3])
PLATFORM = (6.0, np.array([0.01, -0.005, -0.05]), np.diag([0.06, 0.07, 0.09]))


def _x_truth():
    m, s, IG = PLATFORM
    IP = IG + m * (s @ s * np.eye(3) - np.outer(s, s))
    return np.array([m, *(m * s), IP[0, 0], IP[0, 1], IP[0, 2], IP[1, 1], IP[1, 2], IP[2, 2]])


_wrench_x = winch_sim.wrench_of_parameters


def _exact(robot, tau_ref, seed=3, duration=12.0, rate=50.0):
    """Exact samples of the simulator: (G, I, L2, L1, S, C1, Nn, truth phi)."""
    rng = np.random.default_rng(seed)
    A = np.array([c["exit"] for c in robot["cable"]], float)
    b = np.array([c["anchor"] for c in robot["cable"]], float)
    m = len(A)
    path = winch_sim.Path(rng, robot["home"], [0.25, 0.25, 0.15], 0.08)
    t = np.arange(0.0, duration, 1.0 / rate)
    p, _, a, R, om, al = winch_sim.rates(path, t)
    W = winch_sim.wrench_matrix(A, b, p, R)
    x = _x_truth()
    tau = winch_sim.tensions(W, _wrench_x(x, p, a, R, om, al), tau_ref)
    _, L1, L2 = winch_sim.lengths(A, b, path, t)
    d = winch_sim.drive_truth(rng, m)
    cur = winch_sim.currents(d, tau, L1, L2)
    # the regressor of the (linear) wrench by central differences of the simulator's own
    Z = np.stack([(_wrench_x(x + h, p, a, R, om, al) - _wrench_x(x - h, p, a, R, om, al)) / 2e-3
                  for h in 1e-3 * np.eye(10)], axis=2)
    G = np.linalg.pinv(W) @ Z
    Nn = np.linalg.svd(W)[2][:, 6:, :].transpose(0, 2, 1) if m > 6 else None
    k, J, fv, fc, c = winch_sim.reflected(d)
    phi = np.concatenate([x, 1 / k, J, fv, fc, c])
    return G, cur, L2, L1, np.sign(L1), np.ones_like(L1), Nn, phi


@pytest.mark.parametrize("robot,tau_ref", [(SIX, 40.0), (EIGHT, 30.0)], ids=["six", "eight"])
def test_exact_currents_give_the_truth(robot, tau_ref):
    """Noise-free samples: every parameter to 1e-9 from a start 5-20 % off (drive 1's
    ``a`` held, the scale reference)."""
    G, I, L2, L1, S, C1, Nn, phi = _exact(robot, tau_ref)
    rng = np.random.default_rng(0)
    phi0 = phi * (1 + rng.uniform(-0.2, 0.2, phi.size))
    p = 10
    phi0[p] = phi[p]
    fit = fit_output_error(G, I, L2, L1, S, C1, phi0, p, np.full(I.shape[1], 1e3), Nn)
    assert fit.converged
    np.testing.assert_allclose(fit.phi, phi, rtol=1e-9, atol=1e-9 * np.abs(phi).max())
    assert np.max(np.abs(fit.resid)) < 1e-8
    # a wrong inertia sign on one drive (the model's l'' term flipped) is not consistent
    bad = fit_output_error(G, I, -L2, L1, S, C1, phi0, p, np.full(I.shape[1], 1e3), Nn)
    assert np.max(np.abs(bad.phi - phi) / np.abs(phi).max()) > 1e-3


def test_jacobian_against_finite_differences():
    """``jax.jacfwd`` of the (projected, eight-cable) residual against central differences."""
    G, I, L2, L1, S, C1, Nn, phi = _exact(EIGHT, 30.0, duration=2.0)
    r, jac = _residual_fn(G, I, L2, L1, S, C1, np.full((1, 8), 3.0), Nn)
    at = phi * 1.05
    J = np.asarray(jac(at))
    h = 1e-6 * np.maximum(np.abs(at), 1e-3)
    fd = np.stack([(np.asarray(r(at + e)) - np.asarray(r(at - e))) / (2 * e.max())
                   for e in np.diag(h)], axis=2)
    np.testing.assert_allclose(J, fd, rtol=1e-5, atol=1e-6 * np.abs(J).max())


def test_sandwich_covers_white_noise():
    """White current noise of known std on exact six-cable samples, 40 draws: the mass's HAC
    sandwich std (bandwidth 1: white residuals) matches the spread of the estimates and its
    RMS z is near 1."""
    G, I, L2, L1, S, C1, Nn, phi = _exact(SIX, 40.0, duration=10.0, rate=40.0)
    rng = np.random.default_rng(11)
    sigma = 0.05
    est, sd = [], []
    for _ in range(40):
        In = I + sigma * rng.standard_normal(I.shape)
        f = fit_output_error(G, In, L2, L1, S, C1, phi, 10, np.full(6, 1 / sigma ** 2), Nn,
                             bandwidth=1.0)
        est.append(f.phi[0])
        sd.append(np.sqrt(f.cov[0, 0]))
    est, sd = np.array(est), np.array(sd)
    z = (est - phi[0]) / sd
    assert 0.7 < np.sqrt(np.mean(z ** 2)) < 1.35
    assert 0.7 < np.std(est) / np.median(sd) < 1.4
    # the i.i.d. covariance at the right weight agrees with the sandwich
    assert np.sqrt(f.cov_iid[0, 0]) == pytest.approx(sd[-1], rel=0.3)


@pytest.fixture(scope="module")
def short_recording(tmp_path_factory):
    sim = winch_sim.simulate(SIX, PLATFORM, seed=2, duration=8.0, rate_drive=100.0)
    return winch_sim.write(tmp_path_factory.mktemp("oecli") / "d", SIX, sim)


@pytest.mark.parametrize("extra, word", [(["--source", "free-motion", "--reference", "mass:6"],
                                          "--source currents only"),
                                         ([], "--source currents only"),
                                         (["--source", "currents", "--estimator", "tls"],
                                          "invalid choice")])
def test_estimator_option_is_checked(short_recording, capsys, extra, word):
    from cdprid.cli import main

    args = ["identify", str(short_recording), *extra]
    if "--estimator" not in extra:
        args += ["--estimator", "oe"]
    try:
        code = main(args)
    except SystemExit as e:  # argparse's own refusal of an unknown choice
        code = e.code
    assert code == 2
    assert word in capsys.readouterr().err


@pytest.mark.slow  # ~15 s: two runs, each with the Cramer-Rao bound
def test_estimator_reaches_the_json(short_recording, tmp_path):
    """``--estimator cls`` on the command line runs the corrected least squares (and says so);
    the default is the output error."""
    import json

    from cdprid.cli import main

    out = tmp_path / "r.json"
    base = ["identify", str(short_recording), "--source", "currents", "--reference", "drive:1",
            "--params", '{"cutoff_hz": 4}', "--json", str(out)]
    assert main(base + ["--estimator", "cls"]) == 0
    js = json.loads(out.read_text())
    assert js["estimator"] == "cls" and js["pose_noise_correction"] is None
    assert main(base + ["--force"]) == 0
    js = json.loads(out.read_text())
    assert js["estimator"] == "oe"
    assert any("output-error estimator" in n for n in js["notes"])
    # the pose noise's bias subtracted, per parameter, with its Monte-Carlo std
    pc = js["pose_noise_correction"]
    assert set(pc["shift"]) == set(js["parameters"]) | {
        f"{k}_{j}" for k in ("k", "J", "fv", "fc", "c") for j in range(1, 7)}
    assert pc["shift"]["k_1"] == 0.0 and all(v >= 0 for v in pc["shift_std"].values())
    # the pose noise's own share of each std, inside the reported std
    assert set(pc["first_order_std"]) == set(pc["shift"])
    assert pc["first_order_std"]["k_1"] == 0.0 and pc["first_order_std"]["m"] > 0
    assert pc["first_order_std"]["m"] <= js["parameters"]["m"]["std"] * (1 + 1e-12)
    assert any(n.startswith("pose noise (errors in variables)") for n in js["notes"])


def test_progress_names_each_stage(short_recording):
    """``progress`` hears the stages in order: the corrected least squares, then the output
    error with its pose and encoder noise; ``cls`` stops after the first."""
    from cdprid.identify import identify_currents
    from cdprid.io import read_dataset

    ds = read_dataset(short_recording, require_tensions=False)
    kw = dict(reference="drive:1", bound=False, params={"cutoff_hz": 4.0})
    said = []
    identify_currents(ds, progress=said.append, **kw)
    assert said[0] == "corrected least squares" and len(said) == 2
    assert said[1].startswith("output error, then its pose and encoder noise")
    said.clear()
    identify_currents(ds, progress=said.append, estimator="cls", **kw)
    assert said == ["corrected least squares"]
