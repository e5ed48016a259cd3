"""What the simulator's plant takes from a list of effects (:func:`plant_terms`).

The simulator asks this module instead of testing effect names: the scalar terms of the
plant (delay, drag, cable mass, rotation amplitude) and its switches (winch encoders, tilted
gravity).
"""

from __future__ import annotations

import dataclasses

__all__ = ["ENCODER_EFFECT", "PlantTerms", "plant_terms"]


@dataclasses.dataclass(frozen=True)
class PlantTerms:
    """What the simulator's plant takes from the effects (zero when an effect is absent).

    Attributes
    ----------
    delay_s : float
        ``time_delay``: the load cells read the tensions of ``delay_s`` earlier.
    drag_Ns_per_m : float
        ``viscous_drag`` on the platform.
    rho_kg_per_m : float
        ``cable_mass`` linear density.
    rotation_amplitude_rad : float
        ``rotational_dynamics``: the trajectory's added rotation amplitude.
    encoders : bool
        An effect the winch encoders see (``cable_elasticity``): simulate ``lengths.csv``.
    tilted : bool
        ``frame_tilt``: gravity is not along the pose frame's -z (meta.toml records it).
    """

    delay_s: float = 0.0
    drag_Ns_per_m: float = 0.0
    rho_kg_per_m: float = 0.0
    rotation_amplitude_rad: float = 0.0
    encoders: bool = False
    tilted: bool = False


def plant_terms(effects) -> PlantTerms:
    """The plant's scalar terms and switches from a list of effects (see :class:`PlantTerms`)."""
    by_name = {e.name: e.params for e in effects}

    def value(name, key):
        return float(by_name[name][key]) if name in by_name else 0.0

    return PlantTerms(
        delay_s=value("time_delay", "delay_s"),
        drag_Ns_per_m=value("viscous_drag", "coefficient_Ns_per_m"),
        rho_kg_per_m=value("cable_mass", "linear_density_kg_per_m"),
        rotation_amplitude_rad=value("rotational_dynamics", "amplitude_rad"),
        encoders="cable_elasticity" in by_name,
        tilted="frame_tilt" in by_name,
    )


#: the effect the winch encoders measure (its findings come from lengths.csv)
ENCODER_EFFECT = "cable_elasticity"
