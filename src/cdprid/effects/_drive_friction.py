"""``drive_friction``: viscous and Coulomb friction in a winch drive (gear, bearings, drum)
between the cable and the motor current (one module, one effect; motor currents only; the
diagnosis also tests the same friction on every drive, ``drive_friction_all``)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]

# the pulley friction's blocks and hooks: a current, like a load cell on the winch side of
# the pulley, reads ``tau - f_c sign(l') - f_v l'`` (docs/drives.md: the drum's torque
# balance), so the drive's friction is the same form; on a current stream it includes the
# pulleys' own (nothing on the cable side of the motor tells the two apart)
_KEYS = ("coulomb_N", "viscous_Ns_per_m")
_BOUNDS = {"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3}
_SPEED = "motion at several speeds (Coulomb friction does not grow with the speed)"

SPEC = EffectSpec(
    name="drive_friction",
    parameters=(Parameter("cable", "cable", all_cables=True),
                Parameter("coulomb_N", "float", "N", minimum=0.0),
                Parameter("viscous_Ns_per_m", "float", "N s/m", minimum=0.0)),
    doc="""``drive_friction {cable, coulomb_N, viscous_Ns_per_m}``
    Friction in winch drive ``cable`` (or ``"all"``: the same on every drive), reflected to
    the cable: with ``l'`` the rate of the length paid out (> 0 paying out), the tension is
    ``k i + coulomb_N sign(l') + viscous_Ns_per_m l'`` (``f_c``, ``f_v`` of the drive model,
    docs/drives.md): paying out, the cable drives the drum against its friction. It includes
    the friction of the pulleys between the platform and the drum. Motor currents only
    (``diagnose --source currents``). Both coefficients are >= 0.""",
    place=Place.DRIVE,
    diagnosis=DiagnosisForm(
        blocks=(("coulomb", 1), ("pvisc", 1)), per_cable=True, group=1, keys=_KEYS,
        stream="currents", bounds=_BOUNDS, nonneg=_KEYS,
        separated_by={"viscous_drag": _SPEED}),
    variants=(("drive_friction_all", DiagnosisForm(
        blocks=(("coulomb_all", 1), ("pvisc_all", 1)), group=1, keys=_KEYS, stream="currents",
        params=lambda v, extra: {"cable": "all", "coulomb_N": float(v[0]),
                                 "viscous_Ns_per_m": float(v[1])},
        interval=lambda lo, hi, extra: {"coulomb_N": [float(lo[0]), float(hi[0])],
                                        "viscous_Ns_per_m": [float(lo[1]), float(hi[1])]},
        alias="drive_friction:cable=all", report_size=True, bounds=_BOUNDS, nonneg=_KEYS,
        separated_by={"drive_friction": "motion of one cable at a time (friction in one "
                      "drive or the same in all)", "viscous_drag": _SPEED})),),
)
