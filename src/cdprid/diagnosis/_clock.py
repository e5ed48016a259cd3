"""The clock stage of the diagnosis: a tension-stream offset profiled before the greedy search.

Real recordings carry a clock offset between the tension and pose streams of tens of
milliseconds (the UACDPR importer measures -25 ms). A first-order expansion of the delay at
zero under-rates such offsets, and velocity-like effects (viscous friction, drag) alias
part of them, so a greedy search can take those first and never come back to the clock.
This stage profiles the held-out criterion of the base model over a grid of delays (every
sample of the grid is the exact shift of the tension stream, not an expansion), refits
the delay jointly from the profile's minimum, and accepts it as the first finding when it
passes the Bonferroni-corrected Wald test and improves the held-out residual. Once
accepted, the delay is active in every later refit (the other effects are found with the
clock right); the backward stage can still remove it.

Which effect is the clock is declared by its :class:`~cdprid.effects.DiagnosisForm`
(``clock=True``); this module names no effect.
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
from scipy import stats

from cdprid.core import CATMULL_ROM, tension_at
from cdprid.diagnosis._candidates import Candidate, implausible, vocab_interval, vocab_params
from cdprid.diagnosis._problem import Problem, heldout_rms
from cdprid.diagnosis._result import Finding
from cdprid.diagnosis._selection import Selection, linear_model, refit
from cdprid.effects import DIAGNOSIS

#: the clock is accepted first only when it improves the held-out residual by this much (a
#: dominant clock offset); smaller offsets are left to the greedy search
FIRST_GAIN = 0.03

#: delays profiled, s (every 2 ms within +-0.1 s)
GRID_S = np.round(np.arange(-0.1, 0.1 + 1e-9, 0.002), 6)


def clock_candidate(candidates) -> Candidate | None:
    """The candidate whose form is the clock offset, when it is tested."""
    for c in candidates:
        if DIAGNOSIS[c.effect].clock:
            return c
    return None


def delay_profile(prob: Problem, base, grid=GRID_S) -> np.ndarray:
    """Held-out RMS (weighted units) of the base model with the tension stream shifted by
    each delay of ``grid`` (the exact shift, the model refitted at each)."""
    shifted = jax.jit(lambda s: tension_at(prob.d.stream, prob.d.t + s, CATMULL_ROM))
    tau0 = np.asarray(shifted(0.0))
    Z = base.A * prob.wrow[None, :, None]
    out = []
    for dly in grid:
        dtau = np.asarray(shifted(float(dly))) - tau0
        y = base.y + prob.filt(np.einsum("nij,nj->ni", prob.W_all, dtau))
        out.append(heldout_rms(prob, Z, y * prob.wrow))
    return np.asarray(out)


def _vertex(grid, prof) -> float:
    """The profile's minimum, refined by a parabola through its neighbours."""
    k = int(np.argmin(prof))
    if 0 < k < len(grid) - 1:
        y0, y1, y2 = prof[k - 1], prof[k], prof[k + 1]
        den = y0 - 2 * y1 + y2
        if den > 0:
            h = grid[1] - grid[0]
            return float(grid[k] + 0.5 * h * (y0 - y2) / den)
    return float(grid[k])


def clock_stage(prob: Problem, base, s: Selection, candidates, alpha: float, min_gain: float,
                extra: dict, say) -> tuple[Selection, dict]:
    """Profile the clock offset and accept it first when the data ask for it.

    Returns the selection (with the delay as its first finding, or unchanged) and the
    profile for ``info["clock_profile"]`` (grid, held-out RMS, the refined minimum).
    """
    c = clock_candidate(candidates)
    if c is None:
        return s, {}
    prof = delay_profile(prob, base)
    d0 = _vertex(GRID_S, prof)
    info = {"delay_s": GRID_S.tolist(), "heldout_rms": prof.tolist(), "minimum_s": d0}
    say(f"clock: held-out profile over delays {GRID_S[0]:+.3f} to {GRID_S[-1]:+.3f} s: minimum "
        f"at {1e3 * d0:+.1f} ms")
    idx = prob.layout.candidate_indices(c.effect, c.cable)
    Z, y, _, _ = linear_model(prob, s)
    rms_before = heldout_rms(prob, Z, y)
    gain = max(min_gain, FIRST_GAIN)
    if float(np.min(prof)) > rms_before * (1 - gain):
        say(f"clock: the profile's best shift improves the held-out residual by less than "
            f"{100 * gain:g} %; left to the greedy search")
        return s, info
    theta = np.array(s.theta, float)
    theta[idx] = d0
    t = refit(prob, s, theta=theta, active_idx=sorted(set(s.active_idx) | set(idx)))
    Z, y, _, _ = linear_model(prob, t)
    rms_after = heldout_rms(prob, Z, y)
    var = float(t.th_cov[idx[0], idx[0]])
    stat = float(t.theta[idx[0]] ** 2 / var) if var > 0 else 0.0
    p = float(stats.chi2.sf(stat, 1))
    thr = alpha / len(candidates)
    vocab = vocab_params(c, t.theta, prob.layout, extra, t.th_cov)
    why = implausible(c.effect, vocab)
    if why or not p < thr or rms_after > rms_before * (1 - gain):
        say(f"clock: {c.label} at {1e3 * t.theta[idx[0]]:+.1f} ms not accepted first "
            f"(p = {p:.2e}, held-out {rms_before:.4f} -> {rms_after:.4f}"
            + (f", {why}" if why else "") + "); left to the greedy search")
        return s, info
    std = np.sqrt(np.clip(np.diag(t.th_cov), 0, None))
    f = Finding(effect=c.vocabulary_effect, parameters=vocab,
                interval=vocab_interval(c, t.theta, std, prob.layout, extra), aliases=[],
                heldout_rms_before=float(rms_before), heldout_rms_after=float(rms_after),
                p_value=float(min(1.0, p * len(candidates))), statistic=stat, threshold=thr)
    say(f"clock: accepted {c.label}: {vocab}; held-out rms {rms_before:.4f} -> "
        f"{rms_after:.4f} (weighted units)")
    return dataclasses.replace(t, accepted=t.accepted + (c,), findings=t.findings + (f,)), info
