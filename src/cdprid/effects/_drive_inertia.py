"""``drive_inertia``: a winch drive's rotor, gear and drum inertia reflected to its cable
(one module, one effect; motor currents only; the diagnosis also tests the same inertia on
every drive, ``drive_inertia_all``)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _undo(tau, q, c):
    return tau + q["inertia"] * c["lddot"]


def _undo_all(tau, q, c):
    return tau + q["inertia_all"] * c["lddot"]


_BOUNDS = {"J_kg": 1e3}

SPEC = EffectSpec(
    name="drive_inertia",
    parameters=(Parameter("cable", "cable", all_cables=True),
                Parameter("J_kg", "float", "kg", minimum=0.0)),
    doc="""``drive_inertia {cable, J_kg}``
    Winch drive ``cable`` (or ``"all"``: the same on every drive) has the inertia
    ``J_kg = (N^2 J_motor + J_drum) / r^2`` reflected to its cable: with ``l''`` the
    acceleration of the length paid out, the tension is ``k i + J_kg l''`` (docs/drives.md:
    paying out faster, the cable also accelerates the rotor). Motor currents only
    (``diagnose --source currents``); ``J_kg >= 0``.""",
    place=Place.DRIVE,
    diagnosis=DiagnosisForm(
        blocks=(("inertia", 1),), per_cable=True, group=1, keys=("J_kg",), stream="currents",
        tension=_undo, bounds=_BOUNDS, nonneg=("J_kg",)),
    variants=(("drive_inertia_all", DiagnosisForm(
        blocks=(("inertia_all", 1),), group=1, keys=("J_kg",), stream="currents",
        tension=_undo_all,
        params=lambda v, extra: {"cable": "all", "J_kg": float(v[0])},
        interval=lambda lo, hi, extra: {"J_kg": [float(lo[0]), float(hi[0])]},
        alias="drive_inertia:cable=all", bounds=_BOUNDS, nonneg=("J_kg",),
        separated_by={"drive_inertia": "motion of one cable at a time (the inertia of one "
                      "drive or the same in all)"})),),
)
