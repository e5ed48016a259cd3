"""A second start of the search, from the best pair of candidates.

The greedy path (forward, swap, backward) takes one effect at a time. When two effects
partly cancel and each aliases with an effect on a near-collinear partner cable (on the
CRAFT-like robot: the gains of cables 1-6, 2-5, 3-8, 4-7, the anchor errors of cables sharing
an exit corner), step 1 picks a compromise on the partner cable, and the swap stage, which
changes one finding at a time, cannot reach the true pair: every single swap predicts worse.

When the greedy path has named at least two effects, this stage searches *every pair* of
candidates at once at the base linearisation (linearised held-out prediction of the base
model plus the two candidates' columns, all pairs from one set of per-fold Gram matrices:
:func:`cdprid.diagnosis._problem.subset_heldout_rms`). The best pair in which each member
passes the search's own gates given the other (held-out gain ``min_gain``, HAC Wald test at
the first step's threshold) is refitted by the nonlinear refit, checked like any finding,
and the search continues from it (forward steps, swap stage). Of the two complete models
the one that predicts the held-out data better is kept, except that a model with fewer
findings is kept when the two differ by less than ``min_gain`` (:func:`choose`). The
other is reported as a competing model when the data cannot tell them apart.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from cdprid.diagnosis._candidates import vocab_interval, vocab_params
from cdprid.diagnosis._context import DiagnosisContext
from cdprid.diagnosis._problem import Problem, heldout_rms, subset_heldout_rms
from cdprid.diagnosis._result import Finding
from cdprid.diagnosis._selection import (
    Selection,
    candidate_columns,
    extends_base,
    linear_model,
    refit,
    refit_rejected,
    wald_given_others,
)

#: the second start is tried when the greedy path named at least this many effects
#: (besides a clock offset accepted before it)
MIN_FINDINGS = 2


def best_pair(prob: Problem, base, s: Selection, candidates, min_gain: float, thr_p: float):
    """The pair of candidates that best predicts the held-out data at ``s``'s linearisation,
    each member passing the gates given the other.

    Returns ``(pair, rms_pair, rms_before, tests)`` or ``None`` when no pair passes:
    ``tests[i] = (rms without member i, Wald statistic, p-value)``.
    """
    Zb, yb, _, C = linear_model(prob, s)
    cols = candidate_columns(prob, base, s, C,
                             [c for c in candidates if not extends_base(c)])
    cands = list(cols)
    if len(cands) < 2:
        return None
    X = np.concatenate([Zb] + [cols[c] for c in cands], axis=2)
    nb = Zb.shape[2]
    ix, off = [], nb
    for c in cands:
        ix.append(list(range(off, off + cols[c].shape[2])))
        off += cols[c].shape[2]
    head = list(range(nb))
    pairs = list(itertools.combinations(range(len(cands)), 2))
    # one call: the per-fold Gram matrices of X are formed once for all subsets
    allr = subset_heldout_rms(prob, X, yb, [head + ix[i] + ix[j] for i, j in pairs]
                              + [head + ix[i] for i in range(len(cands))] + [head])
    rms, single, rms_before = allr[:len(pairs)], allr[len(pairs):-1], float(allr[-1])
    train = prob.train
    for k in np.argsort(rms):
        i, j = pairs[k]
        # each member must improve the held-out prediction given the other
        if rms[k] > (1 - min_gain) * min(single[i], single[j]):
            continue
        sub = head + ix[i] + ix[j]
        Zs = X[:, :, sub]
        tests = []
        for own, other in ((i, j), (j, i)):
            own_cols = [sub.index(q) for q in ix[own]]
            stat, p = wald_given_others(Zs[train], yb[train], own_cols, prob.lags)
            tests.append((float(single[other]), stat, p))
        if all(p < thr_p for _, _, p in tests):
            return (cands[i], cands[j]), float(rms[k]), rms_before, tests
        # the best pairs are few: one that fails its test is not replaced by a much worse one
        if rms[k] > (1 + min_gain) * float(np.min(rms)):
            break
    return None


def pair_start(prob: Problem, base, s: Selection, candidates, min_gain: float, thr_p: float,
               extra: DiagnosisContext, say, *, known=()):
    """``(selection, pair)``: the selection ``s`` extended by the best pair
    (:func:`best_pair`) and refitted, and that pair. The selection is ``None`` when no pair
    passes (the pair ``None`` too), when both members are among ``known`` (the findings of
    the greedy path: it already started from them), or when the refit makes a member
    implausible or too small."""
    found = best_pair(prob, base, s, candidates, min_gain, thr_p)
    if found is None:
        say("pair start: no pair of candidates passes the gates")
        return None, None
    pair, rms_lin, rms_before, tests = found
    if set(pair) <= set(known):
        say(f"pair start: the best pair, {pair[0].label} + {pair[1].label}, is part of the "
            "greedy path's model; nothing new to start from")
        return None, pair
    idx = sorted(set(s.active_idx).union(*(prob.layout.candidate_indices(c.effect, c.cable)
                                           for c in pair)))
    t = refit(prob, s, active_idx=idx)
    for c in pair:
        why = refit_rejected(prob, t, c, extra)
        if why:
            say(f"pair start: {c.label} {why}")
            return None, pair
    Z, y, _, _ = linear_model(prob, t)
    rms_after = heldout_rms(prob, Z, y)
    std = np.sqrt(np.clip(np.diag(t.th_cov), 0, None))
    n_tests = len(candidates)
    fs = tuple(Finding(effect=c.vocabulary_effect,
                       parameters=vocab_params(c, t.theta, prob.layout, extra, t.th_cov),
                       interval=vocab_interval(c, t.theta, std, prob.layout, extra),
                       aliases=[], heldout_rms_before=rms_without, heldout_rms_after=rms_after,
                       p_value=float(min(1.0, p * n_tests)), statistic=stat, threshold=thr_p)
               for c, (rms_without, stat, p) in zip(pair, tests, strict=True))
    say(f"pair start: best pair {pair[0].label} + {pair[1].label}: held-out rms "
        f"{rms_before:.4f} -> {rms_lin:.4f} (linearised), {rms_after:.4f} refitted")
    return dataclasses.replace(t, accepted=t.accepted + pair, findings=t.findings + fs), pair


def keeps_first(rms_a: float, n_a: int, rms_b: float, n_b: int, min_gain: float) -> bool:
    """Whether model a (held-out rms, number of findings) is kept over model b: the one
    predicting the held-out data better, or the one with fewer findings when the two differ
    by less than ``min_gain`` (relative); a on an exact tie."""
    if abs(rms_b - rms_a) < min_gain * min(rms_a, rms_b) and n_a != n_b:
        return n_a < n_b
    return rms_a <= rms_b


def choose(prob: Problem, a: Selection, b: Selection, min_gain: float):
    """``(kept, other, relative difference of other vs kept)`` (:func:`keeps_first`)."""
    ra, rb = (heldout_rms(prob, *linear_model(prob, x)[:2]) for x in (a, b))
    if keeps_first(ra, len(a.accepted), rb, len(b.accepted), min_gain):
        return a, b, (rb - ra) / ra
    return b, a, (ra - rb) / rb
