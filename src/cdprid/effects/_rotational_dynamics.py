"""``rotational_dynamics``: the platform also rotates (one module, one effect)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _interval(lo, hi, extra):
    z = 1.959963984540054
    a, s = extra["rotation_amplitude"], extra.get("rotation_amplitude_std", 0.0)
    return {"amplitude_rad": [a - z * s, a + z * s]}


SPEC = EffectSpec(
    name="rotational_dynamics",
    parameters=(Parameter("amplitude_rad", "float", "rad", minimum=0.0),),
    doc="""``rotational_dynamics {amplitude_rad}``
    The platform also performs small rotations (:func:`cdprid.model.small_rotation`,
    that peak angle about each axis), so the rotational inertia and angular terms act;
    pose.csv then carries quaternions.""",
    place=Place.MOTION, once=True, plant=(("rotation_amplitude_rad", "amplitude_rad"),),
    diagnosis=DiagnosisForm(
        group=4, when="rotation", base_model=True,
        params=lambda v, extra: {"amplitude_rad": float(extra["rotation_amplitude"])},
        interval=_interval),
)
