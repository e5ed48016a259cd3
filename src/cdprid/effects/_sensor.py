"""The load-cell sensor chain, declared once in physical order.

What a load cell reads, from the cable to the number in ``tensions.csv``: the tension on the
winch side of the pulley (``pulley_friction``), through the play of a hysteretic cell
(``load_cell_hysteresis``), scaled by the cell's gain (``tension_gain``),
plus its zero offset (``tension_offset``) and its zero drift (``tension_drift``), then noise.
Each effect declares its place (:class:`cdprid.effects._spec.Place`); the chain
(:data:`cdprid.effects._registry.SENSOR_CHAIN`) is derived from the registry in that order and
the simulator applies it (:func:`load_cell_reading`); the diagnosis undoes it in the reverse
order (the ``tension`` hooks of :data:`cdprid.effects.DIAGNOSIS`, checked at import and by the
tests).
"""

from __future__ import annotations

import numpy as np

from cdprid.effects._registry import SENSOR_CHAIN

__all__ = ["SENSOR_CHAIN", "load_cell_reading"]


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
