"""``drive_friction``: viscous and Coulomb friction in a winch drive (gear, bearings, drum)
between the cable and the motor current (one module, one effect; motor currents only)."""

from __future__ import annotations

from cdprid.effects._form import Z95 as _Z
from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _report(v, s, kn):
    """The fitted Coulomb and viscous friction and their intervals."""
    return ({"coulomb_N": v["fc"], "viscous_Ns_per_m": v["fv"]},
            {"coulomb_N": [v["fc"] - _Z * s["fc"], v["fc"] + _Z * s["fc"]],
             "viscous_Ns_per_m": [v["fv"] - _Z * s["fv"], v["fv"] + _Z * s["fv"]]})


# the pulley friction's blocks and hooks: a current, like a load cell on the winch side of
# the pulley, reads ``tau - f_c sign(l') - f_v l'`` (docs/drives.md: the drum's torque
# balance), so the drive's friction is the same form; on a current stream it includes the
# pulleys' own (nothing on the cable side of the motor tells the two apart)
_KEYS = ("coulomb_N", "viscous_Ns_per_m")
_BOUNDS = {"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3}
_SPEED = "motion at several speeds (Coulomb friction does not grow with the speed)"

SPEC = EffectSpec(
    name="drive_friction",
    parameters=(Parameter("cable", "cable"),
                Parameter("coulomb_N", "float", "N", minimum=0.0),
                Parameter("viscous_Ns_per_m", "float", "N s/m", minimum=0.0)),
    doc="""``drive_friction {cable, coulomb_N, viscous_Ns_per_m}``
    Friction in winch drive ``cable``, reflected to
    the cable: with ``l'`` the rate of the length paid out (> 0 paying out), the tension is
    ``k i + coulomb_N sign(l') + viscous_Ns_per_m l'`` (``f_c``, ``f_v`` of the drive model,
    docs/drives.md): paying out, the cable drives the drum against its friction. It includes
    the friction of the pulleys between the platform and the drum. Motor currents only:
    ``diagnose --source currents`` names it from ``identify --source currents``' drive model.
    Both coefficients are >= 0.""",
    place=Place.DRIVE,
    diagnosis=DiagnosisForm(
        blocks=(("coulomb", 1), ("pvisc", 1)), per_cable=True, group=1, keys=_KEYS,
        stream="currents", drive=("fc", "fv"), drive_report=_report, bounds=_BOUNDS,
        nonneg=_KEYS,
        separated_by={"viscous_drag": _SPEED}),
)
