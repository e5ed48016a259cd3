"""``tension_gain``: a load cell with a wrong gain (one module, one effect)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _read(x, p, ctx):
    x[:, p["cable"] - 1] *= p["gain"]
    return x


_GAIN_VS_GEOMETRY = ("the same poses at two pretension levels (a gain scales with the tension, "
                     "a direction error with the pose)")

SPEC = EffectSpec(
    name="tension_gain",
    parameters=(Parameter("cable", "cable"), Parameter("gain", "float", "-", positive=True)),
    doc="""``tension_gain {cable, gain}``
    Load cell ``cable`` reads ``gain * tau`` (applied before the offset, before noise).""",
    place=Place.GAIN, read=_read,
    # theta holds gain - 1 (the block is 0 for a right gain)
    diagnosis=DiagnosisForm(
        blocks=(("gain", 1),), per_cable=True, group=1, keys=("gain",),
        stream="tensions",
        tension=lambda tau, q, c: tau / (1.0 + q["gain"]),
        params=lambda v, extra: {"gain": float(1.0 + v[0])},
        interval=lambda lo, hi, extra: {"gain": [float(1 + lo[0]), float(1 + hi[0])]},
        ranges={"gain": (0.5, 2.0)},
        separated_by={"exit_point_error": _GAIN_VS_GEOMETRY,
                      "anchor_point_error": _GAIN_VS_GEOMETRY}),
)
