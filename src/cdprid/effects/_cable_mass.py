"""``cable_mass``: the cables' own weight, lumped at the attachments (one module, one
effect)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]

SPEC = EffectSpec(
    name="cable_mass",
    parameters=(Parameter("linear_density_kg_per_m", "float", "kg/m", minimum=0.0),),
    doc="""``cable_mass {linear_density_kg_per_m}``
    Lumped cable weight: each cable is taken as straight between its leave point and its
    attachment B_i, of length L_i; half of its weight, ``rho L_i g / 2`` (g the gravity
    vector of the plant, so it follows ``frame_tilt``), acts on the platform at B_i (force
    and moment about P). The tensions reported are those along the straight chords (what
    ``W`` multiplies). No sag/catenary shape is modelled.""",
    place=Place.PLATFORM, once=True, plant=(("rho_kg_per_m", "linear_density_kg_per_m"),),
    diagnosis=DiagnosisForm(
        blocks=(("rho", 1),), keys=("linear_density_kg_per_m",),
        load=lambda f, Ln, g, q: f + 0.5 * q["rho"] * Ln * g,
        bounds={"linear_density_kg_per_m": 5.0}, nonneg=("linear_density_kg_per_m",)),
)
