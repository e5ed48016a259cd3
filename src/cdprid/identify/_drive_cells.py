"""Load cells calibrated against the drives (issue 41): with both currents and tensions, each
cell's gain and offset against the tension the identified drive model gives."""

from __future__ import annotations

import numpy as np

from cdprid.identify._cells import CellCalibration, cells_from_design
from cdprid.model import PARAMETER_NAMES
from cdprid.signal import zero_phase_filter

__all__ = ["cells_against_drives"]


def cells_against_drives(ds, model, motion, idx, cur, lengths, sign, wf, dt, params, theta,
                         cov, chunk, notes: list) -> CellCalibration | None:
    """Gains and offsets of the load cells against ``tau_hat = k i + J l'' + f_v l' + f_c s -
    c`` (every channel through the matched filter, as the readings).

    Parameters
    ----------
    ds : Dataset (its tensions; None: no calibration)
    model : str
    motion : Motion
    idx : (n,) the samples the identification used
    cur, lengths, sign : (N, m) on the pose clock (all samples)
    wf : the matched filter
    dt : float
    params : the differentiator's parameters (``cutoff_hz``)
    theta, cov : the identification's estimate and covariance (platform then drives)
    chunk : int
    notes : list
        A sentence is added when the tensions do not cover the samples.

    Returns
    -------
    CellCalibration or None
    """
    if ds.tension is None:
        return None
    t = motion.t
    tt = np.asarray(ds.tension_t, float)
    if tt[0] > t[idx[0]] or tt[-1] < t[idx[-1]]:
        notes.append("load cells not calibrated against the drives: tensions.csv does not cover "
                     "the samples used")
        return None
    meas = np.column_stack([np.interp(t, tt, c) for c in np.asarray(ds.tension, float).T])
    m = ds.robot.n_cables
    d1 = np.gradient(lengths, dt, axis=0)
    d2 = np.empty_like(lengths)
    d2[1:-1] = (lengths[2:] - 2 * lengths[1:-1] + lengths[:-2]) / dt ** 2
    d2[0], d2[-1] = d2[1], d2[-2]

    def F(x):
        return np.asarray(wf(x, np.ones(x.shape[1])))

    chans = [F(cur), zero_phase_filter(d2, dt, params["cutoff_hz"], params.get("order", 2)),
             F(d1), F(sign), -np.ones_like(cur)]
    p = len(PARAMETER_NAMES[model])
    n = len(t)
    T = np.zeros((n, m, p + 5 * m))
    for a, ch in enumerate(chans):
        T[:, np.arange(m), p + a * m + np.arange(m)] = ch
    return cells_from_design(T[idx], theta, cov, F(meas)[idx], "the drives (currents)", chunk)
