"""Stage 1 of the diagnosis: the candidates (effect x cable) and their vocabulary form.

Maps between the theta layout of :mod:`cdprid.diagnosis.model` and the effect vocabulary of
:mod:`cdprid.effects` (names and JSON parameters), plausibility bounds, and what would tell
two effects apart.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .model import ThetaLayout

#: effects the diagnosis tests (the simulator's vocabulary minus ``none``)
CANDIDATE_EFFECTS = (
    "time_delay",
    "tension_offset",
    "tension_gain",
    "exit_point_error",
    "anchor_point_error",
    "viscous_drag",
    "pulley",
    "cable_mass",
    "frame_tilt",
    "rotational_dynamics",
    "pulley_friction",
)


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
        """The effect's name in the vocabulary (``pulley_flipped`` is a ``pulley``)."""
        return "pulley" if self.effect == "pulley_flipped" else self.effect


def alias_label(c: Candidate) -> str:
    """The JSON form of a candidate in ``aliases`` (``effect`` or ``effect:cable=i``)."""
    if c.effect == "pulley_flipped":
        return "pulley:arriving_opposite"
    return c.effect if c.cable is None else f"{c.effect}:cable={c.cable}"


def candidate_list(m: int, has_rotation: bool, robot=None) -> list[Candidate]:
    """Every candidate (effect x cable) for m cables.

    A swivel pulley is a candidate in the direction of robot.toml's ``pulley_axis``; when
    robot.toml models no pulley (every radius 0, so the axis may be a default), the opposite
    arrival direction (``pulley_flipped``: the cable comes up from below) is a candidate too.
    """
    out = [Candidate("time_delay")]
    for eff in ("tension_offset", "tension_gain", "exit_point_error", "anchor_point_error",
                "pulley_friction"):
        out += [Candidate(eff, i) for i in range(1, m + 1)]
    out += [Candidate("viscous_drag"), Candidate("pulley"), Candidate("cable_mass"),
            Candidate("frame_tilt")]
    if robot is not None and not np.any(np.asarray(robot.pulley_radius) > 0):
        out.append(Candidate("pulley_flipped"))
    if has_rotation:
        out.append(Candidate("rotational_dynamics"))
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


def vocab_params(c: Candidate, th_values: np.ndarray, layout: ThetaLayout, extra: dict,
                  th_cov=None) -> dict:
    """A candidate's parameters in the vocabulary's JSON form, from theta."""
    idx = layout.candidate_indices(c.effect, c.cable) if c.effect != "rotational_dynamics" else []
    v = th_values[idx] if idx else None
    if c.effect in ("exit_point_error", "anchor_point_error") and th_cov is not None:
        v = well_determined(v, th_cov[np.ix_(idx, idx)])
    if c.effect == "time_delay":
        return {"delay_s": float(v[0])}
    if c.effect == "tension_offset":
        return {"cable": c.cable, "offset_N": float(v[0])}
    if c.effect == "tension_gain":
        return {"cable": c.cable, "gain": float(1.0 + v[0])}
    if c.effect in ("exit_point_error", "anchor_point_error"):
        return {"cable": c.cable, "displacement_m": [float(z) for z in v]}
    if c.effect == "viscous_drag":
        return {"coefficient_Ns_per_m": float(v[0])}
    if c.effect in ("pulley", "pulley_flipped"):
        axis = np.asarray(extra.get("pulley_axis", [0.0, 0.0, -1.0]), float)
        axis = -axis if c.effect == "pulley_flipped" else axis
        return {"radius_m": float(v[0]), "pulley_axis": (axis + 0.0).tolist()}
    if c.effect == "cable_mass":
        return {"linear_density_kg_per_m": float(v[0])}
    if c.effect == "frame_tilt":
        return {"tilt_rad": [float(v[0]), float(v[1])]}
    if c.effect == "rotational_dynamics":
        return {"amplitude_rad": float(extra["rotation_amplitude"])}
    if c.effect == "pulley_friction":
        return {"cable": c.cable, "coulomb_N": float(v[0]), "viscous_Ns_per_m": float(v[1])}
    raise KeyError(c.effect)


#: plausibility bounds of a refitted effect (a larger value means a degenerate linearisation)
BOUNDS = {"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3, "delay_s": 0.5, "offset_N": 1e3,
           "displacement_m": 0.25, "coefficient_Ns_per_m": 1e3, "radius_m": 0.25,
           "linear_density_kg_per_m": 5.0, "tilt_rad": 0.05}


def implausible(effect: str, params: dict) -> str:
    """A reason string when a refitted effect is physically implausible, else ''."""
    for k, v in params.items():
        if k == "cable":
            continue
        if k == "gain":
            if not 0.5 < v < 2.0:
                return f"gain {v:.3g}"
            continue
        if k == "amplitude_rad":
            continue
        mag = float(np.linalg.norm(np.atleast_1d(v)))
        if not np.isfinite(mag) or mag > BOUNDS.get(k, np.inf):
            return f"{k} = {v}"
        if k in ("radius_m", "linear_density_kg_per_m", "coefficient_Ns_per_m") and v < 0:
            return f"{k} = {v:.3g} < 0"
        if k in ("coulomb_N", "viscous_Ns_per_m") and v < 0:
            return f"{k} = {v:.3g} < 0"
    return ""


def vocab_interval(c: Candidate, th_values, th_std, layout, extra) -> dict:
    """95 % intervals of a candidate's parameters (JSON form) from theta's std."""
    z = 1.959963984540054
    if c.effect == "rotational_dynamics":
        a = extra["rotation_amplitude"]
        s = extra.get("rotation_amplitude_std", 0.0)
        return {"amplitude_rad": [a - z * s, a + z * s]}
    idx = layout.candidate_indices(c.effect, c.cable)
    v, s = th_values[idx], th_std[idx]
    lo, hi = v - z * s, v + z * s
    if c.effect == "tension_gain":
        return {"gain": [float(1 + lo[0]), float(1 + hi[0])]}
    if c.effect == "pulley_friction":
        return {"coulomb_N": [float(lo[0]), float(hi[0])],
                "viscous_Ns_per_m": [float(lo[1]), float(hi[1])]}
    name = {"time_delay": "delay_s", "tension_offset": "offset_N", "viscous_drag":
            "coefficient_Ns_per_m", "pulley": "radius_m", "pulley_flipped": "radius_m",
            "cable_mass": "linear_density_kg_per_m"}
    if c.effect in name:
        return {name[c.effect]: [float(lo[0]), float(hi[0])]}
    key = "tilt_rad" if c.effect == "frame_tilt" else "displacement_m"
    return {key: [[float(a), float(b)] for a, b in zip(lo, hi, strict=True)]}


#: what would separate two effects the data cannot tell apart (for ``separated_by``)
_SEPARATE = {
    frozenset({"pulley", "pulley_flipped"}):
        "poses close to the exit points and far below them (the wrap differs by arrival)",
    frozenset({"tension_offset", "tension_gain"}):
        "a trajectory with a wider range of tension on that cable (a gain scales with the "
        "tension, an offset does not)",
    frozenset({"tension_gain", "exit_point_error"}):
        "the same poses at two pretension levels (a gain scales with the tension, a "
        "direction error with the pose)",
    frozenset({"tension_gain", "anchor_point_error"}):
        "the same poses at two pretension levels (a gain scales with the tension, a "
        "direction error with the pose)",
    frozenset({"exit_point_error", "anchor_point_error"}):
        "rotations of the platform (an attachment error turns with it, an exit error does not)",
    frozenset({"time_delay", "viscous_drag"}):
        "faster motion with the same velocities (a delay follows the tension rate, drag the "
        "velocity)",
    frozenset({"viscous_drag", "pulley_friction"}):
        "motion at several speeds (Coulomb friction does not grow with the speed)",
}


def separated_by(a: str, b: str) -> str:
    """What measurement or trajectory would separate effects ``a`` and ``b``."""
    return _SEPARATE.get(frozenset({a, b}),
                         "a longer trajectory that excites different poses, speeds and tensions")


def swap_alternatives(c: Candidate, candidates: list, accepted: list) -> list:
    """Alternatives to a finding tried by the swap stage: same cable, or global effects."""
    out = []
    for a in candidates:
        if a in accepted or a.effect == "rotational_dynamics" or a == c:
            continue
        if a.cable is None or a.cable == c.cable:
            out.append(a)
    return out
