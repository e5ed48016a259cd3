"""Typed parts of a diagnosis result, each readable as the JSON object it is written as.

Every part is frozen and has named attributes (``res.base_parameters["m"].value``,
``u.correlates_with``); its ``as_json()`` is the object of ``diagnose --json`` (the contract,
key order included), and the old dict reads keep working on it (``part["key"]``,
``part.get("key")``, ``"key" in part``, ``part.keys()``, ``part.items()``, ``dict(part)``),
so scripts written against the lists of dicts of earlier releases run unchanged. A part
compares equal to another part or to a dict with the same JSON.

The parts whose JSON keys vary with the test or stage that made them (:class:`Unexplained`,
:class:`CompetingModel`, :class:`NotNamed`) keep the keys they do not name in ``details`` and
the JSON key order in ``json_keys``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from typing import Any


class JsonView:
    """Dict reads of a part onto its JSON keys (``as_json()``); equality by JSON."""

    __slots__ = ()

    def as_json(self) -> dict:  # pragma: no cover - every part defines it
        """The JSON object of the part (subclasses define it).

        Returns
        -------
        dict
        """
        raise NotImplementedError

    def __getitem__(self, key: str):
        return self.as_json()[key]

    def get(self, key: str, default=None):
        """The value of a JSON key, or ``default`` when the part has no such key.

        Parameters
        ----------
        key : str
        default : object, optional

        Returns
        -------
        object
        """
        return self.as_json().get(key, default)

    def keys(self):
        """The JSON keys, in the JSON's order.

        Returns
        -------
        dict_keys
        """
        return self.as_json().keys()

    def values(self):
        """The JSON values, in the JSON's order.

        Returns
        -------
        dict_values
        """
        return self.as_json().values()

    def items(self):
        """The JSON ``(key, value)`` pairs, in the JSON's order.

        Returns
        -------
        dict_items
        """
        return self.as_json().items()

    def __contains__(self, key) -> bool:
        return key in self.as_json()

    def __iter__(self) -> Iterator[str]:
        return iter(self.as_json())

    def __len__(self) -> int:
        return len(self.as_json())

    def __eq__(self, other) -> bool:
        if isinstance(other, JsonView):
            return type(other) is type(self) and other.as_json() == self.as_json()
        if isinstance(other, Mapping):
            return dict(other) == self.as_json()
        return NotImplemented

    __hash__ = None  # like the dict it stands for


def _fields_json(part) -> dict:
    """``{field: value}`` of a part whose JSON keys are its fields (shallow, in order)."""
    return {f.name: getattr(part, f.name) for f in dataclasses.fields(part)}


@dataclasses.dataclass(frozen=True, eq=False)
class ParameterEstimate(JsonView):
    """One inertial parameter of a fitted model, with its HAC standard deviation.

    Attributes
    ----------
    value : float
        The estimate (kg, kg m or kg m^2 by parameter: ``m``, ``mxG``.., ``Ixx``..).
    std : float
        Its standard deviation (HAC, same unit).
    rel_std_percent : float
        ``100 std / |value|``.
    """

    value: float
    std: float
    rel_std_percent: float

    def as_json(self) -> dict:
        """``{"value", "std", "rel_std_percent"}``.

        Returns
        -------
        dict
        """
        return _fields_json(self)

    @classmethod
    def of(cls, v) -> ParameterEstimate:
        """``v`` itself, or the estimate of its JSON object.

        Parameters
        ----------
        v : ParameterEstimate or mapping
            With the keys ``value``, ``std``, ``rel_std_percent``.

        Returns
        -------
        ParameterEstimate
        """
        return v if isinstance(v, cls) else cls(**v)


class ParameterEstimates(Mapping):
    """The parameters of a fitted model by name (``m``, ``mxG``, ..), in the model's order.

    A read-only mapping of :class:`ParameterEstimate`; ``as_json()`` is the ``parameters``
    object of ``diagnose --json``.

    Parameters
    ----------
    items : mapping
        Name -> :class:`ParameterEstimate` or its JSON object.
    """

    __slots__ = ("_items",)

    def __init__(self, items: Mapping = ()):
        object.__setattr__(self, "_items", {str(k): ParameterEstimate.of(v)
                                             for k, v in dict(items).items()})

    def __setattr__(self, name, value):
        raise dataclasses.FrozenInstanceError(f"cannot assign to field {name!r}")

    def __getitem__(self, name: str) -> ParameterEstimate:
        return self._items[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return f"ParameterEstimates({self._items!r})"

    def __reduce__(self):
        return (ParameterEstimates, (self._items,))

    def as_json(self) -> dict:
        """``{name: {"value", "std", "rel_std_percent"}}``.

        Returns
        -------
        dict
        """
        return {k: v.as_json() for k, v in self._items.items()}

    @classmethod
    def of(cls, v) -> ParameterEstimates:
        """``v`` itself, or the estimates of its JSON object.

        Parameters
        ----------
        v : ParameterEstimates or mapping

        Returns
        -------
        ParameterEstimates
        """
        return v if isinstance(v, cls) else cls(v)


@dataclasses.dataclass(frozen=True, eq=False)
class RankedCandidate(JsonView):
    """One candidate of the first forward step's ranking (HAC Wald test given the base model).

    Attributes
    ----------
    candidate : str
        Its label (``tension_gain[cable 2]``).
    statistic : float
        The Wald statistic.
    dof : int
        Its degrees of freedom.
    p_value : float
        Its p-value alone.
    p_bonferroni : float
        Times the number of candidates tested, at most 1.
    """

    candidate: str
    statistic: float
    dof: int
    p_value: float
    p_bonferroni: float

    def as_json(self) -> dict:
        """``{"candidate", "statistic", "dof", "p_value", "p_bonferroni"}``.

        Returns
        -------
        dict
        """
        return _fields_json(self)

    @classmethod
    def of(cls, v) -> RankedCandidate:
        """``v`` itself, or the ranked candidate of its JSON object.

        Parameters
        ----------
        v : RankedCandidate or mapping

        Returns
        -------
        RankedCandidate
        """
        return v if isinstance(v, cls) else cls(**v)


class _Open(JsonView):
    """A part with named fields, ``details`` for the other JSON keys and ``json_keys`` for
    their order. A named field is in the JSON when ``json_keys`` lists it (every named field
    and then ``details`` when ``json_keys`` is empty)."""

    __slots__ = ()

    def _names(self) -> tuple:
        return tuple(f.name for f in dataclasses.fields(self)
                     if f.name not in ("details", "json_keys"))

    def as_json(self) -> dict:
        """The JSON object, its keys in ``json_keys``' order.

        Returns
        -------
        dict
        """
        names = self._names()
        keys = self.json_keys or names + tuple(self.details)
        return {k: getattr(self, k) if k in names else self.details[k] for k in keys}

    @classmethod
    def of(cls, v):
        """``v`` itself, or the part of its JSON object (its key order kept).

        Parameters
        ----------
        v : the part or mapping

        Returns
        -------
        the part
        """
        if isinstance(v, cls):
            return v
        names = {f.name for f in dataclasses.fields(cls)} - {"details", "json_keys"}
        return cls(**{k: x for k, x in v.items() if k in names},
                   details={k: x for k, x in v.items() if k not in names},
                   json_keys=tuple(v))


@dataclasses.dataclass(frozen=True, eq=False)
class Unexplained(_Open):
    """One structure of the residual that no effect of the vocabulary explains, or a hint.

    Attributes
    ----------
    where : str
        Where it shows (``force along z``, a candidate's label).
    size : float
        Its size, N rms.
    correlates_with : str
        The signal it correlates with, or a sentence.
    p_value : float
        Its p-value (Holm-adjusted over the family of tests; 1 for a withdrawn finding).
    test : str or None
        The test that found it (None when its JSON has no ``test``).
    details : dict
        The other JSON keys (test-specific: ``p_raw``, ``floor_N``, ``frequency_hz``,
        ``withdrawn_finding``, ``significant``, ...).
    json_keys : tuple of str
        The JSON keys in their order.
    """

    where: str
    size: float
    correlates_with: str
    p_value: float | None = None
    test: str | None = None
    details: dict = dataclasses.field(default_factory=dict)
    json_keys: tuple = ()


@dataclasses.dataclass(frozen=True, eq=False)
class CompetingModel(_Open):
    """A complete alternative model within the noise of the final one.

    Attributes
    ----------
    replaces : str
        The finding(s) of the final model it does without (`` + ``-joined labels).
    by : str
        What it has instead.
    parameters : dict
        Their values (vocabulary units; by label when several).
    effects : list of str or None
        All its effects.
    heldout_force_rms_N : float
        Its held-out force residual rms, N.
    relative_difference : float
        Its held-out rms relative to the final model's.
    p_worse : float
        Diebold-Mariano p-value that it predicts worse.
    details : dict
        Other JSON keys.
    json_keys : tuple of str
        The JSON keys in their order.
    """

    replaces: str
    by: str
    parameters: dict
    effects: list | None = None
    heldout_force_rms_N: float | None = None
    relative_difference: float | None = None
    p_worse: float | None = None
    details: dict = dataclasses.field(default_factory=dict)
    json_keys: tuple = ()


@dataclasses.dataclass(frozen=True, eq=False)
class NotNamed(_Open):
    """An effect a real recording always holds, sized on top of the final model, not named.

    Attributes
    ----------
    effect : str
        The vocabulary effect.
    parameters : dict
        Its size (vocabulary units).
    interval : dict
        95 % intervals (HAC).
    p_value : float
        The p-value of the effect alone.
    statistic : float
        Its Wald statistic.
    named : bool
        Always False.
    why : str
        Why it is not named.
    details : dict
        Other JSON keys.
    json_keys : tuple of str
        The JSON keys in their order.
    """

    effect: str
    parameters: dict
    interval: dict
    p_value: float | None = None
    statistic: float | None = None
    named: bool = False
    why: str = ""
    details: dict = dataclasses.field(default_factory=dict)
    json_keys: tuple = ()


def parts(cls, items) -> list[Any]:
    """``[cls.of(x) for x in items]`` (a list, like the lists of dicts it replaces)."""
    return [cls.of(x) for x in items]
