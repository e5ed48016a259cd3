"""``diagnose``: the stages of the diagnosis, in order.

1. :func:`cdprid.diagnosis._problem.prepare` — align, differentiate, masks.
2. :func:`cdprid.diagnosis._base.base_fit` — the paper's model, row weights, noise levels.
3. :func:`cdprid.diagnosis._selection.forward_step` — greedy forward selection with HAC Wald
   tests, thresholds calibrated on null replicates at the first step (reused by the later
   steps), the held-out criterion, nonlinear refit each step.
4. :func:`cdprid.diagnosis._selection.swap_stage` — a pick is replaced by a better alternative;
   ties are aliases with what would separate them.
5. :func:`cdprid.diagnosis._selection.backward_stage` — a finding stays only if needed given the
   others and the unexplained structure.
6. :func:`cdprid.diagnosis._unexplained.unexplained_stage` — what remains, under ``unexplained``.
7. :func:`summarize` — extended model, held-out figures, information criterion.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from cdprid.base import CUTOFF_HZ, TAUT_THRESHOLD_N, TRIM_S, InputError
from cdprid.core import refuse_implausible, rest_mask
from cdprid.diagnosis._base import BaseFit, NoiseLevels, base_fit, noise_levels, null_residuals
from cdprid.diagnosis._budget import MAX_SAMPLES, joined_time, subset
from cdprid.diagnosis._candidates import alias_label, candidate_list
from cdprid.diagnosis._clock import INTERVAL_CAVEAT, clock_check, clock_interval, clock_stage
from cdprid.diagnosis._competing import competing_models
from cdprid.diagnosis._context import DiagnosisContext
from cdprid.diagnosis._drives import SOURCES, datasheet_dataset, platform_candidates
from cdprid.diagnosis._drives_clock import currents_model
from cdprid.diagnosis._hysteresis import (
    TENSION_RATE_SIGNAL,
    direction_feature,
    refine_hysteresis,
)
from cdprid.diagnosis._lengths import lengths_stream, with_elasticity
from cdprid.diagnosis._problem import Problem, force_heldout_rms, measured, prepare
from cdprid.diagnosis._regeometry import geometry_reselection, sensor_pass_check
from cdprid.diagnosis._replace import adopt_better
from cdprid.diagnosis._restart import MIN_FINDINGS, choose, pair_start
from cdprid.diagnosis._parts import ParameterEstimate, ParameterEstimates
from cdprid.diagnosis._result import DiagnosisResult
from cdprid.diagnosis._selection import (
    Selection,
    backward_stage,
    forward_step,
    linear_model,
    start,
    swap_stage,
)
from cdprid.diagnosis._sizes import not_named_sizes
from cdprid.diagnosis._stability import geometry_stage, plausibility_stage, stability_stage
from cdprid.diagnosis._testing import wald
from cdprid.diagnosis._unexplained import (
    finding_floor_N,
    structure_features,
    unexplained_stage,
)
from cdprid.diagnosis._verdict import verdict
from cdprid.effects import DIAGNOSIS
from cdprid.episodes import find_episodes, winch_lengths
from cdprid.io import Dataset, align
from cdprid.model import PARAMETER_NAMES


def weight_at_rest(prob: Problem, theta, min_rest_s: float = 0.5, max_speed: float = 0.03):
    """Platform weight (kg) from the cable forces where the platform is at rest.

    Rest: the core's rule (:func:`cdprid.core.rest_mask`) with the diagnosis' threshold
    ``max_speed`` (3 cm/s, above :data:`cdprid.base.REST_SPEED_M_S`) over at least
    ``min_rest_s``, ``min_rest_s / 2`` dropped where a rest meets motion. Given
    with the raw tensions and with the extended model's sensor corrections (offsets, gains,
    delay), to compare with the mass identified from the motion: a common load-cell gain is
    indistinguishable from the mass, the two must agree under the same sensor model.
    """
    win = max(1, int(round(min_rest_s / prob.dt)))
    rest = rest_mask(prob.t, np.linalg.norm(prob.v, axis=1), max_speed, min_rest_s,
                     edge_s=min_rest_s / 2)
    if rest.sum() < win:
        return None
    g = np.asarray(prob.d.robot.gravity)
    out = {"n_samples": int(rest.sum()), "t_first": float(prob.t[rest][0])}
    for key, th in (("raw_kg", np.zeros(prob.layout.size)), ("corrected_kg", theta)):
        y = measured(prob, th)[rest]
        out[key] = float(np.mean(-(y[:, :3] @ g)) / float(g @ g))
    return out


@dataclasses.dataclass(frozen=True)
class Search:
    """The search's settings (:func:`diagnose`'s parameters of the same names)."""

    alpha: float
    n_null: int
    max_effects: int
    min_gain: float
    seed: int


def summarize(prob: Problem, base: BaseFit, s: Selection, noise: NoiseLevels, settings: dict,
              scale_rel_std: float = 0.0):
    """Extended-model parameters, held-out force RMS (base, extended), BIC and the info dict.
    ``scale_rel_std``: the relative std of a scale held fixed in the fit (on currents, the
    drive model's: :meth:`cdprid.diagnosis._drives.DriveSource.scale_rel_std`), added to every
    parameter's variance as ``(r value)^2`` (``theta = v phi``: docs/drives.md)."""
    train, wrow, lags = prob.train, prob.wrow, prob.lags
    Zfw, yfw, _, _ = linear_model(prob, s)
    names = PARAMETER_NAMES["full" if s.rotational else "translation"]
    _, beta_f, V_f, _ = wald(Zfw[train], yfw[train], [0], lags)
    V_f = V_f + np.diag(np.pad((scale_rel_std * beta_f[:len(names)]) ** 2,
                               (0, len(beta_f) - len(names))))
    ext_params = ParameterEstimates({
        nm: ParameterEstimate(
            value=float(beta_f[i]), std=float(np.sqrt(V_f[i, i])),
            rel_std_percent=float(100 * np.sqrt(V_f[i, i]) / max(abs(beta_f[i]), 1e-300)))
        for i, nm in enumerate(names)
    })
    Zb, yb = base.A * wrow[None, :, None], base.y * wrow
    n_eff = max(10.0, train.sum() / max(1.0, lags / 2.0))
    e_b = yb[train] - np.einsum("nip,p->ni", Zb[train], np.linalg.lstsq(
        Zb[train].reshape(-1, Zb.shape[2]), yb[train].reshape(-1), rcond=None)[0])
    e_f = yfw[train] - np.einsum("nip,p->ni", Zfw[train], beta_f)
    bic_b = n_eff * math.log(np.mean(e_b**2)) + Zb.shape[2] * math.log(n_eff)
    bic_f = n_eff * math.log(np.mean(e_f**2)) + Zfw.shape[2] * math.log(n_eff)
    info = {
        # the model identify --model auto uses: "full" when the platform rotates
        "base_model": "full" if base.rotational else "translation",
        "rotation_deg": prob.rotation_deg,
        "n_samples": int(prob.n),
        "n_train": int(train.sum()),
        "n_heldout": int(prob.test.sum()) if prob.test is not None else None,
        "heldout": ("train/test split" if prob.test is not None
                    else f"blocked {prob.n_folds}-fold CV"),
        "heldout_units": "N (force rows)",
        **settings,
        "noise_position_m": noise.position_m,
        "noise_tension_N": [float(v) for v in noise.tension_N],
        "rotation_amplitude_rad": noise.rotation_amplitude,
        "n_excluded_slack": prob.n_slack,
        "row_weights": [float(w) for w in wrow],
        "hac_lags": lags,
        "weight_at_rest": weight_at_rest(prob, s.theta),
        "information_criterion": {"kind": "BIC (effective sample size)", "base": bic_b,
                                  "extended": bic_f, "n_eff": n_eff},
    }
    resid = (yfw - np.einsum("nip,p->ni", Zfw, beta_f)) / wrow[None, :]
    return ext_params, force_heldout_rms(prob, Zb, yb), force_heldout_rms(prob, Zfw, yfw), \
        info, resid


def _split_at_joins(sig, joins):
    """``sig`` with its gap-free segments cut where two blocks of a budgeted subset meet: the
    blocks are put end to end on one time axis, but the pose jumps there (not a glitch)."""
    if not joins:
        return sig
    cuts = [int(c) for c in np.searchsorted(sig.t, np.asarray(joins))]
    segments = []
    for a, b in sig.segments:
        edges = [a] + [c for c in cuts if a < c < b] + [b]
        segments += list(zip(edges[:-1], edges[1:], strict=True))
    return dataclasses.replace(sig, segments=tuple(segments))


def _problem(ds, train_until, *, cutoff_hz, trim, n_folds, taut_N, max_samples, say,
             keep_episodes=False, source="tensions"):
    """The problem on the whole recording or on its budgeted subset (on the recording's own
    clock) without its episodes (:mod:`cdprid.episodes`, unless kept), its lengths stream, the
    notes (the alignment's included), the episodes and the problem with them kept."""
    # every plausibility guard of identify refuses here; on currents they are notes (the
    # datasheet model lacks the drives' inertia and friction, which their thresholds assume)
    guards = refuse_implausible(ds, taut_N, enforce=source != "currents")
    lengths, notes = lengths_stream(ds)
    notes += [f"plausibility guard (not enforced on motor currents, whose datasheet model "
              f"lacks the drives' inertia and friction): {g}" for g in guards]
    t_first = float(ds.tension_t[0])  # the recording's clock starts there (Subset.clock)
    sub = subset(ds, max_samples, margin_s=max(trim, 0.1))
    if sub is not None:
        notes.append(sub.note)
        say(sub.note)
        ds = sub.dataset
        if train_until is not None:
            train_until = joined_time(sub, train_until)
    prob = prepare(ds, train_until, cutoff_hz, trim, n_folds, taut_N,
                   joins=sub.joins if sub is not None else (),
                   clock=sub.clock if sub is not None else None, source=source)
    sig = _split_at_joins(align(ds), sub.joins if sub is not None else ())
    notes.extend(n for n in sig.notes if n not in notes)
    eps = find_episodes(ds.robot, sig, cutoff_hz, trim=trim, use=prob.use,
                        lengths=winch_lengths(ds, sig.t))
    if sub is not None:  # report the recording's own times, not the joined axis
        eps = eps.retimed(lambda x: float(sub.clock(np.array([x]))[0]) + t_first)
    for e in eps.episodes:
        say(f"episode: {e.describe()}")
    prob_with = prob
    if eps.episodes and not keep_episodes:
        out = eps.excluded
        test = None if prob.test is None else prob.test & ~out
        if (prob.train & ~out).sum() >= 200 and (test is None or test.sum() >= 50):
            notes.append(eps.note())
            prob = dataclasses.replace(prob, use=prob.use & ~out, train=prob.train & ~out,
                                       test=test)
    say(f"aligned {prob.n} samples at {1 / prob.dt:.4g} Hz; {int(prob.train.sum())} used for "
        "fitting" + (f" ({prob.n_slack} samples with a cable below {taut_N:g} N excluded)"
                     if prob.n_slack else ""))
    return prob, sub, lengths, notes, (eps, prob_with)


def diagnose(
    ds: Dataset,
    train_until: float | None = None,
    *,
    cutoff_hz: float = CUTOFF_HZ,
    trim: float = TRIM_S,
    n_folds: int = 5,
    alpha: float = 1e-3,
    n_null: int = 30,
    max_effects: int = 8,
    min_gain: float = 0.01,
    seed: int = 0,
    taut_N: float = TAUT_THRESHOLD_N,
    progress=None,
    max_samples: int = MAX_SAMPLES,
    keep_episodes: bool = False,
    source: str = "tensions",
    reference: str | None = None,
    drive_fit=None,
) -> DiagnosisResult:
    """Diagnose what the paper's model misses in a dataset.

    Parameters
    ----------
    ds : Dataset
    train_until : float, optional
        Fit on t < train_until, measure the held-out gain on t >= train_until (without it:
        blocked cross-validation over ``n_folds`` time blocks).
    cutoff_hz, trim, n_folds : float, float, int
        Zero-phase filter cutoff (Hz: differentiator and matched filter); seconds dropped at
        both ends (filter transients); contiguous time blocks for held-out validation.
    alpha, n_null, max_effects, min_gain : float, int, int, float
        Family-wise false-positive rate (of the candidates' tests; of ``unexplained``'s); null
        residual replicates (from the fitted base model) calibrating thresholds; greedy forward
        selection stops after max_effects; smallest relative held-out RMS change for an effect
        to be accepted, kept or swapped.
    seed, taut_N, progress : int, float, callable
        Seed of the null simulation; samples where any cable is below ``taut_N`` (N) within
        +-0.1 s are excluded; called with progress strings (optional).
    max_samples : int
        Sample budget: a longer recording is analysed on evenly spaced contiguous blocks
        (:func:`cdprid.diagnosis._budget.subset`; ``notes`` and ``info["subset"]`` say which).
    keep_episodes : bool
        Keep the episodes (:mod:`cdprid.episodes`) in the fits (by default left out).
    source, reference, drive_fit : str, str, callable
        ``"tensions"`` (load cells) or ``"currents"`` (docs/drives.md), identify's
        ``--reference``, the drive model's fit (:func:`cdprid.identify.identify_currents`).

    Returns
    -------
    DiagnosisResult
    """
    say = _timed_say(progress, t0 := time.perf_counter())
    cfg = Search(alpha, n_null, max_effects, min_gain, seed)
    prob, sub, lengths, notes, (eps, prob_with), side = _prepared(
        ds, (source, reference, drive_fit), cfg, say, train_until=train_until,
        cutoff_hz=cutoff_hz, trim=trim, n_folds=n_folds, taut_N=taut_N,
        max_samples=max_samples, keep_episodes=keep_episodes)
    prob, base, noise, ctx, candidates = _base_stage(prob, notes, say, side)
    prob, s, (other, second), clock, ranking, thr_first = _search(
        prob, base, noise, ctx, candidates, cfg, say)
    s, hints, withdrawn, clock, regeo = _checks(
        prob, base, s, candidates, feats := _structure(prob), cfg, thr_first=thr_first,
        ctx=ctx, say=say, clock_info=clock)
    s, competing, n_alt, clock = _competing_stage(
        prob, s, candidates, cfg, thr_first, other, ctx=ctx, say=say, notes=notes, clock_info=clock)
    unexplained, rule = _unexplained(prob, s, feats, hints, withdrawn, noise, alpha=alpha, say=say)
    findings, el_info = _findings(prob, s, side, (lengths, sub, notes), alpha, say)
    ext_params, base_ho, ext_ho, info, resid = summarize(prob, base, s, noise, {
        "train_until": train_until, "taut_threshold_N": taut_N,
        "n_candidates": len(candidates), "alpha": alpha, "competing_models_tried": n_alt},
        side.drives.scale_rel_std() if side else 0.0)
    _complete_info(info, not_named=not_named_sizes(prob, base, s, candidates, ctx, thr_first),
                   rule=rule, el_info=el_info, clock_info=clock, second=second, t0=t0,
                   sub=sub, regeo=regeo, side=side)
    return _result(prob, prob_with, eps, s, base, resid, noise, seed=seed, say=say,
                   base_heldout_rms=base_ho, findings=findings, extended_parameters=ext_params,
                   extended_heldout_rms=ext_ho, ranking=ranking, info=info,
                   unexplained=unexplained, notes=notes, competing=competing)


def _competing_stage(prob, s, candidates, cfg: Search, thr, other, *, ctx: DiagnosisContext,
                     say, notes, clock_info):
    """Competing models of the final model; one that predicts the held-out data materially
    better replaces it (:func:`cdprid.diagnosis._replace.adopt_better`, with a note), and
    the competing models are then those of the new model; a named clock offset's interval
    gets its note (:data:`cdprid.diagnosis._clock.INTERVAL_CAVEAT`). Returns ``(selection,
    competing models, alternatives refitted, clock info)``."""
    better, min_gain = [], cfg.min_gain
    competing, n_alt = competing_models(prob, s, candidates, min_gain, ctx, say, other,
                                        better=better)
    if better:
        s, clock_info, note = adopt_better(prob, s, better, candidates, thr=thr,
                                           min_gain=min_gain, extra=ctx, say=say,
                                           clock_info=clock_info)
        notes.append(note)
        competing, n_more = competing_models(prob, s, candidates, min_gain, ctx, say, other)
        n_alt += n_more
    if any(DIAGNOSIS[c.effect].clock for c in s.accepted):  # what its interval holds
        notes.append(INTERVAL_CAVEAT)
    return s, competing, n_alt, clock_info


def _findings(prob, s, side, data: tuple, alpha, say) -> tuple:
    """The findings with cable elasticity's (the encoder stream ``data = (lengths, sub,
    notes)``) and, on currents, the drive side's first: ``(findings, elasticity info)``."""
    lengths, sub, notes = data
    lengths = side.lengths(lengths, notes) if side else lengths
    findings, el_info = with_elasticity(list(s.findings), prob, lengths, sub, alpha, say)
    return (side.findings(prob, s, findings, notes, say) if side else findings), el_info


def _complete_info(info, *, not_named, rule, el_info, clock_info, second, t0, sub,
                   regeo, side=None) -> None:
    """The stages' remaining entries of ``info`` (the budgeted subset's when there is one)."""
    info.update({"not_named": not_named, "unexplained_rule": rule, "lengths": el_info,
                 "clock_profile": clock_info, "second_start": second,
                 "geometry_reselection": regeo,
                 "wall_time_s": time.perf_counter() - t0})
    if sub is not None:
        info["subset"] = sub.as_json()
    info.update(side.info() if side else {})


def _result(prob: Problem, prob_with: Problem, eps, s, base: BaseFit, resid, noise, *, seed,
            say, **parts) -> DiagnosisResult:
    """The result: ``parts`` (:class:`DiagnosisResult`'s fields) with the verdict in its
    ``info``, the base fit's, the arrays the report plots, the episodes and the extended
    model's held-out force rms with the episodes' samples kept (the fit unchanged: ``prob``'s
    training samples and weights)."""
    info, n = parts["info"], len(parts["findings"])
    info["verdict"] = verdict(prob, noise, s.x, parts["extended_heldout_rms"], n, seed)
    say(f"done in {info['wall_time_s']:.1f} s: {n} finding(s)")
    return DiagnosisResult(base_parameters=base.parameters,
                           base_residual_rms=base.residual_rms,
                           arrays=_arrays(prob, base, resid), episodes=eps.as_json(),
                           extended_heldout_rms_with_episodes=_with_episodes(prob, prob_with, s),
                           **parts)


def _with_episodes(prob: Problem, prob_with: Problem, s) -> float:
    """The extended model's held-out force rms with the episodes' samples kept (the fit
    unchanged: ``prob``'s training samples and weights)."""
    Z, y, _, _ = linear_model(prob, s)  # the final model's linearisation
    kept = dataclasses.replace(prob_with, train=prob.train, wrow=prob.wrow)
    return force_heldout_rms(kept, Z, y)


def _checks(prob, base, s, candidates, feats, cfg: Search, *, thr_first,
            ctx: DiagnosisContext, say, clock_info):
    """The stages that may take a finding back: backward elimination, geometry selected again
    given the complete sensor side (:mod:`cdprid.diagnosis._regeometry`), stability over halves
    of the recording and groups of cables (an unstable geometry error is withdrawn before it
    is weighed against the sensor side), geometry beyond the survey tolerance against the
    sensor-side alternatives, and the plausibility of what remains (and backward elimination
    again after a withdrawal, given the model alone: a finding may only have been needed
    beside it); then the clock's
    interval from the final model's joint profile. Returns ``(selection, hints, withdrawn
    findings for unexplained, clock info, info["geometry_reselection"])``."""
    alpha, min_gain = cfg.alpha, cfg.min_gain
    s, hints = backward_stage(prob, s, feats, alpha, min_gain, thr_first, ctx, say)
    s, regeo = geometry_reselection(prob, base, s, candidates, alpha, min_gain, thr_first,
                                    cfg.max_effects, ctx, say)
    sensor_first = []
    if regeo.get("kept") == "geometry selected again":  # a new model: each finding needed?
        s, _ = backward_stage(prob, s, {}, alpha, min_gain, thr_first, ctx, say)
        added = [c for c in candidates if c.label in regeo.get("sensor_pass", ())]
        s, sensor_first = sensor_pass_check(prob, s, added, candidates, min_gain, ctx, say)
    s, unstable = stability_stage(prob, s, ctx, say)
    s, withdrawn = geometry_stage(prob, s, candidates, min_gain, ctx, say)
    s, implausible_now = plausibility_stage(prob, s, ctx, say)
    withdrawn = sensor_first + withdrawn
    if unstable or withdrawn or implausible_now:  # what the others carried may not be needed
        # (given the model alone: the unexplained structure's signals were weighed in the
        # first pass; here a generic sign-of-velocity signal would displace friction)
        s, _ = backward_stage(prob, s, {}, alpha, min_gain, thr_first, ctx, say)
    s, joint_clock = clock_interval(prob, s, ctx)
    return s, hints, unstable + withdrawn + implausible_now, {**clock_info, **joint_clock}, regeo


def _unexplained(prob, s, feats, hints, withdrawn, noise, *, alpha, say):
    """The ``unexplained`` stage on the final model, with the withdrawn findings after it (a
    hint of backward elimination about an effect the final model names again, e.g. after a
    competing model replaced a finding by it, is left out)."""
    named = {c.label for c in s.accepted}
    hints = [h for h in hints if h["where"] not in named]
    Z, y, _, _ = linear_model(prob, s)
    # and each cell's tension-rate sign (issue 37): tested here, not in backward elimination
    feats = {**feats, TENSION_RATE_SIGNAL: prob.filt(direction_feature(prob, s))
             * prob.wrow[None, :, None]}
    unexplained, rule = unexplained_stage(prob, Z, y, feats, hints, noise.tension_N, alpha)
    unexplained += withdrawn
    _say_unexplained(unexplained, say)
    return unexplained, rule


def _timed_say(progress, t0):
    """A progress callback prefixing each message with the seconds since ``t0``."""
    def say(msg):
        if progress is not None:
            progress(f"[{time.perf_counter() - t0:6.1f} s] {msg}")
    return say


def _say_unexplained(unexplained: list, say) -> None:
    """One progress line per unexplained structure."""
    for u in unexplained:
        say(f"unexplained: {u['where']}, {u['size']:.3g} N, like {u['correlates_with']}, "
            f"p = {u['p_value']:.2e}")


def _arrays(prob, base, resid) -> dict:
    """The time series the report plots (residuals before and after, motion, tensions)."""
    return {"t": prob.t, "residual_base": base.residual, "residual_extended": resid,
            "velocity": prob.v, "acceleration": prob.a, "tension": prob.tension,
            "position": prob.position, "train": prob.train, "use": prob.use}


def _structure(prob) -> dict:
    """The residual structure signals (filtered and row-weighted like the regression)."""
    return {k: prob.filt(F) * prob.wrow[None, :, None] for k, F in structure_features(
        prob.W_all, prob.v, prob.om, prob.tension, prob.position, np.asarray(prob.d.clock),
        prob.use, slide=prob.d.slide).items()}


def _prepared(ds, how: tuple, cfg: Search, say, **kw):
    """The problem of the force stream ``how = (source, reference, drive_fit)`` names:
    ``(prob, sub, lengths, notes, (eps, prob_with), side)``, ``side`` the
    :class:`~cdprid.diagnosis._drives_clock.CurrentsSide` on currents, else None (one sentence
    on a bad source, a missing stream or a reference without currents)."""
    source, reference, drive_fit = how
    if source not in SOURCES:
        raise InputError(f"--source {source!r}: use one of {', '.join(SOURCES)}.")

    def problem(x):  # on currents the slack test waits for the drive model (currents_model)
        return _problem(x, kw["train_until"], say=say, source=source, **{
            k: (-np.inf if k == "taut_N" and source == "currents" else v)
            for k, v in kw.items() if k != "train_until"})

    if source == "currents":  # the drive streams' clock, then the drive model
        prob, rest, side = currents_model(
            ds, datasheet_dataset(ds), (reference, drive_fit, kw["taut_N"]), problem,
            lambda p: _base_stage(p, [], lambda m: None), cfg.alpha, cfg.min_gain, say)
        say(rest[2][0])
        return (prob, *rest, side)
    if reference is not None:
        raise InputError("--reference applies to --source currents only (the load cells fix "
                         "the scale).")
    if ds.tension is None:
        raise InputError(f"{ds.path}: the dataset has no tensions.csv; diagnose its motor "
                         "currents with --source currents.")
    return (*problem(ds), None)


def _base_stage(prob, notes: list, say, side=None):
    """The base model's fit, the noise levels estimated from the data and the context the
    candidates' checks read and the candidates (of the problem's source; ``drives`` a
    :class:`~cdprid.diagnosis._drives_clock.CurrentsSide` on currents): ``(prob, base, noise,
    context, candidates)``."""
    prob, base = base_fit(prob)
    if base.rotational:
        notes.append(f"the platform rotates by up to {prob.rotation_deg:.2g} deg: the base model "
                     "is the full 10-parameter model (inertia included), the one identify "
                     "--model auto uses; rotational_dynamics is part of it, not a finding")
        say(notes[-1])
    say(f"base fit: m = {base.x[0]:.4f} kg, force residual rms "
        f"{np.sqrt(np.mean(np.square(base.residual_rms[:3]))):.3f} N")
    noise = noise_levels(prob)
    say(f"noise estimated from the data: position {1e3 * noise.position_m:.3f} mm, tensions "
        f"{np.mean(noise.tension_N):.3f} N (rms over cables)")
    axes = np.asarray(prob.d.robot.pulley_axis, float)
    ctx = DiagnosisContext(rotation_amplitude=noise.rotation_amplitude,
                           rotation_amplitude_std=noise.rotation_amplitude_std,
                           pulley_axis=axes[0] if np.allclose(axes, axes[0]) else axes,
                           finding_floor_N=finding_floor_N(prob.tension[prob.use]),
                           base_mass_kg=float(base.x[0]),
                           drive_k=None if side is None else side.drives.k_nominal)
    candidates = candidate_list(prob.m, prob.has_rotation and not base.rotational, prob.d.robot,
                                source=prob.source)
    if prob.source == "currents":  # the drive side is identify's drive model (drive_findings)
        candidates = platform_candidates(candidates)
    if side is not None:
        candidates = side.candidates(candidates)
    return prob, base, noise, ctx, candidates


def _search(prob, base, noise, ctx: DiagnosisContext, candidates, cfg: Search, say):
    """The clock stage, the greedy forward steps and the swap stage:
    ``(selection, clock_info, first step's ranking, first step's threshold)``."""
    alpha, min_gain = cfg.alpha, cfg.min_gain
    s0, clock_info = clock_stage(prob, base, start(prob, base), candidates, alpha, min_gain,
                                 ctx, say)
    rng = np.random.default_rng(cfg.seed)
    s = s0
    ranking, thr_first = [], alpha / len(candidates)
    for step in range(1, cfg.max_effects + 1):
        # null replicates calibrate the first step's threshold; later steps reuse it
        nulls = null_residuals(prob, noise, s.x[:4], cfg.n_null, rng) if step == 1 else ()
        nxt, rank, thr = forward_step(prob, base, s, candidates, nulls, alpha, min_gain, ctx,
                                      say, step, thr_first if step > 1 else 1.0)
        if step == 1:
            ranking, thr_first = rank, thr
        if nxt is None:
            break
        s = clock_check(prob, nxt, candidates, thr_first, min_gain, ctx, say, f"step {step}")
        prob, s = refine_hysteresis(prob, s, ctx, say, done=prob.hysteresis_refined)
    s = swap_stage(prob, s, candidates, min_gain, ctx, say)
    s, other, second = _second_start(prob, base, s0, s, candidates, cfg, thr=thr_first,
                                     ctx=ctx, say=say)
    prob, s = refine_hysteresis(prob, s, ctx, say, done=prob.hysteresis_refined)
    return prob, s, (other, second), clock_info, ranking, thr_first



def _second_start(prob, base, s0, s, candidates, cfg: Search, *, thr, ctx: DiagnosisContext,
                  say):
    """The search started again from the best pair (:mod:`cdprid.diagnosis._restart`) when
    the greedy path named at least two effects: ``(kept model, the other or None, what was
    done for info["second_start"])``."""
    alpha, min_gain = cfg.alpha, cfg.min_gain
    if len(s.accepted) - len(s0.accepted) < MIN_FINDINGS:
        return s, None, {"tried": False}
    t, pair = pair_start(prob, base, s0, candidates, min_gain, thr, ctx, say,
                         known=s.accepted)
    pair = None if pair is None else [alias_label(c) for c in pair]
    if t is None:
        return s, None, {"tried": True, "pair": pair,
                         "kept": "greedy path" if pair else "greedy path (no pair passes)"}
    for step in range(3, cfg.max_effects + 1):
        nxt, _, _ = forward_step(prob, base, t, candidates, (), alpha, min_gain, ctx, say,
                                 step, thr)
        if nxt is None:
            break
        t = clock_check(prob, nxt, candidates, thr, min_gain, ctx, say, f"step {step}")
    t = swap_stage(prob, t, candidates, min_gain, ctx, say)
    if set(t.accepted) == set(s.accepted):
        say("pair start: the same model as the greedy path")
        return s, None, {"tried": True, "pair": pair, "kept": "same model"}
    keep, other, rel = choose(prob, s, t, min_gain)
    say(f"pair start: kept {' + '.join(c.label for c in keep.accepted)} "
        f"({'the greedy path' if keep is s else 'from the best pair'}); the other model "
        f"({' + '.join(c.label for c in other.accepted)}) has a held-out rms "
        f"{100 * rel:+.2f} % from it")
    return keep, other, {"tried": True, "pair": pair,
                         "kept": "greedy path" if keep is s else "best pair",
                         "other_model": [alias_label(c) for c in other.accepted],
                         "other_relative_difference": float(rel)}
