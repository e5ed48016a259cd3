"""``torque_constant_error``: a winch drive whose current-to-force constant is not its
datasheet's (one module, one effect; motor currents only)."""

from __future__ import annotations

from cdprid.effects._form import Z95 as _Z
from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _report(v, s, kn):
    """``ratio = k / k_nom`` and its interval from the fitted k."""
    return ({"ratio": v["k"] / kn},
            {"ratio": [(v["k"] - _Z * s["k"]) / kn, (v["k"] + _Z * s["k"]) / kn]})


# the load cell's gain block: its hook undoes ``reading = (1 + q) tau``; the datasheet's
# tension ``k_nom i`` is ``tau / ratio``, so ``ratio = 1 / (1 + q)``
_VS_GEOMETRY = ("the same poses at two pretension levels (a torque constant scales with the "
                "tension, a direction error with the pose)")

SPEC = EffectSpec(
    name="torque_constant_error",
    parameters=(Parameter("cable", "cable"), Parameter("ratio", "float", "-", positive=True)),
    doc="""``torque_constant_error {cable, ratio}``
    Winch drive ``cable``'s current-to-force constant is ``ratio`` times its datasheet value
    ``k = torque_constant gear_ratio / drum_radius`` (robot.toml, format 1.2): the cable's
    tension is ``ratio k i`` where the datasheet says ``k i``. Motor currents only:
    ``diagnose --source currents`` names it from ``identify --source currents``' drive model
    (docs/drives.md); the scale reference drive is exact by definition.""",
    place=Place.DRIVE,
    diagnosis=DiagnosisForm(
        blocks=(("gain", 1),), per_cable=True, group=1, keys=("ratio",),
        stream="currents", drive=("k",), drive_report=_report,
        not_on_reference=True,
        params=lambda v, extra: {"ratio": float(1.0 / (1.0 + v[0]))},
        interval=lambda lo, hi, extra: {"ratio": [float(1.0 / (1.0 + hi[0])),
                                                  float(1.0 / (1.0 + lo[0]))]},
        ranges={"ratio": (0.5, 2.0)},
        separated_by={"exit_point_error": _VS_GEOMETRY, "anchor_point_error": _VS_GEOMETRY}),
)
