"""``tension_drift``: a load cell whose zero drifts linearly in time (one module, one effect).

Everything the tool knows about this effect is here, in :data:`SPEC`: its parameters, its model
text (for ``docs/effects.md``), what the load cell reads (the simulator's sensor chain) and its
form in the diagnosis. :mod:`cdprid.effects._registry` registers it with one line.
"""

from __future__ import annotations

import numpy as np

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC", "read"]

_DOC = """``tension_drift {cable, rate_N_per_s}``
    The zero of load cell ``cable`` drifts at a constant rate (temperature, creep of the
    strain gauge): at time ``t`` it reads ``rate_N_per_s (t - t0)`` more, ``t0`` the first
    time stamp of the tension stream (the recording's own clock: a diagnosis of a long
    recording analysed on blocks evaluates it at each block's real time stamps). In the
    sensor chain the drift adds to the reading after the gain, with the offset. Either sign;
    a constant part is a ``tension_offset``."""


def read(reading: np.ndarray, params: dict, ctx: dict) -> np.ndarray:
    """The load-cell readings ``(k, m)`` with the drift added (simulator sensor chain).

    ``ctx["t"]``: the tension time stamps minus the stream's first one, ``(k,)``, s.
    """
    out = np.array(reading, float)
    out[:, params["cable"] - 1] += params["rate_N_per_s"] * np.asarray(ctx["t"], float)
    return out


def _undo(tau, q, c):
    """The reading without the drift (diagnosis, tension hook; ``c["t"]`` the clock)."""
    return tau - q["drift"] * c["t"]


SPEC = EffectSpec(
    name="tension_drift",
    parameters=(Parameter("cable", "cable"), Parameter("rate_N_per_s", "float", "N/s")),
    doc=_DOC, place=Place.ZERO, read=read,
    diagnosis=DiagnosisForm(
        blocks=(("drift", 1),), per_cable=True, group=1, keys=("rate_N_per_s",),
        stream="tensions",
        tension=_undo, bounds={"rate_N_per_s": 100.0},
        separated_by={"tension_offset": "a longer recording (an offset stays, a drift grows "
                      "with time)",
                      "tension_gain": "a trajectory whose tension on that cable does not rise "
                      "or fall with time (a gain follows the tension, a drift the clock)"}),
)
