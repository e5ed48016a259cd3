"""``anchor_point_error``: a cable's attachment on the platform is not where robot.toml says
(one module, one effect)."""

from __future__ import annotations

import numpy as np

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _robot(arrays, p):
    arrays["P_b"][p["cable"] - 1] += np.asarray(p["displacement_m"])


SPEC = EffectSpec(
    name="anchor_point_error",
    parameters=(Parameter("cable", "cable"), Parameter("displacement_m", "vec3", "m")),
    doc="""``anchor_point_error {cable, displacement_m}``
    The same for the attachment b_i (platform frame).""",
    place=Place.GEOMETRY, robot=_robot,
    diagnosis=DiagnosisForm(
        blocks=(("anchor", 3),), per_cable=True, group=1, keys=("displacement_m",),
        geometry=lambda geo, q: {**geo, "b": geo["b"] + q["anchor"]},
        displacement=True, bounds={"displacement_m": 0.25}),
)
