"""The clock stage of the diagnosis: the tension-stream offset, profiled first and tried again
after every step.

Real recordings carry a clock offset between the tension and pose streams of tens of
milliseconds (the UACDPR importer measures -25 ms). A first-order expansion of the delay at
zero under-rates such offsets, and velocity-like effects (viscous friction, drag, friction on
every pulley) alias part of them. :func:`clock_stage` profiles the held-out criterion of the
base model over a grid of delays (exact shifts of the tension stream) and, when its best shift
improves the held-out residual by :data:`FIRST_GAIN`, tries the delay first
(:func:`clock_check`). :func:`clock_check` is called again after every accepted step: the
delay is refitted jointly with every effect of the current model (its joint profile,
:mod:`cdprid.diagnosis._profile`, then Gauss-Newton) and accepted when it passes the
Bonferroni-corrected Wald test and improves the held-out residual. Once accepted, every later
refit profiles it again jointly (never fixed at its first value); the backward stage can
still remove it. :func:`clock_interval` gives the named delay its interval from the final
model's joint profile; :func:`clock_size` the size of a delay not named.

Which effect is the clock is declared by its :class:`~cdprid.effects.DiagnosisForm`
(``clock=True``); this module names no effect.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import chi2_sf
from cdprid.diagnosis._candidates import Candidate, implausible, vocab_interval, vocab_params
from cdprid.diagnosis._problem import Problem, heldout_rms
from cdprid.diagnosis._profile import (
    clock_index,
    joint_profile,
    profile_interval,
    shift_wrenches,
)
from cdprid.diagnosis._result import Finding
from cdprid.diagnosis._selection import Selection, linear_model, model_implausible, refit
from cdprid.diagnosis._whiten import whitened_delay
from cdprid.effects import DIAGNOSIS

#: the clock is accepted first only when it improves the held-out residual by this much (a
#: dominant clock offset); smaller offsets are left to the greedy search
FIRST_GAIN = 0.03

#: delays profiled, s (every 2 ms within +-0.1 s)
GRID_S = np.round(np.arange(-0.1, 0.1 + 1e-9, 0.002), 6)

#: what the named clock offset's interval holds and what it does not (a note of the result;
#: measured on floor8 seed 3 with noise sources switched off and redrawn, results/
#: many-effects-floor8.md)
INTERVAL_CAVEAT = (
    "The clock offset is estimated in the metric of the load cells' noise through the wrench "
    "matrix (force and moment rows correlated); its 95 % interval holds the sampling error of "
    "the tension and pose noise within this recording (HAC variance, exact profile). It does "
    "not hold the error the pose noise gives it through the estimated accelerations and "
    "angular rates (errors in the variables): on the floor-winch benchmark +0.3 ms on average "
    "over noise draws, +0.9 ms on one draw whose interval then missed the truth by 0.8 ms; "
    "allow about 1 ms beyond it.")


def clock_candidate(candidates) -> Candidate | None:
    """The candidate whose form is the clock offset, when it is tested."""
    for c in candidates:
        if DIAGNOSIS[c.effect].clock:
            return c
    return None


def delay_profile(prob: Problem, base, grid=GRID_S) -> np.ndarray:
    """Held-out RMS (weighted units) of the base model with the tension stream shifted by
    each delay of ``grid`` (the exact shift, the model refitted at each).

    The shifted wrenches are those the joint profile uses
    (:func:`cdprid.diagnosis._profile.shift_wrenches`, kept in ``prob.cache`` for the grid;
    compiled once per shape, not once per call)."""
    S = shift_wrenches(prob, list(grid) + [0.0])
    Z = base.A * prob.wrow[None, :, None]
    return np.asarray([heldout_rms(prob, Z, (base.y + S[k] - S[-1]) * prob.wrow)
                       for k in range(len(grid))])


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
    Z, y, _, _ = linear_model(prob, s)
    rms_before = heldout_rms(prob, Z, y)
    gain = max(min_gain, FIRST_GAIN)
    if float(np.min(prof)) > rms_before * (1 - gain):
        say(f"clock: the profile's best shift improves the held-out residual by less than "
            f"{100 * gain:g} %; left to the greedy search")
        return s, info
    t = clock_check(prob, s, candidates, alpha / len(candidates), gain, extra, say, "clock")
    return t, info


def clock_check(prob: Problem, s: Selection, candidates, thr: float, gain: float, extra: dict,
                say, where: str) -> Selection:
    """The clock offset added to the model ``s`` when the data ask for it.

    The delay is refitted jointly with every effect of ``s`` (its profile over exact shifts,
    :func:`cdprid.diagnosis._profile.joint_delay`, then Gauss-Newton); it is accepted when its
    HAC Wald test given the others passes ``thr``, it is plausible and the held-out residual
    improves by ``gain`` (relative). Returns ``s`` with the clock as a new finding, or ``s``.
    Called on the base model and after every accepted step, so that a clock offset hidden at
    first by friction on every pulley is found once the friction is in the model.
    """
    c = clock_candidate(candidates)
    if c is None or c in s.accepted:
        return s
    idx = prob.layout.candidate_indices(c.effect, c.cable)
    Z, y, _, _ = linear_model(prob, s)
    rms_before = heldout_rms(prob, Z, y)
    theta = np.array(s.theta, float)
    theta[idx] = 0.0
    active = sorted(set(s.active_idx) | set(idx))
    # a cheap screen (no new linearisation): the joint profile's best training-cost gain;
    # a delay that cannot reach half the held-out gate is not refitted
    _, cost, _ = joint_profile(prob, theta, s.x, s.rotational, active)
    c0 = cost[int(np.argmin(np.abs(GRID_S)))]
    if 1.0 - np.sqrt(max(float(np.min(cost)), 0.0) / max(c0, 1e-300)) < 0.5 * gain:
        return s
    t = refit(prob, s, theta=theta, active_idx=active)
    Z, y, _, _ = linear_model(prob, t)
    rms_after = heldout_rms(prob, Z, y)
    var = float(t.th_cov[idx[0], idx[0]])
    stat = float(t.theta[idx[0]] ** 2 / var) if var > 0 else 0.0
    p = float(chi2_sf(stat, 1))
    vocab = vocab_params(c, t.theta, prob.layout, extra, t.th_cov)
    why = implausible(c.effect, vocab) or model_implausible(prob, t, extra)
    if why or not p < thr or rms_after > rms_before * (1 - gain):
        say(f"{where}: {c.label} at {1e3 * t.theta[idx[0]]:+.1f} ms (joint profile) not "
            f"accepted (p = {p:.2e}, held-out {rms_before:.4f} -> {rms_after:.4f}"
            + (f", {why}" if why else "") + ")")
        return s
    std = np.sqrt(np.clip(np.diag(t.th_cov), 0, None))
    f = Finding(effect=c.vocabulary_effect, parameters=vocab,
                interval=vocab_interval(c, t.theta, std, prob.layout, extra), aliases=[],
                heldout_rms_before=float(rms_before), heldout_rms_after=float(rms_after),
                p_value=float(min(1.0, p * len(candidates))), statistic=stat, threshold=thr)
    say(f"{where}: accepted {c.label} (joint profile): {vocab}; held-out rms "
        f"{rms_before:.4f} -> {rms_after:.4f} (weighted units)")
    return dataclasses.replace(t, accepted=t.accepted + (c,), findings=t.findings + (f,))


def _whitened(prob: Problem, t: Selection, di: int) -> dict | None:
    """:func:`cdprid.diagnosis._whiten.whitened_delay` of the model ``t``, or None when the
    noise metric cannot be formed (a singular fit: the row-weighted estimate stands)."""
    saved = dict(prob.cache.get("design", {}))  # the final model's linearisations stay
    try:
        w = whitened_delay(prob, t, di)
    except (np.linalg.LinAlgError, ValueError, RuntimeError):
        return None
    finally:
        prob.cache["design"] = saved
    return w if np.isfinite(w["delay_s"]) and w["var"] > 0 else None


def clock_interval(prob: Problem, s: Selection, extra: dict) -> tuple[Selection, dict]:
    """The named clock offset's value and interval in the tension noise's metric
    (:func:`cdprid.diagnosis._whiten.whitened_delay`: the final model's joint profile over
    exact shifts, every other parameter re-solved, in the metric of the cells' noise through
    W; the union of its profile-likelihood and HAC Wald intervals). The model's other
    parameters stay those of the row-weighted fit; ``info`` (for ``info["clock_profile"]``)
    holds both profiles."""
    di = clock_index(prob)
    for k, c in enumerate(s.accepted):
        if not DIAGNOSIS[c.effect].clock or di not in s.active_idx:
            continue
        grid, cost, _ = joint_profile(prob, s.theta, s.x, s.rotational, list(s.active_idx))
        lo, hi, open_ends = profile_interval(grid, cost, float(s.theta[di]),
                                             float(s.th_cov[di, di]))
        info = {"joint_delay_s": grid.tolist(), "joint_training_cost": cost.tolist(),
                "joint_minimum_s": float(s.theta[di]), "joint_interval_s": [lo, hi],
                "interval_reaches_grid_edge": open_ends, "interval_caveat": INTERVAL_CAVEAT}
        f = s.findings[k]
        key = DIAGNOSIS[c.effect].keys[0]
        w = _whitened(prob, s, di)
        if w is not None:
            theta = np.array(s.theta, float)
            theta[di] = w["delay_s"]
            lo, hi, open_ends = w["interval"]
            f = dataclasses.replace(f, parameters=vocab_params(c, theta, prob.layout, extra))
            info.update({"whitened_training_cost": w["cost"].tolist(),
                         "whitened_minimum_s": w["delay_s"], "whitened_interval_s": [lo, hi],
                         "interval_reaches_grid_edge": open_ends})
        f = dataclasses.replace(f, interval={**f.interval, key: [lo, hi]})
        return dataclasses.replace(s, findings=s.findings[:k] + (f,) + s.findings[k + 1:]), info
    return s, {}


def clock_size(prob: Problem, s: Selection, c, extra: dict) -> dict:
    """A clock offset the search did not name: its value, 95 % interval and p-value from the
    final model with the delay added and refitted jointly (never a linearisation at 0).

    The final model's linearisations stay in ``prob.cache`` (this refit's would displace
    them: the stages after it then linearised the final model again, 10 s of a 317 s
    diagnosis on a loaded machine)."""
    idx = prob.layout.candidate_indices(c.effect, c.cable)
    theta = np.array(s.theta, float)
    theta[idx] = 0.0
    saved = dict(prob.cache.get("design", {}))
    try:
        t = refit(prob, s, theta=theta, active_idx=sorted(set(s.active_idx) | set(idx)))
        w = _whitened(prob, t, idx[0])
        if w is None:
            grid, cost, _ = joint_profile(prob, t.theta, t.x, t.rotational,
                                          list(t.active_idx))
            lo, hi, open_ends = profile_interval(grid, cost, float(t.theta[idx[0]]),
                                                 float(t.th_cov[idx[0], idx[0]]))
    finally:
        prob.cache["design"] = saved
    var = float(t.th_cov[idx[0], idx[0]])
    if w is not None:
        (lo, hi, open_ends), var = w["interval"], w["var"]
        t = dataclasses.replace(t, theta=np.where(np.arange(len(t.theta)) == idx[0],
                                                  w["delay_s"], t.theta))
    stat = float(t.theta[idx[0]] ** 2 / var) if var > 0 else 0.0
    key = DIAGNOSIS[c.effect].keys[0]
    return {"parameters": vocab_params(c, t.theta, prob.layout, extra), "interval": {key: [lo, hi]},
            "p_value": float(chi2_sf(stat, 1)), "statistic": stat,
            "interval_reaches_grid_edge": open_ends}
