"""The effect vocabulary of the simulator: unmodelled phenomena injected into synthetic data.

The names and parameter names are a contract shared with the diagnosis (cables numbered
from 1). How each effect is modelled by :func:`cdprid.simulation.simulate`:

``none``
    Nothing.
``time_delay {delay_s}``
    The tension stream lags the pose stream: the tension sample stamped t holds the
    (noise-free) tensions of the plant at ``t - delay_s``, the trajectory being evaluated
    exactly at that time (a true fractional delay).
``tension_offset {cable, offset_N}``
    Load cell ``cable`` reads ``tau + offset_N``.
``tension_gain {cable, gain}``
    Load cell ``cable`` reads ``gain * tau`` (applied before the offset, before noise).
``exit_point_error {cable, displacement_m: [dx, dy, dz]}``
    The true exit point A_i (base frame) is robot.toml's plus the displacement; the plant
    uses the true one, robot.toml keeps the nominal one.
``anchor_point_error {cable, displacement_m}``
    The same for the attachment b_i (platform frame).
``viscous_drag {coefficient_Ns_per_m}``
    A force ``-c v`` on the platform, applied at P (no moment about P); v is the velocity
    of P, base frame.
``pulley {radius_m}``
    Every cable passes over a swivel pulley of that radius (axis from robot.toml, by
    default ``[0, 0, -1]``; reference direction base x) that robot.toml omits: the plant's
    cable directions start at the leave points on the pulley rims (spec v1 pulley model).
    Spec 1.1: ``pulley_axis`` is the direction in which the cable runs into the pulley; to
    simulate a cable arriving from below, give robot.toml ``pulley_axis = [0, 0, 1]``. The
    diagnosis reports the finding with its ``pulley_axis``; when robot.toml models no pulley
    it tests both arrival directions.
``cable_mass {linear_density_kg_per_m}``
    Lumped cable weight: each cable is taken as straight between its leave point and its
    attachment B_i, of length L_i; half of its weight, ``rho L_i g / 2`` (g the gravity
    vector of the plant, so it follows ``frame_tilt``), acts on the platform at B_i (force
    and moment about P). The tensions reported are those along the straight chords (what
    ``W`` multiplies). No sag/catenary shape is modelled.
``frame_tilt {tilt_rad: [rx, ry]}``
    The pose frame (in which robot.toml and pose.csv are expressed) is tilted relative to
    gravity: with ``R_tilt = Ry(ry) Rx(rx)`` (about x first, then about the fixed y) mapping
    pose-frame vectors to the level frame, the plant's gravity in the pose frame is
    ``g_pose = R_tilt^T g`` with g robot.toml's gravity (for g = [0, 0, -9.81]:
    ``g_pose = 9.81 [sin ry, -sin rx cos ry, -cos rx cos ry]``); robot.toml keeps the
    nominal g.
``pulley_friction {cable, coulomb_N, viscous_Ns_per_m}``
    Friction where cable ``cable`` (or ``"all"``: the same coefficients on every cable, as
    on a robot whose pulleys are alike) runs over its pulley/guide between the platform and a
    load cell on the winch side. With ``dl/dt`` the rate of the cable length between the
    exit point and the platform (``dl/dt = -W_i^T [v; omega]``, > 0 paying out), the load
    cell reads ``tau - coulomb_N sign(dl/dt) - viscous_Ns_per_m dl/dt`` before gain,
    offset and noise: hauling the cable in, the winch side needs more than the platform
    side gets. Both coefficients are >= 0.
``cable_elasticity {cable, EA_N}``
    Cable ``cable`` stretches under its tension (Hooke's law, EA_N its axial stiffness E A
    in N): the winch encoder, which measures the unstrained length paid out, reads
    ``l = L / (1 + tau / EA_N)`` where L is the geometric (stretched) length between the
    cable's leave point and its attachment B_i and tau its tension; the other cables read
    ``l = L``. It changes no force: it shows only in the optional ``lengths.csv`` stream
    (``t, l_1..l_m``, m, at the tension times; a cdprid extension of spec 1.1, see
    ``docs/lengths.md``), which the simulator writes with this effect (or with
    ``--lengths``) plus encoder noise ``--noise-length``. The diagnosis fits it per cable
    (with an encoder zero offset) only when a dataset has ``lengths.csv``.
``rotational_dynamics {amplitude_rad}``
    The platform also performs small rotations (:func:`cdprid.model.small_rotation`,
    that peak angle about each axis), so the rotational inertia and angular terms act;
    pose.csv then carries quaternions.

Several effects may be combined (also the same effect on several cables). ``docs/effects.md``
is generated from this docstring, the effects defined in their own modules
(``tension_drift``: :mod:`cdprid.effects._tension_drift`; ``external_wrench``:
:mod:`cdprid.effects._external_wrench`; ``load_cell_hysteresis``:
:mod:`cdprid.effects._load_cell_hysteresis`) and :data:`VOCABULARY`
(:func:`vocabulary_markdown`). The load cells' sensor chain is declared once, in physical
order, in :mod:`cdprid.effects._sensor`.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from cdprid.base import InputError
from cdprid.effects import _external_wrench, _load_cell_hysteresis, _tension_drift
from cdprid.effects._form import DiagnosisForm

__all__ = [
    "VOCABULARY",
    "Effect",
    "parse_effect",
    "validate_effects",
    "true_robot",
    "true_gravity",
    "tilt_matrix",
    "load_cell_friction",
    "encoder_lengths",
    "vocabulary_markdown",
    "effect_parameters_table",
    "DIAGNOSIS",
    "DiagnosisForm",
    "tilt_gravity",
    "EPISODE_EFFECTS",
]

#: effect name -> {parameter name: kind}; kinds: 'float', 'cable', 'vec3', 'vec2'
VOCABULARY: dict[str, dict[str, str]] = {
    "none": {},
    "time_delay": {"delay_s": "float"},
    "tension_offset": {"cable": "cable", "offset_N": "float"},
    "tension_gain": {"cable": "cable", "gain": "float"},
    "exit_point_error": {"cable": "cable", "displacement_m": "vec3"},
    "anchor_point_error": {"cable": "cable", "displacement_m": "vec3"},
    "viscous_drag": {"coefficient_Ns_per_m": "float"},
    "pulley": {"radius_m": "float"},
    "cable_mass": {"linear_density_kg_per_m": "float"},
    "frame_tilt": {"tilt_rad": "vec2"},
    "rotational_dynamics": {"amplitude_rad": "float"},
    "pulley_friction": {"cable": "cable", "coulomb_N": "float", "viscous_Ns_per_m": "float"},
    "cable_elasticity": {"cable": "cable", "EA_N": "float"},
    _tension_drift.NAME: _tension_drift.PARAMETERS,
    _external_wrench.NAME: _external_wrench.PARAMETERS,
    _load_cell_hysteresis.NAME: _load_cell_hysteresis.PARAMETERS,
}

#: effects located in time by the episodes stage (:mod:`cdprid.episodes`), not candidates of
#: the diagnosis
EPISODE_EFFECTS = frozenset({_external_wrench.NAME})


#: per-cable effects that also have a form common to every cable (``"cable": "all"``)
ALL_CABLES = frozenset({"pulley_friction"})


def _convert(effect: str, key: str, kind: str, value):
    where = f"effect '{effect}' parameter '{key}'"
    if kind == "cable" and effect in ALL_CABLES and isinstance(value, str) \
            and value.strip().lower() == "all":
        return "all"
    if isinstance(value, str):
        text = value.strip()
        if kind in ("vec3", "vec2"):
            try:
                value = (
                    json.loads(text)
                    if text.startswith("[")
                    else [float(v) for v in text.split(",")]
                )
            except (ValueError, json.JSONDecodeError):
                raise InputError(
                    f"{where} must be a list of numbers like 0.01,0,-0.02, got {text!r}."
                ) from None
        else:
            try:
                value = float(text)
            except ValueError:
                what = "a number" if kind != "cable" else (
                    "a cable number 1, 2, ..." + (" or all" if effect in ALL_CABLES else ""))
                raise InputError(f"{where} must be {what}, got {text!r}.") from None
    if kind in ("vec3", "vec2"):
        n = 3 if kind == "vec3" else 2
        try:
            arr = [float(v) for v in value]
        except (TypeError, ValueError):
            arr = []
        if len(arr) != n or not all(np.isfinite(arr)):
            raise InputError(f"{where} must be a list of {n} finite numbers, got {value!r}.")
        return arr
    if isinstance(value, bool):
        raise InputError(f"{where} must be a number, got {value!r}.")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where} must be a number, got {value!r}.") from None
    if not np.isfinite(v):
        raise InputError(f"{where} must be finite, got {value!r}.")
    if kind == "cable":
        if v != int(v) or v < 1:
            raise InputError(f"{where} must be a cable number 1, 2, ..."
                             + (" or all" if effect in ALL_CABLES else "")
                             + f", got {value!r}.")
        return int(v)
    return v


@dataclasses.dataclass(frozen=True)
class Effect:
    """One injected effect of the vocabulary (validated at construction).

    Parameters
    ----------
    name : str
        A key of :data:`VOCABULARY`.
    params : dict
        Exactly its parameters; strings (as from the command line) are converted:
        ``"3"``, ``"1.05"``, ``"0.01,0,-0.02"`` or ``"[0.01, 0, -0.02]"``.

    Raises
    ------
    ValueError
        Unknown effect or parameter names, missing parameters or bad values (one sentence
        listing the valid names).
    """

    name: str
    params: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if self.name not in VOCABULARY:
            raise InputError(
                f"unknown effect {self.name!r}; valid effects: {', '.join(VOCABULARY)}."
            )
        spec = VOCABULARY[self.name]
        valid = ", ".join(spec) if spec else "none"
        unknown = [k for k in self.params if k not in spec]
        if unknown:
            raise InputError(
                f"unknown parameter {unknown[0]!r} for effect '{self.name}'; "
                f"valid parameters: {valid}."
            )
        missing = [k for k in spec if k not in self.params]
        if missing:
            raise InputError(
                f"effect '{self.name}' needs the parameter(s) {', '.join(missing)} "
                f"(e.g. --param {missing[0]}=...); valid parameters: {valid}."
            )
        clean = {k: _convert(self.name, k, spec[k], v) for k, v in self.params.items()}
        for key in ("gain", "EA_N"):
            if key in clean and clean[key] <= 0:
                raise InputError(
                    f"effect '{self.name}' parameter '{key}' must be > 0, got {clean[key]}."
                )
        for key in (
            "delay_s",
            "coefficient_Ns_per_m",
            "radius_m",
            "linear_density_kg_per_m",
            "amplitude_rad",
            "coulomb_N",
            "viscous_Ns_per_m",
            "width_N",
        ):
            if key in clean and clean[key] < 0:
                raise InputError(
                    f"effect '{self.name}' parameter '{key}' must be >= 0, got {clean[key]}."
                )
        if self.name == _external_wrench.NAME:
            _external_wrench.check(clean)
        object.__setattr__(self, "params", clean)


def parse_effect(name: str, pairs) -> Effect:
    """Build an :class:`Effect` from ``key=value`` strings (command-line form).

    Parameters
    ----------
    name : str
    pairs : sequence of str
        E.g. ``["cable=3", "gain=1.05"]``.
    """
    params = {}
    for text in pairs:
        if "=" not in text:
            raise InputError(f"--param {text!r} must have the form key=value (effect '{name}').")
        k, v = text.split("=", 1)
        params[k.strip()] = v
    return Effect(name, params)


def validate_effects(effects, n_cables: int) -> list[Effect]:
    """Check cable numbers against the robot and the combination of effects.

    Returns
    -------
    list of Effect
    """
    out = []
    for e in effects:
        e = e if isinstance(e, Effect) else Effect(*e)
        c = e.params.get("cable")
        if c is not None and c != "all" and c > n_cables:
            raise InputError(
                f"effect '{e.name}' refers to cable {c} but the robot has {n_cables} cables "
                f"(numbered 1 to {n_cables})."
            )
        out.append(e)
    for single in (
        "time_delay",
        "viscous_drag",
        "pulley",
        "cable_mass",
        "frame_tilt",
        "rotational_dynamics",
    ):
        if sum(e.name == single for e in out) > 1:
            raise InputError(f"effect '{single}' is given more than once; give it once.")
    return out


def true_robot(robot, effects):
    """The plant's robot: nominal geometry with exit/anchor errors and pulleys applied."""
    B_A = np.array(robot.B_A)
    P_b = np.array(robot.P_b)
    radius = np.array(robot.pulley_radius)
    for e in effects:
        if e.name == "exit_point_error":
            B_A[e.params["cable"] - 1] += np.asarray(e.params["displacement_m"])
        elif e.name == "anchor_point_error":
            P_b[e.params["cable"] - 1] += np.asarray(e.params["displacement_m"])
        elif e.name == "pulley":
            radius[:] = e.params["radius_m"]
    return robot.replace(B_A=B_A, P_b=P_b, pulley_radius=radius)


def load_cell_friction(effects, W, v, omega) -> np.ndarray:
    """What the load cells read in excess of the tension, ``(n, m)``, from ``pulley_friction``.

    Parameters
    ----------
    effects : sequence of Effect
    W : (n, 6, m) true wrench matrices
    v, omega : (n, 3) platform velocity and angular rate at the tension times

    Returns
    -------
    ndarray (n, m)
        ``-coulomb_N sign(dl/dt) - viscous_Ns_per_m dl/dt`` on the cables with friction.
    """
    from cdprid.effects._sensor import load_cell_reading

    W = np.asarray(W)
    zero = np.zeros((W.shape[0], W.shape[2]))
    friction = [e for e in effects if e.name == "pulley_friction"]
    return load_cell_reading(friction, zero, W, v, omega, np.zeros(W.shape[0]))


def encoder_lengths(effects, L, tension) -> np.ndarray:
    """What the winch encoders read, ``(n, m)``: ``L / (1 + tau / EA_N)`` on elastic cables.

    Parameters
    ----------
    effects : sequence of Effect
    L : (n, m) geometric cable lengths (leave point to attachment), m
    tension : (n, m) cable tensions, N

    Returns
    -------
    ndarray (n, m)
        The unstrained lengths (``L`` where a cable has no ``cable_elasticity``).
    """
    out = np.array(L, float)
    for e in effects:
        if e.name == "cable_elasticity":
            i = e.params["cable"] - 1
            out[:, i] = out[:, i] / (1.0 + np.asarray(tension)[:, i] / e.params["EA_N"])
    return out


def tilt_matrix(rx: float, ry: float) -> np.ndarray:
    """``R_tilt = Ry(ry) Rx(rx)``: pose-frame vectors -> level frame (see module docstring)."""
    cx, sx, cy, sy = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    Ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    return Ry @ Rx


def true_gravity(robot, effects) -> np.ndarray:
    """Gravity of the plant expressed in the pose frame (``frame_tilt`` applied)."""
    g = np.asarray(robot.gravity, float)
    for e in effects:
        if e.name == "frame_tilt":
            g = tilt_matrix(*e.params["tilt_rad"]).T @ g
    return g


def effect_parameters_table(effects) -> dict:
    """The ``[truth.effect_parameters]`` table of meta.toml.

    One effect: its parameters as flat keys (e.g. ``delay_s = 0.025``). Several effects:
    the flat keys that are not ambiguous (given by one effect only), plus one sub-table per
    effect name (``[truth.effect_parameters.tension_gain]``); a name used again gets
    ``_2``, ``_3``... appended.
    """
    effects = [e for e in effects if e.name != "none"]
    if len(effects) == 1:
        return dict(effects[0].params)
    flat: dict = {}
    counts: dict = {}
    for e in effects:
        for k, v in e.params.items():
            counts[k] = counts.get(k, 0) + 1
            flat[k] = v
    out = {k: v for k, v in flat.items() if counts[k] == 1}
    seen: dict = {}
    for e in effects:
        seen[e.name] = seen.get(e.name, 0) + 1
        key = e.name if seen[e.name] == 1 else f"{e.name}_{seen[e.name]}"
        out[key] = dict(e.params)
    return out


def vocabulary_markdown() -> str:
    """``docs/effects.md``: the vocabulary table and each effect's model, from this module.

    Generated from :data:`VOCABULARY` and the module docstring (one definition of each
    effect); ``tests/effects/test_vocabulary.py`` checks that the committed file is up to date.
    """
    doc = __doc__ or ""
    lines = ["# Effect vocabulary", "",
             "Generated by `cdprid.effects.vocabulary_markdown()` from "
             "`src/cdprid/effects/_effects.py` "
             "(do not edit by hand). Cables are numbered from 1; the simulator injects these "
             "effects (`cdprid simulate --effect NAME --param key=value`) and the diagnosis "
             "names them (`cdprid diagnose`).", "",
             "| effect | parameters |", "|---|---|"]
    for name, spec in VOCABULARY.items():
        params = ", ".join(f"`{k}` ({v})" for k, v in spec.items()) or "-"
        lines.append(f"| `{name}` | {params} |")
    lines += ["", "## Models", ""]
    body = doc.split("\n\n", 2)[-1] if doc.count("\n\n") >= 2 else doc
    body = (body.split("\n\nSeveral effects")[0] + "\n" + _tension_drift.DOC + "\n"
            + _external_wrench.DOC + "\n" + _load_cell_hysteresis.DOC)
    for block in body.strip().split("\n``"):
        text = block if block.startswith("``") else "``" + block
        head, _, rest = text.partition("\n")
        lines += [f"### {head.strip()}", "", " ".join(x.strip() for x in rest.split("\n")), ""]
    lines += ["## How the diagnosis represents them", "",
              "From `cdprid.effects.DIAGNOSIS` (the one table the diagnosis's candidates and "
              "theta layout read). `cable_elasticity` is tested on the winch-encoder stream "
              "`lengths.csv` (docs/lengths.md), not through theta.", "",
              "| candidate | theta blocks | per cable | tested when | reported as |",
              "|---|---|---|---|---|"]
    for name, f in DIAGNOSIS.items():
        blocks = ", ".join(f"`{b}` ({n})" for b, n in f.blocks) or "- (rotational terms)"
        lines.append(f"| `{name}` | {blocks} | {'yes' if f.per_cable else 'no'} | {f.when} | "
                     f"`{f.vocabulary or name}` |")
    lines += ["", "Adding an effect: its entry in `VOCABULARY` and the model text in the "
              "docstring of `src/cdprid/effects/_effects.py`, its simulation in that module, "
              "and its "
              "`DiagnosisForm` in `DIAGNOSIS` (blocks, candidates, JSON form, intervals, bounds, "
              "what separates it from others) with its physics in the forward model as hooks "
              "(`tension`, `geometry`, `leave`, `gravity`, `load`, `model`); "
              "`cdprid.diagnosis._model` applies them in the table's order and names no "
              "effect.", ""]
    return "\n".join(lines).rstrip() + "\n"


# ----------------------------------------------------------------------------- diagnosis forms


def tilt_gravity(g, tilt):
    """Gravity in the pose frame for a frame tilt ``[rx, ry]`` (JAX; see ``frame_tilt``)."""
    import jax.numpy as jnp

    rx, ry = tilt[0], tilt[1]
    cx, sx, cy, sy = jnp.cos(rx), jnp.sin(rx), jnp.cos(ry), jnp.sin(ry)
    Rx = jnp.array([[1.0, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = jnp.array([[cy, 0, sy], [0, 1.0, 0], [-sy, 0, cy]])
    return (Ry @ Rx).T @ g  # g_pose = R_tilt^T g, R_tilt = Ry(ry) Rx(rx)


def _flipped_leave(T, geo, q, c):
    """A swivel pulley of radius ``pulley_flip`` whose cable arrives opposite to the axis,
    added as a displacement of the leave point (exact when either radius is 0)."""
    from cdprid.model import pulley_leave_point

    T_flip, _, _ = pulley_leave_point(geo["A"], c["bb"], c["p"], q["pulley_flip"], -c["k"],
                                      c["ref"])
    return T + (T_flip - geo["A"])


def _drag_model(y, d, q):
    import jax.numpy as jnp

    return y + jnp.concatenate([d.v * q["drag"], jnp.zeros_like(d.v)], axis=1)


def _friction_tension(tau, q, c):
    import jax.numpy as jnp

    slide = c.get("slide", jnp.sign(c["ldot"]))  # expected sign, see diagnosis.problem
    return tau + q["coulomb"] * slide + q["pvisc"] * c["ldot"]


def _common_friction_tension(tau, q, c):
    import jax.numpy as jnp

    slide = c.get("slide", jnp.sign(c["ldot"]))
    return tau + q["coulomb_all"] * slide + q["pvisc_all"] * c["ldot"]


def _pulley_params(flip: bool):
    def params(v, extra):
        axis = np.asarray(extra.get("pulley_axis", [0.0, 0.0, -1.0]), float)
        axis = -axis if flip else axis
        return {"radius_m": float(v[0]), "pulley_axis": (axis + 0.0).tolist()}
    return params


def _rotation_interval(lo, hi, extra):
    z = 1.959963984540054
    a, s = extra["rotation_amplitude"], extra.get("rotation_amplitude_std", 0.0)
    return {"amplitude_rad": [a - z * s, a + z * s]}


_GAIN_VS_GEOMETRY = ("the same poses at two pretension levels (a gain scales with the tension, "
                     "a direction error with the pose)")

#: the diagnosis's form of every effect it tests, in theta-layout order (``pulley_flipped``
#: is the diagnosis's second arrival direction of ``pulley``; ``cable_elasticity`` is tested
#: on the lengths stream by :mod:`cdprid.diagnosis._lengths`, not through theta)
DIAGNOSIS: dict[str, DiagnosisForm] = {
    "time_delay": DiagnosisForm(
        blocks=(("delay", 1),), group=0, keys=("delay_s",), bounds={"delay_s": 0.5}, clock=True,
        report_size=True,
        # first-order expansion about the linearisation point: exact in value and slope
        tension=lambda tau, q, c: tau + (q["delay"] - c["at"]["delay"]) * c["taud"],
        separated_by={"viscous_drag": "faster motion with the same velocities (a delay "
                      "follows the tension rate, drag the velocity)"}),
    "tension_offset": DiagnosisForm(
        blocks=(("offset", 1),), per_cable=True, group=1, keys=("offset_N",),
        tension=lambda tau, q, c: tau - q["offset"],
        bounds={"offset_N": 1e3},
        separated_by={"tension_gain": "a trajectory with a wider range of tension on that "
                      "cable (a gain scales with the tension, an offset does not)"}),
    _tension_drift.NAME: _tension_drift.FORM,
    "tension_gain": DiagnosisForm(
        blocks=(("gain", 1),), per_cable=True, group=1,
        tension=lambda tau, q, c: tau / (1.0 + q["gain"]),
        params=lambda v, extra: {"gain": float(1.0 + v[0])},
        interval=lambda lo, hi, extra: {"gain": [float(1 + lo[0]), float(1 + hi[0])]},
        ranges={"gain": (0.5, 2.0)},
        separated_by={"exit_point_error": _GAIN_VS_GEOMETRY,
                      "anchor_point_error": _GAIN_VS_GEOMETRY}),
    "exit_point_error": DiagnosisForm(
        blocks=(("exit", 3),), per_cable=True, group=1, keys=("displacement_m",),
        geometry=lambda geo, q: {**geo, "A": geo["A"] + q["exit"]},
        displacement=True, bounds={"displacement_m": 0.25},
        separated_by={"anchor_point_error": "rotations of the platform (an attachment error "
                      "turns with it, an exit error does not)"}),
    "anchor_point_error": DiagnosisForm(
        blocks=(("anchor", 3),), per_cable=True, group=1, keys=("displacement_m",),
        geometry=lambda geo, q: {**geo, "b": geo["b"] + q["anchor"]},
        displacement=True, bounds={"displacement_m": 0.25}),
    "viscous_drag": DiagnosisForm(
        blocks=(("drag", 1),), keys=("coefficient_Ns_per_m",), model=_drag_model,
        bounds={"coefficient_Ns_per_m": 1e3}, nonneg=("coefficient_Ns_per_m",),
        separated_by={"pulley_friction": "motion at several speeds (Coulomb friction does not "
                      "grow with the speed)"}),
    "pulley": DiagnosisForm(
        blocks=(("radius", 1),), keys=("radius_m",), params=_pulley_params(False),
        geometry=lambda geo, q: {**geo, "r": geo["r"] + q["radius"]},
        bounds={"radius_m": 0.25}, nonneg=("radius_m",),
        separated_by={"pulley_flipped": "poses close to the exit points and far below them "
                      "(the wrap differs by arrival)"}),
    "cable_mass": DiagnosisForm(
        blocks=(("rho", 1),), keys=("linear_density_kg_per_m",),
        load=lambda f, Ln, g, q: f + 0.5 * q["rho"] * Ln * g,
        bounds={"linear_density_kg_per_m": 5.0}, nonneg=("linear_density_kg_per_m",)),
    "frame_tilt": DiagnosisForm(
        blocks=(("tilt", 2),), keys=("tilt_rad",), bounds={"tilt_rad": 0.05},
        gravity=lambda g, q: tilt_gravity(g, q["tilt"])),
    "rotational_dynamics": DiagnosisForm(
        group=4, when="rotation", base_model=True,
        params=lambda v, extra: {"amplitude_rad": float(extra["rotation_amplitude"])},
        interval=_rotation_interval),
    "pulley_friction": DiagnosisForm(
        blocks=(("coulomb", 1), ("pvisc", 1)), per_cable=True, group=1,
        keys=("coulomb_N", "viscous_Ns_per_m"), tension=_friction_tension,
        bounds={"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3},
        nonneg=("coulomb_N", "viscous_Ns_per_m")),
    "pulley_friction_all": DiagnosisForm(
        blocks=(("coulomb_all", 1), ("pvisc_all", 1)), group=1,
        keys=("coulomb_N", "viscous_Ns_per_m"), tension=_common_friction_tension,
        params=lambda v, extra: {"cable": "all", "coulomb_N": float(v[0]),
                                 "viscous_Ns_per_m": float(v[1])},
        interval=lambda lo, hi, extra: {"coulomb_N": [float(lo[0]), float(hi[0])],
                                        "viscous_Ns_per_m": [float(lo[1]), float(hi[1])]},
        vocabulary="pulley_friction", alias="pulley_friction:cable=all", report_size=True,
        bounds={"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3},
        nonneg=("coulomb_N", "viscous_Ns_per_m"),
        separated_by={"pulley_friction": "motion of one cable at a time (friction on one "
                      "pulley or the same on all)",
                      "viscous_drag": "motion at several speeds (Coulomb friction does not "
                      "grow with the speed)"}),
    "pulley_flipped": DiagnosisForm(
        blocks=(("pulley_flip", 1),), group=3, when="no_pulley", keys=("radius_m",),
        params=_pulley_params(True), vocabulary="pulley", alias="pulley:arriving_opposite",
        leave=_flipped_leave,
        bounds={"radius_m": 0.25}, nonneg=("radius_m",)),
    _load_cell_hysteresis.NAME: _load_cell_hysteresis.FORM,
}
