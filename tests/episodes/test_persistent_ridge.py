"""The ridge that anchors the scan's persistent columns (``_stage._fit``'s ``prior``) against
an independent oracle: ordinary least squares of the whitened rows stacked with the ridge's
rows (``sqrt(lam) s_j (beta_j - beta0_j)``, ``s_j`` the column's whitened norm)."""

from __future__ import annotations

import numpy as np


def _problem(seed=0, n=300, p=3, q=4):
    rng = np.random.default_rng(seed)
    Z = rng.normal(size=(n, 6, p + q))
    Z[..., p] = Z[..., p + 1] + 1e-4 * rng.normal(size=(n, 6))  # two nearly collinear columns
    y = np.einsum("nip,p->ni", Z, rng.normal(size=p + q)) + 0.1 * rng.normal(size=(n, 6))
    L = np.tril(rng.normal(size=(6, 6))) + 3 * np.eye(6)
    rows = rng.random(n) > 0.2
    return y, Z, rows, L, rng.normal(size=q)


def test_ridge_equals_stacked_least_squares():
    from cdprid.episodes._stage import _fit

    y, Z, rows, L, b0 = _problem()
    lam, q = 0.05, len(b0)
    r, beta = _fit(y, Z, rows, L, (b0, lam))
    Zw = np.einsum("ij,njp->nip", L, Z[rows]).reshape(-1, Z.shape[2])
    yw = (y[rows] @ L.T).reshape(-1)
    s = np.linalg.norm(Zw, axis=0)
    R = np.zeros((q, Z.shape[2]))
    R[:, -q:] = np.sqrt(lam) * np.diag(s[-q:])
    want = np.linalg.lstsq(np.vstack([Zw, R]), np.concatenate([yw, np.sqrt(lam) * s[-q:] * b0]),
                           rcond=None)[0]
    np.testing.assert_allclose(beta, want, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(r, y - np.einsum("nip,p->ni", Z, want), atol=1e-8)


def test_ridge_limits():
    """No ridge: the plain fit; a strong one: the last columns held at ``beta0``."""
    from cdprid.episodes._stage import _fit

    y, Z, rows, L, b0 = _problem(1)
    r_plain, plain = _fit(y, Z, rows, L)
    r_weak, weak = _fit(y, Z, rows, L, (b0, 1e-12))
    np.testing.assert_allclose(r_weak, r_plain, atol=1e-6)
    np.testing.assert_allclose(weak[:3], plain[:3], atol=1e-6)  # the well-determined ones
    _, held = _fit(y, Z, rows, L, (b0, 1e6))
    np.testing.assert_allclose(held[-len(b0):], b0, atol=1e-4)


def _robust_fit_every_step(y, Z, rows, whiten, steps=3, prior=None):
    """The robust fit as it was before repeated fits of the same samples were skipped."""
    from cdprid.episodes._stage import REJECT_SIGMAS, _fit

    r, beta = _fit(y, Z, rows, whiten, prior)
    for _ in range(steps):
        x = r[rows]
        med = np.median(x, 0)
        mad = 1.4826 * np.median(np.abs(x - med), 0)
        ok = np.all(np.abs(r - med) <= REJECT_SIGMAS * np.maximum(mad, 1e-12), axis=1)
        if (rows & ok).sum() < max(10 * Z.shape[2], rows.sum() // 2):
            break
        r, beta = _fit(y, Z, rows & ok, whiten, prior)
    return r, beta


def test_robust_fit_skips_only_repeated_fits():
    """Bit-identical to fitting every step, with outliers (a push) and without."""
    from cdprid.episodes._stage import _robust_fit

    for seed, push in ((2, 0.0), (3, 30.0)):
        y, Z, rows, L, b0 = _problem(seed)
        y[100:130, :3] += push
        for prior in (None, (b0, 0.01)):
            r1, b1 = _robust_fit(y, Z, rows, L, prior=prior)
            r2, b2 = _robust_fit_every_step(y, Z, rows, L, prior=prior)
            np.testing.assert_array_equal(b1, b2)
            np.testing.assert_array_equal(r1, r2)
