"""The context the candidates' checks and the vocabulary forms read besides the fit.

Set once after the base fit (:func:`cdprid.diagnosis._pipeline.diagnose`) and passed through
the search, the checks and the sizes unchanged. It replaces an untyped ``extra`` dict and
still reads like it (``ctx["rotation_amplitude"]``, ``ctx.get("pulley_axis", default)``),
which the diagnosis forms of :mod:`cdprid.effects` (``params(values, ctx)``,
``interval(lo, hi, ctx)``) use.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np


@dataclasses.dataclass(frozen=True)
class DiagnosisContext:
    """What the diagnosis knows besides the fit, read by the checks and vocabulary forms.

    A field left None is absent: ``ctx["key"]`` raises ``KeyError`` and ``ctx.get("key",
    default)`` gives ``default``, as the dict it replaces did.

    Attributes
    ----------
    rotation_amplitude : float or None
        The platform's 99.5 % rotation amplitude (rad), the size the vocabulary gives
        ``rotational_dynamics``.
    rotation_amplitude_std : float or None
        Its noise (rad).
    pulley_axis : numpy.ndarray or None
        The pulleys' swivel axis, base frame: ``(3,)`` when every pulley has the same one,
        else ``(m, 3)``.
    finding_floor_N : float
        Smallest force (rms, N) a finding may have
        (:func:`cdprid.diagnosis._unexplained.finding_floor_N`); 0 when not set.
    base_mass_kg : float or None
        The base model's mass (kg), the reference of the model's plausibility.
    drive_k : numpy.ndarray or None
        The drives' datasheet current-to-force constants ``(m,)`` N/A (``diagnose --source
        currents``: the reading is ``k i``; a current offset in A is its offset in N over
        ``k``).
    cable : int or None
        The candidate's cable (1-based), set by the vocabulary forms' readers
        (:func:`cdprid.diagnosis._candidates.vocab_params`) for a per-cable form.
    """

    rotation_amplitude: float | None = None
    rotation_amplitude_std: float | None = None
    pulley_axis: np.ndarray | None = dataclasses.field(default=None, compare=False)
    finding_floor_N: float = 0.0
    base_mass_kg: float | None = None
    drive_k: np.ndarray | None = dataclasses.field(default=None, compare=False)
    cable: int | None = None

    def __getitem__(self, key: str):
        value = getattr(self, key) if key in _NAMES else None
        if value is None:
            raise KeyError(key)
        return value

    def get(self, key: str, default=None):
        """The field ``key``, or ``default`` when it is absent (None or not a field).

        Parameters
        ----------
        key : str
        default : object, optional

        Returns
        -------
        object
        """
        value = getattr(self, key) if key in _NAMES else None
        return default if value is None else value

    def __contains__(self, key) -> bool:
        return key in _NAMES and getattr(self, key) is not None

    def keys(self) -> list[str]:
        """The fields that are set, in their order.

        Returns
        -------
        list of str
        """
        return [k for k in _NAMES if getattr(self, k) is not None]

    def __iter__(self):
        return iter(self.keys())

    @classmethod
    def of(cls, extra) -> DiagnosisContext:
        """``extra`` itself, or the context of a dict with (some of) the fields' names.

        Parameters
        ----------
        extra : DiagnosisContext or mapping

        Returns
        -------
        DiagnosisContext

        Raises
        ------
        TypeError
            A key is not a field (a misspelt name is not silently ignored).
        """
        if isinstance(extra, cls):
            return extra
        if not isinstance(extra, Mapping):
            raise TypeError(f"a DiagnosisContext or a mapping, not {type(extra).__name__}")
        unknown = sorted(set(extra) - set(_NAMES))
        if unknown:
            raise TypeError(f"DiagnosisContext has no field {', '.join(unknown)} "
                            f"(its fields: {', '.join(_NAMES)})")
        return cls(**extra)


_NAMES = tuple(f.name for f in dataclasses.fields(DiagnosisContext))
