"""A competing model that predicts materially better replaces the named one (issue 37).

The competing-model stage (:mod:`cdprid.diagnosis._competing`) refits complete alternative
models, each with one finding replaced by an alias (always the clock offset by friction on
every pulley and the reverse). On the floor-winch 8-cable robot (seed 2) it found friction on
every pulley in place of a +63 ms clock offset predicting the held-out data 72 % better, and
only reported it. Here such a model is adopted: when an alternative's held-out RMS is lower
by more than :data:`cdprid.diagnosis._competing.REPLACE_FRACTION` and the Diebold-Mariano
test finds it better at :data:`cdprid.diagnosis._competing.DM_LEVEL`
(:func:`cdprid.diagnosis._competing.verdict_of`), the best of them replaces the named model,
with a note; the replaced finding becomes an alias of its replacement. The clock offset is
then tried again jointly with the new model (the replacement may have carried what had
displaced it) and its interval taken from the new model's joint profile.
"""

from __future__ import annotations

import dataclasses

from cdprid.diagnosis._candidates import alias_label
from cdprid.diagnosis._clock import clock_check, clock_interval
from cdprid.diagnosis._context import DiagnosisContext
from cdprid.diagnosis._selection import Selection, with_vocabulary


def adopt_better(prob, s: Selection, better: list, candidates, *, thr: float, min_gain: float,
                 extra: DiagnosisContext, say, clock_info: dict) -> tuple[Selection, dict, str]:
    """The named model ``s`` replaced by the best materially better alternative.

    Parameters
    ----------
    prob : Problem
    s : Selection
        The named model.
    better : list
        ``(relative_difference, p_worse, k, replaced, replacing, selection)`` from
        :func:`cdprid.diagnosis._competing.competing_models` (non-empty).
    candidates : list of Candidate
    thr : float
        The search's p-value threshold (for the clock offset tried again).
    min_gain : float
        The search's held-out gate (relative).
    extra : DiagnosisContext
        The context of the candidates' checks.
    say : callable
    clock_info : dict
        ``info["clock_profile"]`` so far (its joint entries are replaced).

    Returns
    -------
    selection : Selection
    clock_info : dict
    note : str
        What was replaced by what and by how much the held-out prediction improved.
    """
    rel, p, k, old, new, t = min(better, key=lambda b: b[0])
    f = s.findings[k]
    f = dataclasses.replace(f, effect=new.vocabulary_effect,
                            aliases=sorted(set(f.aliases) | {alias_label(old)}))
    t = with_vocabulary(prob, dataclasses.replace(
        t, accepted=s.accepted[:k] + (new,) + s.accepted[k + 1:],
        findings=s.findings[:k] + (f,) + s.findings[k + 1:]), extra)
    note = (f"{alias_label(old)} replaced by {alias_label(new)}: the model with "
            f"{alias_label(new)} in its place predicts the held-out data {100 * -rel:.0f} % "
            f"better (held-out rms relative difference {100 * rel:+.1f} %, p = {1 - p:.2g} that "
            "it is not better; the competing-model stage's rule)")
    say(f"competing models: {note}")
    t = clock_check(prob, t, candidates, thr, min_gain, extra, say, "after the replacement")
    t, joint = clock_interval(prob, t, extra)
    info = {k2: v for k2, v in clock_info.items() if not k2.startswith("joint_")
            and k2 != "interval_reaches_grid_edge"}
    return t, {**info, **joint}, note
