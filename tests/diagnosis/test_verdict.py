"""The verdict is true (issue 37 item 5): "within its noise" only when the held-out residual is
within what the noise predicts; otherwise how far above it is."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cdprid.diagnosis import _verdict as V


def _fake_noise(monkeypatch, sigma: float, n: int = 4000):
    """Noise-only residual replicates: white, ``sigma`` N on each force row."""
    def null_residuals(prob, noise, x, n_null, rng):
        for _ in range(n_null):
            yield sigma * rng.normal(size=(n, 6))
    monkeypatch.setattr(V, "null_residuals", null_residuals)
    return SimpleNamespace(use=np.ones(n, bool), test=None)


def test_within_the_noise_only_when_the_residual_is(monkeypatch):
    prob = _fake_noise(monkeypatch, 0.5)
    inside = V.verdict(prob, None, np.zeros(4), 0.51, 0)
    assert inside["within_noise"] and "explains this data within its noise" in inside["text"]
    assert "paper's model" in inside["text"]
    assert abs(inside["noise_predicted_rms_N"] - 0.5) < 0.01
    assert V.MIN_MARGIN <= inside["margin"] < 0.2
    nine = V.verdict(prob, None, np.zeros(4), 4.5, 3)
    assert not nine["within_noise"] and abs(nine["ratio"] - 9.0) < 0.2
    assert "does not explain" in nine["text"] and "9" in nine["text"]
    assert "extended model" in nine["text"]


def test_the_margin_is_the_statistics_own_spread(monkeypatch):
    """Few samples: the held-out rms itself scatters, the margin widens with it."""
    prob = _fake_noise(monkeypatch, 0.5, n=20)
    v = V.verdict(prob, None, np.zeros(4), 0.5, 0)
    assert v["margin"] > 0.15  # 1.645 x ~ 1 / sqrt(2 x 60) relative std
