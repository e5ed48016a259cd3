"""``current_offset``: a winch drive whose current reading has a zero offset (one module, one
effect; motor currents only)."""

from __future__ import annotations

from cdprid.effects._form import Z95 as _Z
from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _report(v, s, kn):
    """``offset_A = c / k`` and its interval from the fitted c (N) and k."""
    return ({"offset_A": v["c"] / v["k"]},
            {"offset_A": [(v["c"] - _Z * s["c"]) / v["k"], (v["c"] + _Z * s["c"]) / v["k"]]})


def _k(extra) -> float:
    """The datasheet's current-to-force constant (N/A) of the candidate's cable."""
    return float(extra["drive_k"][extra["cable"] - 1])


# the load cell's offset block (N on the datasheet's tension ``k_nom i``): its hook undoes
# ``reading = tau + q`` before the torque constant's, so ``offset_A = q / k_nom`` exactly
SPEC = EffectSpec(
    name="current_offset",
    parameters=(Parameter("cable", "cable"), Parameter("offset_A", "float", "A")),
    doc="""``current_offset {cable, offset_A}``
    Winch drive ``cable`` reports ``i + offset_A`` for the current ``i`` that makes its
    torque: the cable's tension is ``k (i_read - offset_A)`` (``c = k offset_A`` of the drive
    model, docs/drives.md). Motor currents only:
    ``diagnose --source currents`` names it from ``identify --source currents``' drive model.""",
    place=Place.DRIVE,
    diagnosis=DiagnosisForm(
        blocks=(("offset", 1),), per_cable=True, group=1, keys=("offset_A",),
        stream="currents", drive=("c",), drive_report=_report,
        params=lambda v, extra: {"offset_A": float(v[0]) / _k(extra)},
        interval=lambda lo, hi, extra: {"offset_A": [float(lo[0]) / _k(extra),
                                                     float(hi[0]) / _k(extra)]},
        bounds={"offset_A": 1e2},
        separated_by={"torque_constant_error": "a trajectory with a wider range of tension on "
                      "that cable (a torque constant scales with the current, an offset does "
                      "not)"}),
)
