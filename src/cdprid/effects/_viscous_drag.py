"""``viscous_drag``: a force against the platform's velocity (one module, one effect)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _model(y, d, q):
    """Model side (diagnosis): the drag ``c v`` on the force rows."""
    import jax.numpy as jnp

    return y + jnp.concatenate([d.v * q["drag"], jnp.zeros_like(d.v)], axis=1)


SPEC = EffectSpec(
    name="viscous_drag",
    parameters=(Parameter("coefficient_Ns_per_m", "float", "N s/m", minimum=0.0),),
    doc="""``viscous_drag {coefficient_Ns_per_m}``
    A force ``-c v`` on the platform, applied at P (no moment about P); v is the velocity
    of P, base frame.""",
    place=Place.PLATFORM, once=True, plant=(("drag_Ns_per_m", "coefficient_Ns_per_m"),),
    diagnosis=DiagnosisForm(
        blocks=(("drag", 1),), keys=("coefficient_Ns_per_m",), model=_model,
        bounds={"coefficient_Ns_per_m": 1e3}, nonneg=("coefficient_Ns_per_m",),
        separated_by={"pulley_friction": "motion at several speeds (Coulomb friction does not "
                      "grow with the speed)"}),
)
