"""Geometry findings selected again once the sensor side of the model is complete (issue 37).

The greedy path takes one effect at a time, and a geometry error (an exit or attachment point
off its surveyed place) accepted early carries whatever the model then lacks. On the floor-
winch robot's seed 2 (a 3 cm exit-point error on cable 2, a hysteretic cell on cable 1, a
13 ms clock offset, friction on every pulley, an offset on cable 7) step 3 took a 1.6 cm
anchor error on cable 3 while the clock offset stood at +58 ms and the hysteretic cell was
not yet in the model; a 2.1 cm anchor error on cable 1 then joined it, and the two together
stood in for the one exit-point error. Given the final sensor side, neither anchor error alone
improves the held-out prediction by 0.41 % (linearised), the exit-point error alone by 1.7 %
(the pair of anchor errors 1.9 %): the two were needed only beside each other, and backward
elimination, which removes one finding at a time, cannot see that.

:func:`geometry_reselection` therefore withdraws every geometry finding when a sensor-side
finding was accepted after the first of them, selects geometry again by the search's own
forward steps (the same gates: the first step's threshold, the held-out gain ``min_gain``)
from that sensor-side model, and keeps the model that predicts the held-out data better, the
one with fewer findings when the two are within ``min_gain``
(:func:`cdprid.diagnosis._restart.choose`, the rule of the second start). When the
geometry findings were all accepted after the sensor side, the forward steps would retrace
the same path: nothing is done.
"""

from __future__ import annotations

from cdprid.diagnosis._problem import Problem
from cdprid.diagnosis._restart import choose
from cdprid.diagnosis._selection import Selection, extends_base, forward_step, withdraw
from cdprid.effects import DIAGNOSIS


def is_geometry(c) -> bool:
    """Whether candidate ``c`` is a geometry error: it moves a point of the geometry (exit or
    attachment point) or tilts the frame (a form on gravity)."""
    form = DIAGNOSIS[c.effect]
    return bool(form.displacement) or getattr(form, "gravity", None) is not None


def needs_reselection(accepted) -> bool:
    """True when a sensor-side finding (not geometry, not an extension of the base model) was
    accepted after the first geometry finding: that geometry finding was chosen against an
    incomplete sensor side. ``accepted`` in the order of acceptance."""
    first = next((k for k, c in enumerate(accepted) if is_geometry(c)), None)
    if first is None:
        return False
    return any(not is_geometry(c) and not extends_base(c) for c in accepted[first + 1:])


def geometry_reselection(prob: Problem, base, s: Selection, candidates, alpha: float,
                         min_gain: float, thr_p: float, max_effects: int, extra: dict,
                         say) -> tuple[Selection, dict]:
    """The model with its geometry findings selected again given its sensor side.

    Parameters
    ----------
    prob, base, s
        The problem, the base fit and the model after backward elimination.
    candidates : list
        The search's candidates (only the geometry ones are tried).
    alpha, min_gain, thr_p : float
        The search's level, held-out gate (relative) and the first step's threshold.
    max_effects : int
        At most this many findings in the re-selected model.
    extra : dict
        The candidates' context (:func:`cdprid.diagnosis._pipeline._base_stage`).
    say : callable
        Progress.

    Returns
    -------
    (Selection, dict)
        The kept model and ``info["geometry_reselection"]``: whether it was tried, the two
        models' findings and held-out rms and which was kept.
    """
    if not needs_reselection(s.accepted):
        return s, {"tried": False}
    t = s
    while (k := next((k for k, c in enumerate(t.accepted) if is_geometry(c)), None)) is not None:
        t = withdraw(prob, t, k, extra)
    # the sensor side first (what the geometry carried may be a sensor error the greedy path
    # never reached), then the geometry given it
    for pool in ([c for c in candidates if not is_geometry(c) and not extends_base(c)],
                 [c for c in candidates if is_geometry(c)]):
        for step in range(len(t.accepted) + 1, max_effects + 1):
            nxt, _, _ = forward_step(prob, base, t, pool, (), alpha, min_gain, extra,
                                     lambda m: say(f"geometry again: {m}"), step, thr_p)
            if nxt is None:
                break
            t = nxt
    info = {"tried": True, "greedy_path": [c.label for c in s.accepted],
            "again": [c.label for c in t.accepted]}
    if set(t.accepted) == set(s.accepted):
        say("geometry again: the same geometry findings given the complete sensor side")
        return s, {**info, "kept": "same model"}
    keep, other, rel = choose(prob, s, t, min_gain)
    say(f"geometry again: kept {' + '.join(c.label for c in keep.accepted) or 'no finding'} "
        f"({'the greedy path' if keep is s else 'geometry selected again'}); the other model "
        f"({' + '.join(c.label for c in other.accepted)}) has a held-out rms {100 * rel:+.2f} % "
        "from it")
    return keep, {**info, "kept": "greedy path" if keep is s else "geometry selected again",
                  "other_relative_difference": float(rel)}


__all__ = ["geometry_reselection", "is_geometry", "needs_reselection"]
