"""Model-level ambiguity: complete models that predict the held-out data as well as the final one.

A finding's ``aliases`` say that, at the step it was accepted, another candidate explained the
residual about as well. With several effects at once that is not enough: once the other
findings are in, replacing one finding by one of its aliases gives a *complete* alternative
model, which may predict the held-out data as well as the chosen one. This stage builds each
such model (one finding replaced by one alias, every effect refitted by the nonlinear refit),
compares its held-out prediction with the final model's, and reports those the data cannot
tell apart from it:

* the relative held-out RMS difference is below the search's own gate ``min_gain`` (the
  swap stage would not have preferred either), or
* a Diebold-Mariano test of equal held-out accuracy (per-sample held-out squared errors,
  the Bartlett HAC variance over the residuals' correlation length) does not find the
  alternative worse at :data:`DM_LEVEL`.

A named clock offset is always compared with friction on every pulley in its place and the
reverse (:func:`clock_twins`: the two alias on every cable, issue 37). Each entry carries the
replacing effect's parameters under that model, so a user sees both
explanations with their sizes (e.g. a 16 N offset on cable 2, or a 0.8 deg frame tilt).
"""

from __future__ import annotations

import math

import numpy as np

from cdprid.base import Status, normal_sf
from cdprid.diagnosis._candidates import alias_label, vocab_params
from cdprid.diagnosis._problem import Problem, force_heldout_rms, heldout_residuals, heldout_rms
from cdprid.diagnosis._selection import extends_base, linear_model, refit, refit_rejected
from cdprid.diagnosis._testing import hac_cov
from cdprid.effects import DIAGNOSIS

#: one-sided level of the test that an alternative model predicts worse
DM_LEVEL = 0.05
#: at most this many alternative models are refitted (the strongest aliases first)
MAX_ALTERNATIVES = 12
#: an alternative replaces the named model when its held-out RMS is lower by more than this
#: fraction (material) and the Diebold-Mariano test finds it better at :data:`DM_LEVEL`
#: (beyond its sampling uncertainty)
REPLACE_FRACTION = 0.05


def verdict_of(rel: float, loss_alt, loss_best, lags: int, min_gain: float) -> str | None:
    """What an alternative complete model is to the named one.

    ``"replaces"`` when it predicts the held-out data materially and significantly better:
    its held-out RMS lower by more than :data:`REPLACE_FRACTION` (``rel``, relative to the
    named model's) and the one-sided Diebold-Mariano test (:func:`dm_p_worse`) finds it
    better at :data:`DM_LEVEL`; ``"competes"`` when the data cannot tell the two apart (the
    difference below the search's gate ``min_gain``, or the test does not find it worse);
    ``None`` when it predicts worse.
    """
    p = dm_p_worse(loss_alt, loss_best, lags)
    if rel < -REPLACE_FRACTION and p > 1.0 - DM_LEVEL:
        return "replaces"
    if rel < min_gain or p > DM_LEVEL:
        return "competes"
    return None


def dm_p_worse(loss_alt, loss_best, lags: int) -> float:
    """One-sided Diebold-Mariano p-value of 'the alternative predicts worse'.

    ``loss_*`` are per-sample held-out squared errors (same samples); the variance of the
    mean of their difference is the diagnosis's own Bartlett HAC (:func:`hac_cov`, window
    ``lags + 1``: the residuals pass the matched filter, so consecutive samples are
    correlated over about ``lags``). Equal series give 0.5.
    """
    d = np.asarray(loss_alt, float) - np.asarray(loss_best, float)
    n = d.size
    if n < 2:
        return 0.5
    var = float(hac_cov(np.ones((n, 1, 1)), (d - d.mean())[:, None], lags)[0, 0])
    if not var > 0:
        return 0.5 if d.mean() == 0 else (0.0 if d.mean() > 0 else 1.0)
    return float(normal_sf(d.mean() / math.sqrt(var)))


def clock_twins(c, candidates) -> list:
    """The candidates that can pass for ``c`` when ``c`` is the clock offset or friction on
    every pulley (velocity-like on every cable): the other one. A named clock offset is
    always compared with friction on every pulley in its place, and the reverse, so that a
    recording on which the two cannot be told apart says so (a competing model)."""
    clock = [a for a in candidates if DIAGNOSIS[a.effect].clock]
    common_friction = [a for a in candidates if a.cable is None and DIAGNOSIS[a.effect].report_size
                       and not DIAGNOSIS[a.effect].clock]
    if DIAGNOSIS[c.effect].clock:
        return common_friction
    if c in common_friction:
        return clock
    return []


def heldout_losses(prob: Problem, Z, y) -> np.ndarray:
    """Per-sample held-out squared error of a linearised model (weighted units, the 6 rows
    summed): the losses the Diebold-Mariano comparison (:func:`dm_p_worse`) weighs.

    Parameters
    ----------
    prob : Problem
        The problem (its held-out folds).
    Z, y : ndarray
        The model's linearisation (:func:`cdprid.diagnosis._selection.linear_model`).

    Returns
    -------
    ndarray
        One loss per held-out sample.
    """
    _, r = heldout_residuals(prob, Z, y)
    return np.sum(r * r, axis=1)


def heldout_against(prob: Problem, s, loss_alt) -> tuple[float, float]:
    """``(rms, p_worse)``: the held-out rms of the model ``s`` and the one-sided
    Diebold-Mariano p-value that an alternative with per-sample held-out losses ``loss_alt``
    predicts worse than it (0.0 when ``loss_alt`` is None: no alternative).

    Parameters
    ----------
    prob : Problem
    s : Selection
        The model as it stands.
    loss_alt : ndarray or None
        The alternative's :func:`heldout_losses`.

    Returns
    -------
    (float, float)
    """
    Z, y, _, _ = linear_model(prob, s)
    rms = heldout_rms(prob, Z, y)
    if loss_alt is None:
        return rms, 0.0
    return rms, dm_p_worse(loss_alt, heldout_losses(prob, Z, y), prob.lags)


def competing_models(prob: Problem, s, candidates, min_gain: float, extra: dict,
                     say=lambda msg: None, other=None, better=None) -> tuple[list, int]:
    """Alternative complete models within the noise of the final one.

    Parameters
    ----------
    prob : Problem
    s : Selection
        The final model (after backward elimination).
    candidates : list of Candidate
    min_gain : float
        The search's held-out gate (relative).
    extra : dict
        The context of the candidates' checks.
    say : callable
    other : Selection, optional
        A complete model found another way (the search's second start from the best pair,
        :mod:`cdprid.diagnosis._restart`), compared with the final model like the alternatives
        (``replaces`` and ``by`` then join several labels with " + ", and ``parameters``
        maps each replacing effect's label to its parameters when there are several).
    better : list, optional
        Receives ``(relative_difference, p_worse, k, replaced, replacing, selection)`` for
        every one-finding alternative that predicts the held-out data materially and
        significantly better (:func:`verdict_of`: it should replace the named model, see
        :func:`adopt_better`); such an alternative is not a competing model.

    Returns
    -------
    models : list of dict
        Best first; each ``{"replaces", "by", "parameters", "effects",
        "heldout_force_rms_N", "relative_difference", "p_worse"}``.
    n_tried : int
        Alternatives refitted (a refit that fails or is implausible is not a model).
    """
    saved = {k: dict(v) for k, v in prob.cache.items()}
    try:
        out, n_tried = _competing(prob, s, candidates, min_gain, extra, say,
                                  [] if better is None else better)
        if other is not None:
            m = _whole_model(prob, s, other, min_gain, extra, say)
            n_tried += 1
            out += [] if m is None else [m]
        out.sort(key=lambda m: m["relative_difference"])
        return out, n_tried
    finally:  # the alternatives' linearisations must not displace the final model's
        prob.cache.clear()
        prob.cache.update(saved)


def _competing(prob, s, candidates, min_gain, extra, say, better):
    by_label = {}
    for c in candidates:
        by_label.setdefault(alias_label(c), c)
    Z, y, _, _ = linear_model(prob, s)
    rms_best = heldout_rms(prob, Z, y)
    loss_best = heldout_losses(prob, Z, y)
    pairs = []
    for k, (c, f) in enumerate(zip(s.accepted, s.findings, strict=True)):
        if extends_base(c):
            continue
        for lab in f.aliases:
            a = by_label.get(lab)
            if a is not None and a not in s.accepted and not extends_base(a):
                pairs.append((k, c, a))
        for a in clock_twins(c, candidates):  # friction and the clock: always compared
            if a not in s.accepted and (k, c, a) not in pairs:
                pairs.insert(0, (k, c, a))
    out, n_tried = [], 0
    for k, c, a in pairs[:MAX_ALTERNATIVES]:
        theta = s.theta.copy()
        idx_old = prob.layout.candidate_indices(c.effect, c.cable)
        theta[idx_old] = 0.0
        active = sorted((set(s.active_idx) - set(idx_old))
                        | set(prob.layout.candidate_indices(a.effect, a.cable)))
        t = refit(prob, s, theta=theta, active_idx=active)
        if t.status is Status.FAILED or refit_rejected(prob, t, a, extra):
            continue
        n_tried += 1
        Za, ya, _, _ = linear_model(prob, t)
        rms = heldout_rms(prob, Za, ya)
        rel = (rms - rms_best) / rms_best
        loss = heldout_losses(prob, Za, ya)
        p, kind = dm_p_worse(loss, loss_best, prob.lags), verdict_of(rel, loss, loss_best,
                                                                      prob.lags, min_gain)
        if kind == "replaces":
            better.append((float(rel), p, k, c, a, t))
            say(f"competing model: {a.label} instead of {c.label}, held-out rms "
                f"{rms_best:.4f} -> {rms:.4f} ({100 * rel:+.2f} %, p = {1 - p:.2g} that it is "
                f"not better): predicts materially better (more than {100 * REPLACE_FRACTION:g} "
                "% and beyond its sampling uncertainty)")
        elif kind == "competes":
            accepted = s.accepted[:k] + (a,) + s.accepted[k + 1:]
            out.append({
                "replaces": alias_label(c), "by": alias_label(a),
                "parameters": vocab_params(a, t.theta, prob.layout, extra, t.th_cov),
                "effects": [alias_label(b) for b in accepted],
                "heldout_force_rms_N": force_heldout_rms(prob, Za, ya),
                "relative_difference": float(rel), "p_worse": p})
            say(f"competing model: {a.label} instead of {c.label}, held-out rms "
                f"{rms_best:.4f} -> {rms:.4f} ({100 * rel:+.2f} %, p = {p:.2g} that it is "
                "worse): the data cannot tell the two apart")
    out.sort(key=lambda m: m["relative_difference"])
    return out, n_tried


def _whole_model(prob, s, o, min_gain, extra, say):
    """The entry of a complete alternative model ``o`` when the data cannot tell it from the
    final model ``s``, else ``None``."""
    Z, y, _, _ = linear_model(prob, s)
    Zo, yo, _, _ = linear_model(prob, o)
    rms_best, rms = heldout_rms(prob, Z, y), heldout_rms(prob, Zo, yo)
    rel = (rms - rms_best) / rms_best
    p = dm_p_worse(heldout_losses(prob, Zo, yo), heldout_losses(prob, Z, y), prob.lags)
    gone = [c for c in s.accepted if c not in o.accepted]
    new = [c for c in o.accepted if c not in s.accepted]
    if not new or not (rel < min_gain or p > DM_LEVEL):
        return None
    params = {alias_label(c): vocab_params(c, o.theta, prob.layout, extra, o.th_cov)
              for c in new}
    say(f"competing model: {' + '.join(c.label for c in new)} instead of "
        f"{' + '.join(c.label for c in gone) or 'nothing'}, held-out rms {rms_best:.4f} -> "
        f"{rms:.4f} ({100 * rel:+.2f} %, p = {p:.2g} that it is worse): the data cannot tell "
        "the two apart")
    return {"replaces": " + ".join(alias_label(c) for c in gone),
            "by": " + ".join(alias_label(c) for c in new),
            "parameters": next(iter(params.values())) if len(new) == 1 else params,
            "effects": [alias_label(b) for b in o.accepted],
            "heldout_force_rms_N": force_heldout_rms(prob, Zo, yo),
            "relative_difference": float(rel), "p_worse": p}
