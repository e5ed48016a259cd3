"""``pulley``: swivel pulleys that robot.toml omits (one module, one effect; the diagnosis
also tests the opposite arrival direction, ``pulley_flipped``)."""

from __future__ import annotations

import numpy as np

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _robot(arrays, p):
    arrays["pulley_radius"][:] = p["radius_m"]


def _pulley_params(flip: bool):
    def params(v, extra):
        axis = np.asarray(extra.get("pulley_axis", [0.0, 0.0, -1.0]), float)
        axis = -axis if flip else axis
        return {"radius_m": float(v[0]), "pulley_axis": (axis + 0.0).tolist()}
    return params


def _flipped_leave(T, geo, q, c):
    """A swivel pulley of radius ``pulley_flip`` whose cable arrives opposite to the axis,
    added as a displacement of the leave point (exact when either radius is 0)."""
    from cdprid.model import pulley_leave_point

    T_flip, _, _ = pulley_leave_point(geo["A"], c["bb"], c["p"], q["pulley_flip"], -c["k"],
                                      c["ref"])
    return T + (T_flip - geo["A"])


SPEC = EffectSpec(
    name="pulley",
    parameters=(Parameter("radius_m", "float", "m", minimum=0.0),),
    doc="""``pulley {radius_m}``
    Every cable passes over a swivel pulley of that radius (axis from robot.toml, by
    default ``[0, 0, -1]``; reference direction base x) that robot.toml omits: the plant's
    cable directions start at the leave points on the pulley rims (spec v1 pulley model).
    Spec 1.1: ``pulley_axis`` is the direction in which the cable runs into the pulley; to
    simulate a cable arriving from below, give robot.toml ``pulley_axis = [0, 0, 1]``. The
    diagnosis reports the finding with its ``pulley_axis``; when robot.toml models no pulley
    it tests both arrival directions.""",
    place=Place.GEOMETRY, once=True, robot=_robot,
    diagnosis=DiagnosisForm(
        blocks=(("radius", 1),), keys=("radius_m",), params=_pulley_params(False),
        geometry=lambda geo, q: {**geo, "r": geo["r"] + q["radius"]},
        bounds={"radius_m": 0.25}, nonneg=("radius_m",),
        separated_by={"pulley_flipped": "poses close to the exit points and far below them "
                      "(the wrap differs by arrival)"}),
    # the second arrival direction, tested only when robot.toml models no pulley
    variants=(("pulley_flipped", DiagnosisForm(
        blocks=(("pulley_flip", 1),), group=3, when="no_pulley", keys=("radius_m",),
        params=_pulley_params(True), alias="pulley:arriving_opposite", leave=_flipped_leave,
        bounds={"radius_m": 0.25}, nonneg=("radius_m",))),),
)
