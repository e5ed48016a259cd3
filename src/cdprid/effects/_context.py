"""The context of a diagnosis form's per-cable hooks, typed: :class:`CableContext`.

The hooks ``tension(tau, q, c)`` and ``leave(T, geo, q, c)`` of a
:class:`~cdprid.effects.DiagnosisForm` read ``c``. The diagnosis's forward model
(:func:`cdprid.diagnosis._model.cable_contribution`) builds it, today as a dict with these keys;
the hooks read it by key (``c["ldot"]``, ``c.get("slide", ...)``), which this class also
supports, so the diagnosis can pass a :class:`CableContext` instead without touching a hook.
"""

from __future__ import annotations

import dataclasses
from typing import Any

__all__ = ["CableContext"]


@dataclasses.dataclass(frozen=True)
class CableContext:
    """What a per-cable hook knows besides its own theta blocks (one sample, one cable).

    Attributes
    ----------
    at : dict
        Every theta block of this cable at the linearisation point (``at["delay"]``, s).
    taud : float
        Rate of the load-cell reading, N/s.
    ldot : float
        Rate of the cable length between exit point and platform (> 0 paying out), m/s.
    R : (3, 3) array
        Platform orientation (platform frame -> base frame).
    p : (3,) array
        Platform position, base frame, m.
    k : (3,) array
        Pulley axis of robot.toml (the direction the cable runs into the pulley).
    ref : (3,) array
        Pulley reference direction.
    t : float
        The recording's own clock, s from the tension stream's first time stamp.
    slide : float
        Expected sign of the cable's sliding speed in [-1, 1] (Coulomb terms).
    bb : (3,) array, optional
        Attachment in the base frame relative to P, ``R b``, m (set after the geometry
        hooks, before the ``leave`` hooks; None before).
    lddot : float
        Acceleration of that cable length (the nominal geometry's, raw second differences
        of the poses that the matched filter then smooths like the accelerations), m/s^2;
        0 where the diagnosis does not build it (load cells: no hook reads it).
    """

    at: dict
    taud: Any
    ldot: Any
    R: Any
    p: Any
    k: Any
    ref: Any
    t: Any = 0.0
    slide: Any = None
    bb: Any = None
    lddot: Any = 0.0

    def __getitem__(self, key: str):
        """``c["ldot"]``: the attribute (the hooks' key access, as on a dict)."""
        if key not in self.__dataclass_fields__ or (key == "bb" and self.bb is None):
            raise KeyError(key)
        return getattr(self, key)

    def get(self, key: str, default=None):
        """``c.get("slide", default)``: the attribute, or ``default`` when it is None.

        Parameters
        ----------
        key : str
            An attribute of the context.
        default : object, optional

        Returns
        -------
        object
        """
        value = getattr(self, key, None)
        return default if value is None else value
