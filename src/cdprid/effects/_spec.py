"""One effect as one object: :class:`EffectSpec` (name, parameters, model text, place in the
plant or the sensor chain, simulation terms, diagnosis form) and :class:`Parameter`.

A leaf module: each effect's module (``_time_delay.py``, ``_pulley.py``...) builds its one
``SPEC`` from these classes; :mod:`cdprid.effects._registry` lists the specs, one line each,
and derives the vocabulary, the sensor chain, the diagnosis table, the validation and
``docs/effects.md`` from them.
"""

from __future__ import annotations

import dataclasses
import enum
import json
from collections.abc import Callable

import numpy as np

from cdprid.base import InputError
from cdprid.effects._form import DiagnosisForm, SpecError

__all__ = ["KINDS", "Parameter", "Place", "EffectSpec"]

#: parameter kinds: a number, a cable number (1-based), a list of 3 or 2 numbers
KINDS = ("float", "cable", "vec3", "vec2")


class Place(enum.Enum):
    """Where an effect acts, in physical order from the motion to the recorded numbers.

    The load cell's chain is ``PULLEY -> CELL -> GAIN -> ZERO`` (the force on the cable at
    the platform, through its pulley, the cell's mechanics, its gain, its zero); the
    simulator applies the effects of these places in this order and the diagnosis undoes
    them in the reverse one. ``CLOCK`` is the tension stream's time stamps, ``ENCODER`` the
    winch encoders' stream (``lengths.csv``). ``DRIVE`` is the winch drive between the cable
    and the motor current (format 1.2, ``currents.csv``): its reflected inertia, friction,
    torque constant and current offset, which a motor current sees and a load cell does not;
    the diagnosis reads a current stream as the datasheet's tension ``k i`` and undoes the
    drive's effects through the load cell's own tension hooks where they have the same form
    (offset, gain, friction), the inertia last.
    """

    NONE = 0
    MOTION = 1
    GEOMETRY = 2
    GRAVITY = 3
    PLATFORM = 4
    DRIVE = 5
    PULLEY = 6
    CELL = 7
    GAIN = 8
    ZERO = 9
    CLOCK = 10
    ENCODER = 11

    @property
    def load_cell(self) -> bool:
        """True for the places of the load cell's sensor chain."""
        return self in (Place.PULLEY, Place.CELL, Place.GAIN, Place.ZERO)


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One parameter of an effect: its name, kind, unit and valid range.

    Attributes
    ----------
    name : str
        JSON / command-line name (``offset_N``; the unit is part of the name).
    kind : str
        One of :data:`KINDS`.
    unit : str
        Unit for the docs (``"-"`` for a cable number or a ratio).
    minimum : float, optional
        The value must be ``>= minimum``.
    positive : bool
        The value must be ``> 0``.
    all_cables : bool
        A ``cable`` parameter that also takes ``"all"`` (the same effect on every cable).
    """

    name: str
    kind: str
    unit: str = "-"
    minimum: float | None = None
    positive: bool = False
    all_cables: bool = False

    def __post_init__(self):
        if self.kind not in KINDS:
            raise SpecError(f"parameter {self.name!r} has kind {self.kind!r}; kinds: "
                             f"{', '.join(KINDS)}.")

    @property
    def range_text(self) -> str:
        """The valid range in words (for the docs)."""
        if self.kind == "cable":
            return "1 .. m" + (" or `all`" if self.all_cables else "")
        if self.positive:
            return "> 0"
        return f">= {self.minimum:g}" if self.minimum is not None else "any"

    def convert(self, effect: str, value):
        """The value checked and converted (strings as from the command line).

        Parameters
        ----------
        effect : str
            The effect's name (for the message).
        value : str, number or sequence
            ``"3"``, ``"1.05"``, ``"0.01,0,-0.02"``, ``"[0.01, 0, -0.02]"`` or the value.

        Returns
        -------
        float, int, ``"all"`` or list of float

        Raises
        ------
        InputError
            One sentence naming the effect and the parameter.
        """
        value = self._parsed(effect, value)
        if self.kind in ("vec3", "vec2"):
            return self._vector(effect, value)
        return self._scalar(effect, value)

    def _where(self, effect: str) -> str:
        return f"effect '{effect}' parameter '{self.name}'"

    def _cable_words(self) -> str:
        return "a cable number 1, 2, ..." + (" or all" if self.all_cables else "")

    def _parsed(self, effect, value):
        if not isinstance(value, str):
            return value
        text = value.strip()
        if self.kind == "cable" and self.all_cables and text.lower() == "all":
            return "all"
        if self.kind in ("vec3", "vec2"):
            try:
                return (json.loads(text) if text.startswith("[")
                        else [float(v) for v in text.split(",")])
            except (ValueError, json.JSONDecodeError):
                raise InputError(f"{self._where(effect)} must be a list of numbers like "
                                 f"0.01,0,-0.02, got {text!r}.") from None
        try:
            return float(text)
        except ValueError:
            what = self._cable_words() if self.kind == "cable" else "a number"
            raise InputError(f"{self._where(effect)} must be {what}, got {text!r}.") from None

    def _vector(self, effect, value):
        n = 3 if self.kind == "vec3" else 2
        try:
            arr = [float(v) for v in value]
        except (TypeError, ValueError):
            arr = []
        if len(arr) != n or not all(np.isfinite(arr)):
            raise InputError(f"{self._where(effect)} must be a list of {n} finite numbers, "
                             f"got {value!r}.")
        return arr

    def _scalar(self, effect, value):
        where = self._where(effect)
        if value == "all" and self.kind == "cable" and self.all_cables:
            return "all"
        if isinstance(value, bool):
            raise InputError(f"{where} must be a number, got {value!r}.")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(f"{where} must be a number, got {value!r}.") from None
        if not np.isfinite(v):
            raise InputError(f"{where} must be finite, got {value!r}.")
        if self.kind == "cable":
            if v != int(v) or v < 1:
                raise InputError(f"{where} must be {self._cable_words()}, got {value!r}.")
            return int(v)
        if self.positive and v <= 0:
            raise InputError(f"{where} must be > 0, got {v}.")
        if self.minimum is not None and v < self.minimum:
            raise InputError(f"{where} must be >= {self.minimum:g}, got {v}.")
        return v


@dataclasses.dataclass(frozen=True)
class EffectSpec:
    """Everything the tool knows about one effect (one per effect module, ``SPEC``).

    Attributes
    ----------
    name : str
        The vocabulary name (a contract: ``--effect NAME``, the diagnosis's ``effect``).
    parameters : tuple of Parameter
        In the order of the vocabulary and the docs.
    doc : str
        The model text of ``docs/effects.md``: its first line ``name {parameters}`` in double
        backquotes, then the physics, indented by four spaces.
    place : Place
        Where it acts (orders the simulator's sensor chain; see :class:`Place`).
    once : bool
        It may be given at most once in a simulation.
    check : callable, optional
        ``check(params)``: a rule between parameters; raises :class:`~cdprid.base.InputError`.
    read : callable, optional
        Load-cell places: ``read(reading (k, m), params, ctx) -> reading`` with ``ctx["t"]``
        the tension times from the stream's first (s) and ``ctx["ldot"]`` the cable rates.
    robot : callable, optional
        ``GEOMETRY``: ``robot(arrays, params)`` changes the plant's ``B_A``, ``P_b`` or
        ``pulley_radius`` (numpy arrays, in place).
    gravity : callable, optional
        ``GRAVITY``: ``gravity(g, params) -> g``, the plant's gravity in the pose frame.
    wrench : callable, optional
        ``wrench(t, params) -> (k, 6)``: a wrench on the platform at times ``t``.
    encoder : callable, optional
        ``ENCODER``: ``encoder(L, tension, params) -> l``, what the winch encoders read.
    plant : tuple of (str, str)
        ``(field of PlantTerms, parameter)``: a scalar term of the simulator's plant.
    diagnosis : DiagnosisForm, optional
        Its form in the diagnosis (None: not a candidate).
    variants : tuple of (str, DiagnosisForm)
        Further diagnosis forms reported under this effect's name (e.g. the same friction
        on every cable), each after ``diagnosis`` in the table.
    episodic : bool
        Located in time by the episodes stage (:mod:`cdprid.episodes`), not a candidate.
    """

    name: str
    parameters: tuple = ()
    doc: str = ""
    place: Place = Place.NONE
    once: bool = False
    check: Callable | None = None
    read: Callable | None = None
    robot: Callable | None = None
    gravity: Callable | None = None
    wrench: Callable | None = None
    encoder: Callable | None = None
    plant: tuple = ()
    diagnosis: DiagnosisForm | None = None
    variants: tuple = ()
    episodic: bool = False

    def __post_init__(self):
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise SpecError(f"effect {self.name!r} names a parameter twice: {names}.")
        if not self.doc.startswith(f"``{self.name}"):
            raise SpecError(f"the doc of effect {self.name!r} must begin with ``{self.name}.")
        if (self.read is not None) != self.place.load_cell:
            raise SpecError(f"effect {self.name!r}: a read term needs a load-cell place and "
                             f"a load-cell place a read term (place {self.place.name}).")
        for form in self.forms().values():
            for key in (*form.keys, *form.nonneg):
                if key not in names:
                    raise SpecError(f"a diagnosis form of effect {self.name!r} reports "
                                     f"{key!r}, which is not one of its parameters {names}.")
        for _, key in self.plant:
            if key not in names:
                raise SpecError(f"effect {self.name!r}: plant term of unknown parameter "
                                 f"{key!r}.")

    def forms(self) -> dict:
        """Its diagnosis forms by table name (``diagnosis`` under ``name``, then variants),
        each variant reporting this effect's name.

        Returns
        -------
        dict
            Table name -> DiagnosisForm.
        """
        out = {} if self.diagnosis is None else {self.name: self.diagnosis}
        for key, form in self.variants:
            out[key] = dataclasses.replace(form, vocabulary=self.name)
        return out

    @property
    def kinds(self) -> dict:
        """``{parameter: kind}`` (one entry of the vocabulary)."""
        return {p.name: p.kind for p in self.parameters}

    def validate(self, params: dict) -> dict:
        """The parameters checked and converted (see :meth:`Parameter.convert`).

        Parameters
        ----------
        params : dict
            Exactly this effect's parameters.

        Returns
        -------
        dict

        Raises
        ------
        InputError
            Unknown, missing or bad parameters (one sentence naming the effect and the
            parameter, listing the valid ones).
        """
        valid = ", ".join(p.name for p in self.parameters) or "none"
        unknown = [k for k in params if k not in self.kinds]
        if unknown:
            raise InputError(f"unknown parameter {unknown[0]!r} for effect '{self.name}'; "
                             f"valid parameters: {valid}.")
        missing = [p.name for p in self.parameters if p.name not in params]
        if missing:
            raise InputError(f"effect '{self.name}' needs the parameter(s) "
                             f"{', '.join(missing)} (e.g. --param {missing[0]}=...); valid "
                             f"parameters: {valid}.")
        by_name = {p.name: p for p in self.parameters}
        clean = {k: by_name[k].convert(self.name, v) for k, v in params.items()}
        if self.check is not None:
            self.check(clean)
        return clean
