"""Model selection rules of issue 37 on synthetic regressions (fast, no simulation).

1. Backward elimination: a structure signal that spans a finding's form (its own signature,
   like "sign of cable velocity" for friction on every pulley) does not displace the finding;
   a signal that only correlates with a finding still does (the finding then fits part of a
   structure it does not explain).
2. Competing models: an alternative that predicts the held-out data better by more than its
   sampling uncertainty and by a material fraction replaces the named model; one within the
   noise is reported as a competing model.
"""

from __future__ import annotations

import numpy as np

from cdprid.diagnosis import _selection as S
from cdprid.diagnosis._candidates import Candidate
from cdprid.diagnosis._competing import DM_LEVEL, REPLACE_FRACTION, verdict_of
from cdprid.diagnosis._signature import OWN_SIGNATURE, canonical_correlation
from cdprid.signal import zero_phase_filter


def _smooth(rng, n, q):
    return zero_phase_filter(rng.normal(size=(n, 6 * q)), 0.01, 4.0).reshape(n, 6, q)


def _half_split_heldout(Zc, yc):
    half = len(Zc) // 2
    b, *_ = np.linalg.lstsq(Zc[:half].reshape(-1, Zc.shape[2]), yc[:half].reshape(-1),
                            rcond=None)
    r = yc[half:] - np.einsum("nip,p->ni", Zc[half:], b)
    return float(np.sqrt(np.mean(r * r)))


def _regression(seed, own: bool):
    """Base columns, one finding's column and a 4-column structure signal F.

    ``own``: the finding is the sum of F's columns (F reproduces it, like a common Coulomb
    friction and the per-cable sign of velocity) and the data hold it plus a per-cable
    difference; else the data hold a mixed-sign structure in F and the finding is a column
    that only correlates with it."""
    rng = np.random.default_rng(seed)
    n = 2000
    base, F = _smooth(rng, n, 2), _smooth(rng, n, 4)
    noise = 0.1 * _smooth(rng, n, 1)[:, :, 0]
    if own:
        C = F.sum(axis=2, keepdims=True)
        y = base @ np.array([1.0, -0.5]) + 1.0 * C[:, :, 0] + 0.3 * F[:, :, 0] + noise
    else:
        C = 0.6 * F[:, :, :1] + 0.8 * _smooth(rng, n, 1)
        y = base @ np.array([1.0, -0.5]) + F @ np.array([1.0, -1.0, 0.8, -0.6]) + noise
    return np.concatenate([base, C], axis=2), y, F


def _weakest(Z, y, F):
    pick = Candidate("pulley_friction_all", None)
    return S.weakest_finding([pick], Z, y, lambda c: [2], _half_split_heldout,
                             np.ones(len(Z), bool), 75, 0.01, 1e-4, (F,))


def test_a_structure_that_spans_a_finding_does_not_displace_it():
    Z, y, F = _regression(3, own=True)
    assert canonical_correlation(Z[:, :, 2:], F) >= OWN_SIGNATURE
    # the old rule (the structure appended to the model as it is) removes the finding: its
    # column lies in the structure's span, whatever the data say
    k_old, why, _ = S.weakest_finding([Candidate("pulley_friction_all", None)],
                                      np.concatenate([Z, F], axis=2), y, lambda c: [2],
                                      _half_split_heldout, np.ones(len(Z), bool), 75, 0.01,
                                      1e-4)
    assert k_old == 0 and why
    k, why, _ = _weakest(Z, y, F)
    assert k is None, why


def test_a_structure_that_only_correlates_with_a_finding_still_displaces_it():
    Z, y, F = _regression(4, own=False)
    assert canonical_correlation(Z[:, :, 2:], F) < OWN_SIGNATURE
    k, why, _ = _weakest(Z, y, F)
    assert k == 0 and "removing it" in why


def test_competing_model_replaces_only_when_materially_and_significantly_better():
    rng = np.random.default_rng(5)
    n = 3000
    best = 1.0 + rng.normal(size=n) ** 2  # per-sample held-out squared errors
    rms = float(np.sqrt(best.mean()))

    def rel_of(loss):
        return float(np.sqrt(loss.mean())) / rms - 1.0

    # an alternative with half the squared error: replaces the named model
    alt = 0.5 * best
    assert verdict_of(rel_of(alt), alt, best, 20, 0.01) == "replaces"
    # better by a small fraction (significant but not material): within the noise
    alt = best * (1 - 0.5 * REPLACE_FRACTION)
    assert verdict_of(rel_of(alt), alt, best, 20, 0.01) == "competes"
    # better by a material fraction on average, but not beyond its sampling uncertainty
    e = rng.normal(size=n)
    alt = best * (1 - 4 * REPLACE_FRACTION) + 40.0 * (e - e.mean())
    assert rel_of(alt) < -REPLACE_FRACTION
    assert verdict_of(rel_of(alt), alt, best, 20, 0.01) == "competes"
    # clearly worse: neither
    alt = best + 1.0
    assert verdict_of(rel_of(alt), alt, best, 20, 0.01) is None
    assert 0 < DM_LEVEL < 0.5
