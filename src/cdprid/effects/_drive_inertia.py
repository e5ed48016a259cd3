"""``drive_inertia``: a winch drive's rotor, gear and drum inertia reflected to its cable
(one module, one effect; motor currents only)."""

from __future__ import annotations

from cdprid.effects._form import Z95 as _Z
from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _report(v, s, kn):
    """The fitted reflected inertia and its interval."""
    return {"J_kg": v["J"]}, {"J_kg": [v["J"] - _Z * s["J"], v["J"] + _Z * s["J"]]}


def _undo(tau, q, c):
    return tau + q["inertia"] * c["lddot"]


_BOUNDS = {"J_kg": 1e3}

SPEC = EffectSpec(
    name="drive_inertia",
    parameters=(Parameter("cable", "cable"), Parameter("J_kg", "float", "kg", minimum=0.0)),
    doc="""``drive_inertia {cable, J_kg}``
    Winch drive ``cable`` has the inertia
    ``J_kg = (N^2 J_motor + J_drum) / r^2`` reflected to its cable: with ``l''`` the
    acceleration of the length paid out, the tension is ``k i + J_kg l''`` (docs/drives.md:
    paying out faster, the cable also accelerates the rotor). Motor currents only:
    ``diagnose --source currents`` names it from ``identify --source currents``' drive model;
    ``J_kg >= 0``.""",
    place=Place.DRIVE,
    diagnosis=DiagnosisForm(
        blocks=(("inertia", 1),), per_cable=True, group=1, keys=("J_kg",),
        stream="currents", drive=("J",), drive_report=_report,
        tension=_undo, bounds=_BOUNDS, nonneg=("J_kg",)),
)
