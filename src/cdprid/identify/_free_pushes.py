"""Pushes on a freely swinging platform, located in its own residual (``identify --source
free-motion``).

A hand pushing the platform acts in the free directions, exactly the equations the
free-motion fit reads (on a simulated recording, pushes kept doubled z_G). Two tests locate
them:

1. with load cells, the episodes stage (:func:`cdprid.episodes.find_episodes`: the cable
   wrench residual and the energy balance of the locked platform);
2. always, the free directions' own residual ``F[N^T S Z] theta`` (n, 6 - m): the episodes
   stage's change-point scan (:func:`cdprid.episodes.locate`, its noise model and false-alarm
   rate) on it, fit -> locate -> refit until the stretches stop changing (at most
   :data:`PASSES` passes). No tension is needed.

When the scan's stretches would cover more than :data:`MAX_SHARE` of the samples, the residual
is not local in time (the model misses something all along: geometry, pulley friction, drag) and
the scan's stretches are not used; the command says so. The share is higher than the episodes
stage's 30 %: a release protocol (push, let swing, push again) may spend up to half its time
pushing, which a simulated recording does (33 %).
"""

from __future__ import annotations

import math

import numpy as np

from cdprid.effects import EXTERNAL_WRENCH
from cdprid.episodes import (
    Episode,
    filter_autocorrelation,
    find_episodes,
    locate,
    noise_model,
    winch_lengths,
    window_level,
)
from cdprid.identify._free_rows import fit_rows

__all__ = ["MAX_SHARE", "PASSES", "left_out"]

#: scan stretches covering more than this share of the fitted samples are not local in time
MAX_SHARE = 0.5
#: fit -> scan -> refit passes at most
PASSES = 3


def _stage(ds, sig, cutoff: float, trim: float, far_per_hour: float):
    """The episodes stage's episodes and exclusion (tensions needed), or none."""
    if ds.tension is None:
        return (), np.zeros(len(sig.t), bool), 0.0
    found = find_episodes(ds.robot, sig, cutoff_hz=cutoff, trim=trim,
                          far_per_hour=far_per_hour, lengths=winch_lengths(ds, sig.t))
    return found.episodes, found.excluded, float(found.margin_s)


def _residual_episode(t, a: int, b: int, T: float, mean, p: float) -> Episode:
    """A stretch of the free directions' residual as an ``external_wrench`` episode (only its
    projection on the free directions is seen: force and moment are not given)."""
    return Episode(float(t[a]), float(t[b - 1]), EXTERNAL_WRENCH, None, None, None, None, p,
                   {"free_directions_N": float(np.linalg.norm(mean)),
                    "located_by": "free-motion residual"})


def left_out(ds, sig, P, ref_i: int, ref_value: float, names, cutoff: float, trim: float,
             far_per_hour: float, use, chunk: int):
    """The samples the free-motion fit leaves out and what located them.

    Parameters
    ----------
    ds : Dataset
    sig : AlignedSignals
    P : (n, k, p) the free directions' rows (:func:`cdprid.identify._free_rows.
        projected_filtered_rows`)
    ref_i : int
        The reference parameter's index.
    ref_value : float
        Its value (scales the residual to newtons).
    names : tuple of str
    cutoff : float
        The matched filter's cutoff, Hz.
    trim : float
        Seconds left out at the segments' edges, s.
    far_per_hour : float
        False alarms per hour on a push-free recording (both tests).
    use : (n,) bool
        The samples the fit may use.
    chunk : int

    Returns
    -------
    excluded : (n,) bool
    episodes : tuple of Episode (time order)
    caveat : str or None
        Why the residual scan's stretches were not used.
    margin_s : float
        Seconds of filter transient added on each side.
    """
    t, dt = np.asarray(sig.t, float), float(sig.dt)
    eps, stage, margin_s = _stage(ds, sig, cutoff, trim, far_per_hour)
    margin = max(2, int(math.ceil(2.0 / (cutoff * dt))))
    level = window_level(far_per_hour)
    rho = filter_autocorrelation(dt, cutoff)
    max_lag = int(math.ceil(1.5 / (cutoff * dt)))
    n_windows = (t[-1] - t[0]) * 2.0 * sum(1.0 / s for s in (0.2, 0.4, 0.8, 1.6, 3.2))
    excl, found, caveat = stage.copy(), [], None
    for _ in range(PASSES):
        if (use & ~excl).sum() < 10 * P.shape[2]:
            break
        res = fit_rows(P, np.flatnonzero(use & ~excl), ref_i, names, chunk)
        r = np.einsum("nkp,p->nk", P, ref_value * np.insert(res.x, ref_i, 1.0))
        nm = noise_model(r, use & ~excl, max_lag, rho)
        found = locate(r, use, dt, nm, level, guard=margin)
        scanned = np.zeros_like(stage)
        for a, b, _, _ in found:
            scanned[max(0, a - margin):b + margin] = True
        new = stage | scanned
        share = float((scanned & use).sum()) / max(1, int(use.sum()))
        if share > MAX_SHARE:
            caveat = (f"the free directions' residual departs from its noise over "
                      f"{100 * share:.0f} % of the recording: not local pushes but something "
                      "the free-motion model misses all along (geometry, pulley friction, "
                      "drag); its stretches are not left out and the estimate may be biased")
            excl, found = stage.copy(), []
            break
        if np.array_equal(new, excl):
            break
        excl = new
    from cdprid.base import chi2_sf

    k = P.shape[1]
    eps = tuple(sorted(tuple(eps) + tuple(
        _residual_episode(t, a, b, T, mean, float(min(1.0, chi2_sf(T, k) * n_windows)))
        for a, b, T, mean in found), key=lambda e: e.start_s))
    return excl, eps, caveat, max(margin_s, margin * dt)
