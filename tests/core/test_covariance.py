"""The covariance module: eq. 20 and the HAC sandwich against numpy references and Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.core import (
    andrews_bandwidth,
    hac_covariance,
    iid_covariance,
    sample_scores,
    std_from_cov,
)
from cdprid.model import EIGHT_REDUNDANT, SIX_SUSPENDED


def _ar1(rng, n, phi, burn=200):
    w = rng.standard_normal(n + burn)
    u = np.zeros(n + burn)
    for k in range(1, n + burn):
        u[k] = phi * u[k - 1] + w[k]
    return u[burn:]


def _design(n, k=1):
    t = np.arange(n) / 100.0
    X = np.stack([np.ones(n), np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 0.3 * t + 0.2)], 1)
    if k == 1:
        return X
    rows = [X * (1.0 + 0.3 * j) for j in range(k)]
    return np.stack(rows, axis=1)  # (n, k, p)


def test_iid_covariance_equals_normal_equation_inverse(rng):
    A = rng.standard_normal((200, 4))
    R = np.linalg.qr(A, mode="r")
    np.testing.assert_allclose(iid_covariance(R, 2.5), 2.5 * np.linalg.inv(A.T @ A),
                               rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("k", [1, 6])
@pytest.mark.parametrize("L", [1, 3, 17])
def test_hac_equals_explicit_bartlett_sum(rng, k, L):
    """Reference: (Z^T Z)^-1 (sum_{|j|<L} (1 - |j|/L) Gamma_j) (Z^T Z)^-1 by explicit loops."""
    n = 300
    Z = _design(n, k) + 0.1 * rng.standard_normal((n, k, 3) if k > 1 else (n, 3))
    e = rng.standard_normal((n, k) if k > 1 else n)
    cov, bw = hac_covariance(Z, e, bandwidth=L)
    assert bw == L
    Zg = Z if k > 1 else Z[:, None, :]
    eg = e if k > 1 else e[:, None]
    S = np.array([Zg[t].T @ eg[t] for t in range(n)])
    meat = S.T @ S
    for j in range(1, L):
        G = S[j:].T @ S[:-j]
        meat += (1 - j / L) * (G + G.T)
    Zf = Zg.reshape(-1, 3)
    B = np.linalg.inv(Zf.T @ Zf)
    np.testing.assert_allclose(cov, B @ meat @ B, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(sample_scores(Zg, eg), S, rtol=1e-12)


def test_hac_bandwidth_one_on_white_noise_matches_white_sandwich(rng):
    n = 2000
    X = _design(n)
    e = rng.standard_normal(n)
    cov, _ = hac_covariance(X, e, bandwidth=1)
    B = np.linalg.inv(X.T @ X)
    np.testing.assert_allclose(cov, B @ (X.T * e**2) @ X @ B, rtol=1e-10)


def test_andrews_bandwidth_grows_with_correlation(rng):
    n = 4000
    X = _design(n)
    bws = [andrews_bandwidth(sample_scores(X, _ar1(rng, n, phi))) for phi in (0.0, 0.5, 0.9)]
    assert bws[0] < 3.0
    assert bws[0] < bws[1] < bws[2]
    # Andrews' closed form for a scalar AR(1): alpha = 4 phi^2 / ((1 - phi)^2 (1 + phi)^2)
    one = _ar1(rng, 20000, 0.8)[:, None]
    alpha = 4 * 0.64 / (0.2**2 * 1.8**2)
    expected = 1.1447 * (alpha * 20000) ** (1 / 3)
    assert abs(andrews_bandwidth(one) - expected) < 0.1 * expected


def test_std_from_cov_clips_negative_diagonal():
    np.testing.assert_array_equal(std_from_cov(np.diag([4.0, -1e-20])), [2.0, 0.0])


def test_shape_mismatch_is_one_sentence():
    with pytest.raises(ValueError, match="do not match"):
        hac_covariance(np.ones((10, 6, 3)), np.ones((10, 5)))


@pytest.mark.slow
def test_hac_covers_ar1_noise_where_iid_does_not():
    """Monte Carlo: LS on AR(1) noise (phi = 0.9); the HAC z-scores have RMS near 1, eq. 20's ~4."""
    rng = np.random.default_rng(7)
    n, reps = 3000, 300
    X = _design(n)
    beta = np.array([1.0, 2.0, -1.0])
    z_hac, z_iid = [], []
    for _ in range(reps):
        y = X @ beta + _ar1(rng, n, 0.9)
        Q, R = np.linalg.qr(X)
        b = np.linalg.solve(R, Q.T @ y)
        e = y - X @ b
        cov, _ = hac_covariance(X, e, R=R)
        z_hac.append((b - beta) / std_from_cov(cov))
        z_iid.append((b - beta) / std_from_cov(iid_covariance(R, e @ e / (n - 3))))
    z_hac, z_iid = np.array(z_hac), np.array(z_iid)
    rms = np.sqrt(np.mean(z_hac**2, axis=0))
    cover = np.mean(np.abs(z_hac) < 1.96, axis=0)
    assert np.all(rms < 1.3) and np.all(rms > 0.8), rms
    assert np.all(cover > 0.86) and np.all(cover < 0.99), cover
    assert np.all(np.sqrt(np.mean(z_iid**2, axis=0)) > 3.0)


# ----------------------------------------------------------------------------- robots (slow)


@pytest.mark.slow
@pytest.mark.parametrize("robot_dict,tau_ref", [(SIX_SUSPENDED, 25.0), (EIGHT_REDUNDANT, 40.0)])
def test_identify_default_std_covers_the_error(tmp_path, robot_dict, tau_ref):
    """Monte Carlo of `identify` with default options on robots other than the CRAFT-like one.

    4.5 kg platform, 3 deg rotations, 0.3 mm / 0.5 N noise: the HAC z-scores of m and m s_G
    have RMS near 1 (eq. 20's are several times larger) and the nominal 95 % interval covers.
    """
    from cdprid.identify import identify_dataset
    from cdprid.io import read_dataset
    from cdprid.model import InertialParameters, preset, robot_from_dict
    from cdprid.simulation import SensorNoise, simulate, write_simulation

    robot = robot_from_dict(robot_dict, source=robot_dict["name"])
    truth = InertialParameters(4.5, np.array([0.01, -0.005, -0.04]), np.diag([0.03, 0.035, 0.05]))
    traj = preset("rich", robot, duration=26.0, rotation_amplitude=0.05)
    z, zi = [], []
    for seed in range(12):
        sim = simulate(robot, traj, truth, noise=SensorNoise(position_m=3e-4, tension_N=0.5),
                       seed=seed, tau_ref=tau_ref)
        rep = identify_dataset(read_dataset(write_simulation(sim, tmp_path / f"d{seed}")))
        assert rep.model == "full"
        x = np.asarray(truth.vector("full"))[:4]
        z.append((rep.result.x[:4] - x) / rep.result.std[:4])
        zi.append((rep.result.x[:4] - x) / rep.result.std_iid[:4])
    z, zi = np.array(z), np.array(zi)
    assert np.sqrt(np.mean(z**2)) < 1.5, np.sqrt(np.mean(z**2, axis=0))
    assert np.abs(z).max() < 4.0
    cover = np.mean(np.abs(z) < 1.96)
    assert 0.85 <= cover <= 1.0, cover
    assert np.sqrt(np.mean(zi**2)) > np.sqrt(np.mean(z**2))


@pytest.mark.parametrize("k", [1, 6])
def test_leverage_adjusted_hac_equals_leave_one_window_out_refits(rng, k):
    """Reference: each Bartlett window's score replaced by ``Z^T Z (b - b_(-w))``, where
    ``b_(-w)`` is the LS estimate refitted without the window's rows (explicit lstsq)."""
    n, L, p = 80, 5, 3
    Z = _design(n, k) + 0.1 * rng.standard_normal((n, k, p) if k > 1 else (n, p))
    Zg = Z if k > 1 else Z[:, None, :]
    y = Zg @ np.array([1.0, -2.0, 0.5]) + rng.standard_normal((n, Zg.shape[1]))
    Zf, yf = Zg.reshape(-1, p), y.reshape(-1)
    b = np.linalg.lstsq(Zf, yf, rcond=None)[0]
    e = y - Zg @ b
    meat = np.zeros((p, p))
    for w in range(n + L - 1):  # windows [w - L + 1, w] clipped to the data
        keep = np.ones(n, bool)
        keep[max(w - L + 1, 0): min(w + 1, n)] = False
        bw = np.linalg.lstsq(Zg[keep].reshape(-1, p), y[keep].reshape(-1), rcond=None)[0]
        a = Zf.T @ Zf @ (b - bw)
        meat += np.outer(a, a)
    B = np.linalg.inv(Zf.T @ Zf)
    cov, bw_used = hac_covariance(Zg, e, bandwidth=L, leverage=True)
    assert bw_used == L
    np.testing.assert_allclose(cov, B @ (meat / L) @ B, rtol=1e-8, atol=1e-15)
    # the adjustment only inflates: the adjusted variance exceeds the plain Newey-West one
    plain, _ = hac_covariance(Zg, e, bandwidth=L)
    assert np.all(np.diag(cov) > np.diag(plain))


def test_default_hac_is_leverage_adjusted_with_the_andrews_bandwidth(rng):
    n = 600
    X = _design(n)
    e = _ar1(rng, n, 0.8)
    cov, bw = hac_covariance(X, e)
    assert bw == andrews_bandwidth(sample_scores(X, e))
    np.testing.assert_allclose(cov, hac_covariance(X, e, bandwidth=bw, leverage=True)[0],
                               rtol=1e-12)
