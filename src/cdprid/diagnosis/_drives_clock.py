"""The clock of the drive streams, found before the drive model (``diagnose --source currents``).

``identify --source currents`` has no clock offset between the drives' streams (currents,
encoder lengths) and the poses: fitted on a recording whose currents are 20 ms late, its drive
model absorbed the offset (a reflected inertia, torque constants off) and the diagnosis then
named those instead of the clock (the benchmark's ``clock`` case, six-cable robot). So on
currents the clock offset is looked for first, on the datasheet tension ``k_nom i`` with every
drive's parameters free (the torque constants but the reference's, the offsets, friction and
inertia: the drive model linearised, refitted at each exact shift of the profile), by the
search's own clock check (:func:`cdprid.diagnosis._clock.clock_check`: the joint profile, its
HAC Wald test, plausibility and a 3 % held-out gain) and its interval
(:func:`cdprid.diagnosis._clock.clock_interval`). When it is named, identify fits the drive
model with the drive streams' time stamps corrected and the diagnosis reads the corrected
stream; the finding is this one. The torque constants refitted here carry the current noise
(errors in variables), which biases the scale, not where the profile's minimum lies.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.diagnosis._clock import FIRST_GAIN, clock_check, clock_interval
from cdprid.diagnosis._selection import refit, start
from cdprid.effects import DIAGNOSIS

__all__ = ["DRIVE_CLOCK_CAVEAT", "STEP_S", "CurrentsSide", "currents_clock", "currents_model"]

#: the note a named clock offset of the drive streams carries (benchmarks/drives_diagnosis.py)
DRIVE_CLOCK_CAVEAT = (
    "the drive streams' clock offset comes out short of the truth beyond its interval on "
    "simulated recordings (18.4 of 20 ms at 0.03 A current noise, 19.6 without: the drives' "
    "viscous friction and inertia take part of a time shift, the time derivative of the "
    "pose-dependent static tension looking like a speed): read it as a lower bound of its "
    "magnitude; cable elasticity is not tested on the encoder lengths, which share that clock")

#: a refinement of the drive streams' clock smaller than this (s) is not applied
STEP_S = 2e-4


def _drive_indices(prob, reference_cable) -> list:
    """Theta indices of every drive's parameters (the reference drive's torque constant
    excepted) through the forms that declare them (``DiagnosisForm.drive``)."""
    out = set()
    for name, form in DIAGNOSIS.items():
        if not form.drive:
            continue
        for j in range(1, prob.m + 1):
            if form.not_on_reference and j == reference_cable:
                continue
            out |= set(prob.layout.candidate_indices(name, j))
    return sorted(out)


def _pass(prob, base, candidates, ref_cable, thr: float, gain: float, extra, say,
          free: bool = True):
    """One clock check, with every drive parameter free (``free``) or the problem's drive model
    held: ``(delay, finding, info)`` or ``(0.0, None, {})``."""
    s = start(prob, base)
    if free:
        s = refit(prob, s, active_idx=_drive_indices(prob, ref_cable))
    t = clock_check(prob, s, candidates, thr, gain, extra, say, "drive clock")
    new = [k for k, c in enumerate(t.accepted) if DIAGNOSIS[c.effect].clock]
    if not new:
        return 0.0, None, {}
    t, info = clock_interval(prob, t, extra)
    f = t.findings[new[0]]
    return float(f.parameters[DIAGNOSIS[t.accepted[new[0]].effect].keys[0]]), f, info


def currents_clock(prob, base, candidates, reference_cable, alpha: float, min_gain: float,
                   extra, say):
    """``(delay_s, finding, info)`` of the drive streams' clock offset with every drive
    parameter free, or ``(0.0, None, {})`` when the data do not name one (the search's clock
    check: its threshold and a 3 % held-out gain).

    Parameters
    ----------
    prob : Problem
        The datasheet tension's problem (no drive model in it yet).
    base : BaseFit
    candidates : list of Candidate
        The search's (their number is the Bonferroni factor; the clock's among them).
    reference_cable : int or None
        The scale reference drive.
    alpha, min_gain : float
        The search's family-wise level and held-out gain.
    extra : DiagnosisContext
    say : callable

    Returns
    -------
    (float, Finding or None, dict)
    """
    return _pass(prob, base, candidates, reference_cable, alpha / len(candidates),
                 max(min_gain, FIRST_GAIN), extra, lambda m: say(f"drive clock: {m}"))


def _refined(prob, base_stage, delay: float, f, say):
    """The clock offset's remainder with identify's drive model held (``prob.theta0``; no
    refitted torque constant, so no current noise in the regressor): ``(step, finding)``,
    the finding's interval moved by ``delay``; ``(0.0, f)`` when it cannot be refined."""
    pb, base, _, ctx, candidates = base_stage(prob)
    step, g, _ = _pass(pb, base, candidates, None, 1.0, -1.0, ctx, lambda m: None, free=False)
    if g is None:
        return 0.0, f
    key = next(iter(g.interval))
    say(f"drive clock: {1e3 * step:+.2f} ms more with identify's drive model held")
    return step, dataclasses.replace(f, parameters={key: delay + step}, interval={
        key: [delay + v for v in g.interval[key]]})


@dataclasses.dataclass
class CurrentsSide:
    """What the diagnosis on currents carries besides the problem: identify's drive model, its
    tests, the drive streams' clock offset (``(finding, info)`` or None) and the level."""

    drives: object
    tests: list
    clock: tuple | None = None
    alpha: float = 1e-3

    def candidates(self, candidates) -> list:
        """The search's candidates: without the clock when it was named first."""
        if self.clock is None:
            return candidates
        return [c for c in candidates if not DIAGNOSIS[c.effect].clock]

    def lengths(self, lengths, notes: list):
        """The encoder stream for cable elasticity: none when the drive clock was named (the
        encoders share it, known only to about a millisecond; a note says so)."""
        if self.clock is None:
            return lengths
        notes.append(DRIVE_CLOCK_CAVEAT)
        return None

    def findings(self, prob, s, findings, notes: list, say) -> list:
        """The drive-side findings and the clock's before the search's, and the scale note."""
        from cdprid.diagnosis._drives import drive_findings

        named = drive_findings(prob, s, self.tests, self.alpha)
        notes.append(self.drives.scale_note())
        say(f"drive side: {len(named)} effect(s) named by identify's drive model")
        return list(named) + ([self.clock[0]] if self.clock else []) + list(findings)

    def info(self) -> dict:
        """``info["source"]`` and ``info["source_currents"]``."""
        return {"source": "currents", "source_currents": {
            **self.drives.as_json(), "tests": self.tests,
            "clock": self.clock[1] if self.clock else None}}


def currents_model(raw, ds, fit: tuple, problem, base_stage, alpha: float, min_gain: float,
                   say) -> tuple:
    """The diagnosis's problem on currents with the drive streams' clock and identify's drive
    model: ``(problem, (sub, lengths, notes, (eps, prob_with)), side)``.

    Parameters
    ----------
    raw : Dataset
        As read (identify reads its drive streams from the folder).
    ds : Dataset
        The datasheet tension's dataset (:func:`cdprid.diagnosis._drives.datasheet_dataset`).
    fit : tuple
        ``(reference, drive_fit, taut_N)``: identify's ``--reference``, the drive model's fit
        (:func:`cdprid.diagnosis._drives.fit_drives`) and the slack threshold (N), applied to
        the drive model's tension (``problem`` builds the problems without it: the datasheet
        reading ``k i`` is the tension minus the drive's friction and inertia, below any
        threshold where a cable pays out against 10 N of friction).
    problem : callable
        ``problem(ds) -> (prob, sub, lengths, notes, (eps, prob_with))`` (the pipeline's).
    base_stage : callable
        ``base_stage(prob) -> (prob, base, noise, context, candidates)`` (the pipeline's).
    alpha, min_gain : float
    say : callable

    Returns
    -------
    tuple
        ``side``: a :class:`CurrentsSide`.
    """
    from cdprid.diagnosis._drives import drive_named, drive_theta, fit_drives, gauge_cable

    reference, drive_fit, taut_N = fit

    def drive_model(late):
        return fit_drives(raw, reference, drive_fit, late, lambda m: say(f"identify: {m}"))

    prob, *rest = problem(ds)
    pb, base, _, ctx, candidates = base_stage(prob)
    delay, f, info = currents_clock(pb, base, candidates, gauge_cable(raw), alpha, min_gain,
                                    ctx, say)
    if f is not None:  # the stream read on the poses' clock from here on
        prob, *rest = problem(_shifted(ds, delay))
    drives = drive_model(delay)
    if f is not None:  # again with identify's drive model (its torque constants unbiased)
        step, f = _refined(dataclasses.replace(prob, theta0=drive_theta(drives, prob.layout)),
                           base_stage, delay, f, say)
        if abs(step) > STEP_S:
            delay += step
            prob, *rest = problem(_shifted(ds, delay))
            drives = drive_model(delay)
        rest[2].append(f"the drive streams' clock offset {1e3 * delay:+.2f} ms (named first, "
                       "on the datasheet tension with every drive's parameters free, then "
                       "refined with identify's drive model) is taken out of them before "
                       "identify and every later fit")
    th0 = drive_theta(drives, prob.layout)
    eps, prob_with = rest[3]
    prob, prob_with = (_taut(x, th0, taut_N) for x in (prob, prob_with))
    rest[2][:0] = [drives.note(), *drives.notes]
    side = CurrentsSide(drives, drive_named(drives, alpha), None if f is None else (f, info),
                        alpha)
    return prob, (rest[0], rest[1], rest[2], (eps, prob_with)), side


def _taut(prob, th0, taut_N: float):
    """The problem with the drive model ``th0`` and without the samples where the model's
    tension of a cable (matched-filtered) is below ``taut_N`` (the shared rule's window)."""
    import jax.numpy as jnp

    from cdprid.base import UserError
    from cdprid.core import taut_mask
    from cdprid.diagnosis._model import tension_jac

    # through the matched filter: the inertia's raw second differences are noise per sample
    tau = prob.filt(np.asarray(tension_jac(prob.d, jnp.asarray(th0), prob.layout)[0]))
    ok = taut_mask(prob.t, prob.t, tau, threshold_N=taut_N)
    if int((prob.use & ok).sum()) < 200:
        raise UserError(f"only {int((prob.use & ok).sum())} pose samples have every cable's "
                        f"tension (the drive model's) above {taut_N:g} N, 200 are needed: "
                        "slack cables, or currents the drive model does not explain.")
    return dataclasses.replace(
        prob, theta0=th0, use=prob.use & ok, train=prob.train & ok,
        test=None if prob.test is None else prob.test & ok,
        n_slack=prob.n_slack + int((prob.use & ~ok).sum()))


def _shifted(ds, delay: float):
    """The dataset with the drive streams' time stamps (the datasheet tension's, currents.csv's
    and lengths.csv's) ``delay`` earlier."""
    extra = dict(ds.extra)
    for name in ("currents", "lengths"):
        if name in extra:
            cols, vals = extra[name]
            vals = np.array(vals, float)
            vals[:, list(cols).index("t")] -= delay
            extra[name] = (cols, vals)
    return dataclasses.replace(ds, tension_t=ds.tension_t - delay, extra=extra)
