"""``cable_elasticity``: cables that stretch under tension, seen by the winch encoders (one
module, one effect; the diagnosis tests it on ``lengths.csv``, :mod:`cdprid.diagnosis`)."""

from __future__ import annotations

import numpy as np

from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _encoder(out, tension, p):
    i = p["cable"] - 1
    out[:, i] = out[:, i] / (1.0 + np.asarray(tension)[:, i] / p["EA_N"])
    return out


SPEC = EffectSpec(
    name="cable_elasticity",
    parameters=(Parameter("cable", "cable"), Parameter("EA_N", "float", "N", positive=True)),
    doc="""``cable_elasticity {cable, EA_N}``
    Cable ``cable`` stretches under its tension (Hooke's law, EA_N its axial stiffness E A
    in N): the winch encoder, which measures the unstrained length paid out, reads
    ``l = L / (1 + tau / EA_N)`` where L is the geometric (stretched) length between the
    cable's leave point and its attachment B_i and tau its tension; the other cables read
    ``l = L``. It changes no force: it shows only in the optional ``lengths.csv`` stream
    (``t, l_1..l_m``, m, at the tension times; a cdprid extension of spec 1.1, see
    ``docs/lengths.md``), which the simulator writes with this effect (or with
    ``--lengths``) plus encoder noise ``--noise-length``. The diagnosis fits it per cable
    (with an encoder zero offset) only when a dataset has ``lengths.csv``.""",
    place=Place.ENCODER, encoder=_encoder,
)
