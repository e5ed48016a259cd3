"""``pulley_friction``: friction where a cable runs over its pulley between the platform and
its load cell (one module, one effect; the diagnosis also tests the same friction on every
cable, ``pulley_friction_all``)."""

from __future__ import annotations

import numpy as np

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _read(x, p, ctx):
    i = slice(None) if p["cable"] == "all" else p["cable"] - 1
    ld = ctx["ldot"][:, i]
    x[:, i] += -p["coulomb_N"] * np.sign(ld) - p["viscous_Ns_per_m"] * ld
    return x


def _undo(tau, q, c):
    import jax.numpy as jnp

    slide = c.get("slide", jnp.sign(c["ldot"]))  # expected sign, see the diagnosis's problem
    return tau + q["coulomb"] * slide + q["pvisc"] * c["ldot"]


def _undo_all(tau, q, c):
    import jax.numpy as jnp

    slide = c.get("slide", jnp.sign(c["ldot"]))
    return tau + q["coulomb_all"] * slide + q["pvisc_all"] * c["ldot"]


_KEYS = ("coulomb_N", "viscous_Ns_per_m")
_BOUNDS = {"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3}
_SPEED = "motion at several speeds (Coulomb friction does not grow with the speed)"

SPEC = EffectSpec(
    name="pulley_friction",
    parameters=(Parameter("cable", "cable", all_cables=True),
                Parameter("coulomb_N", "float", "N", minimum=0.0),
                Parameter("viscous_Ns_per_m", "float", "N s/m", minimum=0.0)),
    doc="""``pulley_friction {cable, coulomb_N, viscous_Ns_per_m}``
    Friction where cable ``cable`` (or ``"all"``: the same coefficients on every cable, as
    on a robot whose pulleys are alike) runs over its pulley/guide between the platform and a
    load cell on the winch side. With ``dl/dt`` the rate of the cable length between the
    exit point and the platform (``dl/dt = -W_i^T [v; omega]``, > 0 paying out), the load
    cell reads ``tau - coulomb_N sign(dl/dt) - viscous_Ns_per_m dl/dt`` before gain,
    offset and noise: hauling the cable in, the winch side needs more than the platform
    side gets. Both coefficients are >= 0.""",
    place=Place.PULLEY, read=_read,
    diagnosis=DiagnosisForm(
        blocks=(("coulomb", 1), ("pvisc", 1)), per_cable=True, group=1, keys=_KEYS,
        stream="tensions",
        tension=_undo, bounds=_BOUNDS, nonneg=_KEYS),
    variants=(("pulley_friction_all", DiagnosisForm(
        blocks=(("coulomb_all", 1), ("pvisc_all", 1)), group=1, keys=_KEYS,
        stream="tensions",
        tension=_undo_all,
        params=lambda v, extra: {"cable": "all", "coulomb_N": float(v[0]),
                                 "viscous_Ns_per_m": float(v[1])},
        interval=lambda lo, hi, extra: {"coulomb_N": [float(lo[0]), float(hi[0])],
                                        "viscous_Ns_per_m": [float(lo[1]), float(hi[1])]},
        alias="pulley_friction:cable=all", report_size=True, bounds=_BOUNDS, nonneg=_KEYS,
        separated_by={"pulley_friction": "motion of one cable at a time (friction on one "
                      "pulley or the same on all)", "viscous_drag": _SPEED})),),
)
