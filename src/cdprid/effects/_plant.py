"""What the simulator's plant takes from a list of effects (:func:`plant_terms`).

The simulator asks this module instead of testing effect names: the scalar terms of the
plant (delay, drag, cable mass, rotation amplitude; each spec's ``plant``) and its switches
(winch encoders, tilted gravity; the specs with an ``encoder`` or ``gravity`` term).
"""

from __future__ import annotations

import dataclasses

__all__ = ["PlantTerms", "plant_terms"]


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
    """The plant's scalar terms and switches from a list of effects (see :class:`PlantTerms`).

    Parameters
    ----------
    effects : sequence of Effect

    Returns
    -------
    PlantTerms
    """
    from cdprid.effects._registry import SPECS

    values: dict = {}
    encoders = tilted = False
    for e in effects:
        spec = SPECS[e.name]
        values.update({field: float(e.params[key]) for field, key in spec.plant})
        encoders |= spec.encoder is not None
        tilted |= spec.gravity is not None
    return PlantTerms(**values, encoders=encoders, tilted=tilted)
