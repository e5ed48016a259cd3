"""Stage 1 of the diagnosis: the candidates (effect x cable) and their vocabulary form.

Maps between the theta layout of :mod:`cdprid.diagnosis._model` and the effect vocabulary of
:mod:`cdprid.effects` (its registry: names and JSON parameters), plausibility bounds,
and what would tell two effects apart — all read from the one table
:data:`cdprid.effects.DIAGNOSIS`; this module names no effect.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.diagnosis._context import DiagnosisContext
from cdprid.diagnosis._model import ThetaLayout
from cdprid.effects import DIAGNOSIS, VOCABULARY

#: effects the diagnosis tests through theta (the vocabulary minus ``none`` and the effects
#: tested on other streams), from :data:`cdprid.effects.DIAGNOSIS`
CANDIDATE_EFFECTS = tuple(k for k in DIAGNOSIS if k in VOCABULARY)


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One testable extension: an effect, optionally on one cable."""

    effect: str
    cable: int | None = None

    @property
    def label(self) -> str:
        """Readable name, e.g. ``tension_gain[cable 2]``."""
        return self.effect if self.cable is None else f"{self.effect}[cable {self.cable}]"

    @property
    def vocabulary_effect(self) -> str:
        """The effect's name in the vocabulary (a diagnosis variant reports its effect)."""
        return DIAGNOSIS[self.effect].vocabulary or self.effect


def alias_label(c: Candidate) -> str:
    """The JSON form of a candidate in ``aliases`` (``effect`` or ``effect:cable=i``)."""
    alias = DIAGNOSIS[c.effect].alias
    if alias:
        return alias
    return c.effect if c.cable is None else f"{c.effect}:cable={c.cable}"


def candidate_list(m: int, has_rotation: bool, robot=None, source: str = "tensions",
                   reference_cable: int | None = None) -> list[Candidate]:
    """Every candidate (effect x cable) for m cables, by group then in the table's order.

    An effect declared ``when="no_pulley"`` (the swivel pulley's opposite arrival direction)
    is a candidate only when robot.toml models no pulley (every radius 0, so the axis may be
    a default); ``when="rotation"`` only when the pose stream rotates; a form of one stream
    (``stream="tensions"`` or ``"currents"``) only on that source; a ``not_on_reference``
    form never on the scale reference drive.

    Parameters
    ----------
    m : int
        Number of cables.
    has_rotation : bool
        Whether the pose stream rotates.
    robot : CableRobot, optional
        Decides the ``when="no_pulley"`` candidates.
    source : str
        The force stream: ``"tensions"`` (load cells) or ``"currents"`` (winch drives).
    reference_cable : int, optional
        The scale reference drive (1-based), currents only.

    Returns
    -------
    list of Candidate
    """
    no_pulley = robot is not None and not np.any(np.asarray(robot.pulley_radius) > 0)
    ok = {"always": True, "no_pulley": no_pulley, "rotation": has_rotation}
    out = []
    for group in sorted({f.group for f in DIAGNOSIS.values()}):
        for name, f in DIAGNOSIS.items():
            if f.group != group or not ok[f.when] or f.stream not in ("any", source):
                continue
            out += ([Candidate(name, i) for i in range(1, m + 1) if not (
                f.not_on_reference and i == reference_cable)] if f.per_cable
                else [Candidate(name)])
    return out


def well_determined(v, cov, ratio: float = 0.4):
    """Shrink the poorly determined directions of a 3-D displacement estimate to zero.

    A displacement of an exit or attachment point along its cable barely changes the cable
    direction, so that component is weakly identifiable (its standard deviation is large).
    Components along covariance eigen-directions whose standard deviation exceeds ``ratio``
    times the estimate's norm are set to zero (the prior of no displacement); the interval
    keeps the full uncertainty.
    """
    w, E = np.linalg.eigh(cov)
    c = E.T @ v
    s = np.sqrt(np.clip(w, 0, None))
    keep = s <= ratio * max(np.linalg.norm(v), 1e-12)
    return E @ (c * keep)


def _split(form, values) -> list:
    """The values of a candidate's theta indices, one entry per block (list when size > 1)."""
    out, i = [], 0
    for _, size in form.blocks:
        seg = values[i:i + size]
        out.append(float(seg[0]) if size == 1 else [float(z) for z in seg])
        i += size
    return out


def vocab_params(c: Candidate, th_values: np.ndarray, layout: ThetaLayout,
                 extra: DiagnosisContext, th_cov=None) -> dict:
    """A candidate's parameters in the vocabulary's JSON form, from theta."""
    form = DIAGNOSIS[c.effect]
    idx = layout.candidate_indices(c.effect, c.cable)
    v = th_values[idx] if idx else np.zeros(0)
    if form.displacement and th_cov is not None:
        v = well_determined(v, th_cov[np.ix_(idx, idx)])
    head = {"cable": c.cable} if form.per_cable else {}
    extra = _with_cable(extra, c.cable)
    if form.params is not None:
        return {**head, **form.params(v, extra)}
    return {**head, **dict(zip(form.keys, _split(form, v), strict=True))}


def _with_cable(extra, cable):
    """The forms' context with the candidate's cable set (a dict gets the key)."""
    if isinstance(extra, DiagnosisContext):
        return dataclasses.replace(extra, cable=cable)
    return {**(extra or {}), "cable": cable}


def implausible(effect: str, params: dict) -> str:
    """A reason string when a refitted effect is physically implausible, else ''.

    Reads the effect's ``ranges``, ``bounds`` and ``nonneg`` of :data:`DIAGNOSIS`;
    parameters not computed from theta (e.g. an amplitude) are not checked.
    """
    form = DIAGNOSIS[effect]
    checked = set(form.keys) | set(form.bounds) | set(form.nonneg) | {"pulley_axis"}
    for k, v in params.items():
        if k in form.ranges:
            lo, hi = form.ranges[k]
            if not lo < v < hi:
                return f"{k} {v:.3g}"
            continue
        if k == "cable" or k not in checked:
            continue
        mag = float(np.linalg.norm(np.atleast_1d(v)))
        if not np.isfinite(mag) or mag > form.bounds.get(k, np.inf):
            return f"{k} = {v}"
        if k in form.nonneg and v < 0:
            return f"{k} = {v:.3g} < 0"
    return ""


def vocab_interval(c: Candidate, th_values, th_std, layout,
                   extra: DiagnosisContext) -> dict:
    """95 % intervals of a candidate's parameters (JSON form) from theta's std."""
    z = 1.959963984540054
    form = DIAGNOSIS[c.effect]
    idx = layout.candidate_indices(c.effect, c.cable)
    v, s = th_values[idx], th_std[idx]
    lo, hi = v - z * s, v + z * s
    extra = _with_cable(extra, c.cable)
    if form.interval is not None:
        return form.interval(lo, hi, extra)
    out = {}
    for key, a, b in zip(form.keys, _split(form, lo), _split(form, hi), strict=True):
        out[key] = ([[x, y] for x, y in zip(a, b, strict=True)] if isinstance(a, list)
                    else [a, b])
    return out


def separated_by(a: str, b: str) -> str:
    """What measurement or trajectory would separate effects ``a`` and ``b``."""
    for x, y in ((a, b), (b, a)):
        text = DIAGNOSIS[x].separated_by.get(y) if x in DIAGNOSIS else None
        if text:
            return text
    return "a longer trajectory that excites different poses, speeds and tensions"


def swap_alternatives(c: Candidate, candidates: list, accepted: list) -> list:
    """Alternatives to a finding tried by the swap stage: same cable, or global effects."""
    out = []
    for a in candidates:
        if a in accepted or not DIAGNOSIS[a.effect].blocks or a == c:
            continue
        if a.cable is None or a.cable == c.cable:
            out.append(a)
    return out
