"""The tension noise's metric of the clock offset (issue 37): the row covariance fitted from
the residual, checked against residuals drawn with a known covariance."""

from __future__ import annotations

import dataclasses

import numpy as np


def _toy_problem(n: int, m: int, rng):
    """A stand-in for a Problem: random wrench matrices, row weights, nothing else read."""

    @dataclasses.dataclass
    class P:
        W_all: np.ndarray
        wrow: np.ndarray

    W = rng.normal(size=(n, 6, m))
    W[:, 3:] *= 0.2  # moment rows: lever arms of ~0.2 m
    return P(W, np.array([1.0] * 3 + [5.0] * 3))


def test_noise_metric_recovers_the_cells_and_the_rows_variances():
    """r_t = W_t e_t + u_t with cell variances a_j and row variances d: the fitted metric
    whitens r (sample covariance of Linv r is the identity within sampling error) and is the
    inverse Cholesky factor of sum_j a_j w_j w_j^T + diag(d) within a few per cent."""
    from cdprid.diagnosis._whiten import noise_metric

    rng = np.random.default_rng(0)
    n, m = 20000, 8
    prob = _toy_problem(n, m, rng)
    a = rng.uniform(0.02, 0.2, size=m)
    d = np.array([0.3, 0.2, 0.4, 0.002, 0.003, 0.001])
    e = rng.normal(size=(n, m)) * np.sqrt(a)
    r = np.einsum("tij,tj->ti", prob.W_all, e) + rng.normal(size=(n, 6)) * np.sqrt(d)
    Linv = noise_metric(prob, r, np.ones(n, bool))
    z = np.einsum("tij,tj->ti", Linv, r)
    np.testing.assert_allclose(z.T @ z / n, np.eye(6), atol=0.05)
    M = np.einsum("tij,j,tkj->tik", prob.W_all[:50], a, prob.W_all[:50]) + np.diag(d)
    got = np.linalg.inv(np.einsum("tji,tjk->tik", Linv[:50], Linv[:50]))
    np.testing.assert_allclose(got, M, rtol=0.1, atol=0.02 * np.max(d))


def test_noise_metric_of_four_cables_is_regular():
    """Four cables: W S W^T has rank 4 of 6; with no row noise the floor on the diagonal
    keeps the metric finite (a valid, if not efficient, weighting)."""
    from cdprid.diagnosis._whiten import noise_metric

    rng = np.random.default_rng(1)
    n, m = 4000, 4
    prob = _toy_problem(n, m, rng)
    r = np.einsum("tij,tj->ti", prob.W_all, 0.3 * rng.normal(size=(n, m)))
    Linv = noise_metric(prob, r, np.ones(n, bool))
    assert np.all(np.isfinite(Linv))
    z = np.einsum("tij,tj->ti", Linv, r)
    assert np.all(np.isfinite(z)) and np.max(np.abs(z.T @ z / n - np.eye(6))) < 1.0
