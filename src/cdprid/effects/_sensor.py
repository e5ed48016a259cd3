"""The load-cell sensor chain, declared once in physical order.

What a load cell reads, from the cable to the number in ``tension.csv``: the tension on the
winch side of the pulley (``pulley_friction``), through the play of a hysteretic cell
(``load_cell_hysteresis``), scaled by the cell's gain (``tension_gain``),
plus its zero offset (``tension_offset``) and its zero drift (``tension_drift``), then noise.
The simulator applies :data:`SENSOR_CHAIN` in this order (:func:`load_cell_reading`); the
diagnosis undoes it in the reverse order (the ``tension`` hooks of
:data:`cdprid.effects.DIAGNOSIS`, checked by the tests).
"""

from __future__ import annotations

import numpy as np

from cdprid.effects import _load_cell_hysteresis, _tension_drift

__all__ = ["SENSOR_CHAIN", "load_cell_reading"]


def _friction(x, p, ctx):
    i = slice(None) if p["cable"] == "all" else p["cable"] - 1
    ld = ctx["ldot"][:, i]
    x[:, i] += -p["coulomb_N"] * np.sign(ld) - p["viscous_Ns_per_m"] * ld
    return x


def _gain(x, p, ctx):
    x[:, p["cable"] - 1] *= p["gain"]
    return x


def _offset(x, p, ctx):
    x[:, p["cable"] - 1] += p["offset_N"]
    return x


#: (effect name, how it changes the reading) in physical order, cable to number
SENSOR_CHAIN = (
    ("pulley_friction", _friction),
    (_load_cell_hysteresis.NAME, _load_cell_hysteresis.read),
    ("tension_gain", _gain),
    ("tension_offset", _offset),
    (_tension_drift.NAME, _tension_drift.read),
)


def load_cell_reading(effects, tau, W, v, omega, t) -> np.ndarray:
    """What the load cells read (before noise), ``(k, m)``.

    Parameters
    ----------
    effects : sequence of Effect
    tau : (k, m) cable tensions on the platform side, N
    W : (k, 6, m) true wrench matrices (for the cable rates ``dl/dt = -W^T [v; omega]``)
    v, omega : (k, 3) platform velocity and angular rate at the tension times
    t : (k,) tension time stamps, s (the drift counts from the first)

    Returns
    -------
    ndarray (k, m)
    """
    t = np.asarray(t, float)
    ldot = -np.einsum("nim,ni->nm", np.asarray(W), np.concatenate([v, omega], axis=1))
    ctx = {"t": t - t[0] if t.size else t, "ldot": ldot}
    x = np.array(tau, float)
    for name, apply in SENSOR_CHAIN:
        for e in effects:
            if e.name == name:
                x = apply(x, e.params, ctx)
    return x
