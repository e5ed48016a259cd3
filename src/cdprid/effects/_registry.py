"""The registry: every effect's spec, one line each, and the tables derived from it.

:data:`REGISTRY` is the only list of effects. Its order is the vocabulary's, the diagnosis's
table and theta layout (a spec's variants follow it); the load cell's sensor chain is ordered
by each spec's :class:`~cdprid.effects._spec.Place` (physics), and the registry must list the
effects whose diagnosis form undoes a tension reading in the reverse of that order (checked
here, at import). Adding an effect: its module ``_name.py`` with one ``SPEC`` and one line
below (see ``docs/effects.md``, "Adding an effect").
"""

from __future__ import annotations

import importlib

from cdprid.effects._form import DiagnosisForm, SpecError
from cdprid.effects._spec import EffectSpec, Place

__all__ = ["REGISTRY", "SPECS", "VOCABULARY", "DIAGNOSIS", "SENSOR_CHAIN", "EPISODE_EFFECTS",
           "ENCODER_EFFECT", "spec_of"]

#: the effects, one module ``cdprid.effects._<name>`` each, in the table's order
_MODULES = (
    "none",
    "time_delay",
    "tension_offset",
    "tension_drift",
    "tension_gain",
    "exit_point_error",
    "anchor_point_error",
    "viscous_drag",
    "pulley",
    "cable_mass",
    "frame_tilt",
    "rotational_dynamics",
    "pulley_friction",
    "cable_elasticity",
    "external_wrench",
    "load_cell_hysteresis",
    "current_offset",
    "torque_constant_error",
    "drive_friction",
    "drive_inertia",
)

#: every effect's :class:`EffectSpec`, in the table's order
REGISTRY: tuple[EffectSpec, ...] = tuple(
    importlib.import_module(f"{__package__}._{name}").SPEC for name in _MODULES)


def _check(registry) -> None:
    """Raise SpecError on duplicate names, tension hooks out of the physical order or theta
    blocks shared by forms of one stream (or of different shapes)."""
    names = [s.name for s in registry] + [k for s in registry for k, _ in s.variants]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise SpecError(f"effect names registered twice: {dup}.")
    shapes: dict = {}
    for key, f in ((k, f) for s in registry for k, f in s.forms().items()):
        for block, size in f.blocks:  # a shared block (another stream's form) keeps its shape
            first = shapes.setdefault(block, (f.per_cable, size, f.stream, key))
            if first[:2] != (f.per_cable, size) or (first[3] != key and "any" in (
                    first[2], f.stream)) or (first[3] != key and first[2] == f.stream):
                raise SpecError(f"theta block {block!r} is shared by {first[3]!r} and {key!r}: "
                                 "only forms of different streams may share a block, with "
                                 "one shape.")
    places = [s.place.value for s in registry for f in s.forms().values()
              if f.tension is not None]
    if places != sorted(places, reverse=True):
        raise SpecError("the registry must list the effects with a diagnosis tension hook "
                         "from the recorded number back to the cable (the reverse of the "
                         "sensor chain's Place order).")


_check(REGISTRY)

#: name -> spec
SPECS: dict[str, EffectSpec] = {s.name: s for s in REGISTRY}

#: effect name -> {parameter name: kind}; kinds: 'float', 'cable', 'vec3', 'vec2'
VOCABULARY: dict[str, dict[str, str]] = {s.name: s.kinds for s in REGISTRY}

#: the diagnosis's form of every effect it tests, in theta-layout order (a spec's forms:
#: its own, then its variants, e.g. ``pulley_flipped``; ``cable_elasticity`` is tested on
#: the lengths stream by :mod:`cdprid.diagnosis`, not through theta)
DIAGNOSIS: dict[str, DiagnosisForm] = {k: f for s in REGISTRY for k, f in s.forms().items()}

#: (effect name, how it changes the reading) of the load cell, in physical order from the
#: cable to the number (:class:`Place`, then the registry's order)
SENSOR_CHAIN = tuple((s.name, s.read) for s in sorted(
    (s for s in REGISTRY if s.place.load_cell), key=lambda s: s.place.value))

#: effects located in time by the episodes stage (:mod:`cdprid.episodes`), not candidates of
#: the diagnosis
EPISODE_EFFECTS = frozenset(s.name for s in REGISTRY if s.episodic)

_encoders = [s.name for s in REGISTRY if s.place is Place.ENCODER]
if len(_encoders) != 1:
    raise SpecError(f"one effect must act on the winch encoders, got {_encoders}.")
#: the effect the winch encoders measure (its findings come from lengths.csv)
ENCODER_EFFECT: str = _encoders[0]


def spec_of(name: str) -> EffectSpec:
    """The spec of a vocabulary name.

    Parameters
    ----------
    name : str

    Returns
    -------
    EffectSpec

    Raises
    ------
    InputError
        An unknown name (one sentence listing the valid ones).
    """
    from cdprid.base import InputError

    if name not in SPECS:
        raise InputError(f"unknown effect {name!r}; valid effects: {', '.join(SPECS)}.")
    return SPECS[name]
