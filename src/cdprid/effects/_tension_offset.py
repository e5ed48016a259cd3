"""``tension_offset``: a load cell with a zero offset (one module, one effect)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _read(x, p, ctx):
    x[:, p["cable"] - 1] += p["offset_N"]
    return x


SPEC = EffectSpec(
    name="tension_offset",
    parameters=(Parameter("cable", "cable"), Parameter("offset_N", "float", "N")),
    doc="""``tension_offset {cable, offset_N}``
    Load cell ``cable`` reads ``tau + offset_N``.""",
    place=Place.ZERO, read=_read,
    diagnosis=DiagnosisForm(
        blocks=(("offset", 1),), per_cable=True, group=1, keys=("offset_N",),
        stream="tensions",
        tension=lambda tau, q, c: tau - q["offset"], bounds={"offset_N": 1e3},
        separated_by={"tension_gain": "a trajectory with a wider range of tension on that "
                      "cable (a gain scales with the tension, an offset does not)"}),
)
