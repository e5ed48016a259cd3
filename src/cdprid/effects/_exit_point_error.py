"""``exit_point_error``: a cable's exit point is not where robot.toml says (one module, one
effect)."""

from __future__ import annotations

import numpy as np

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _robot(arrays, p):
    arrays["B_A"][p["cable"] - 1] += np.asarray(p["displacement_m"])


SPEC = EffectSpec(
    name="exit_point_error",
    parameters=(Parameter("cable", "cable"), Parameter("displacement_m", "vec3", "m")),
    doc="""``exit_point_error {cable, displacement_m: [dx, dy, dz]}``
    The true exit point A_i (base frame) is robot.toml's plus the displacement; the plant
    uses the true one, robot.toml keeps the nominal one.""",
    place=Place.GEOMETRY, robot=_robot,
    diagnosis=DiagnosisForm(
        blocks=(("exit", 3),), per_cable=True, group=1, keys=("displacement_m",),
        geometry=lambda geo, q: {**geo, "A": geo["A"] + q["exit"]},
        displacement=True, bounds={"displacement_m": 0.25},
        separated_by={"anchor_point_error": "rotations of the platform (an attachment error "
                      "turns with it, an exit error does not)"}),
)
