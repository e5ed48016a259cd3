"""Identification without the episodes: the samples of pushes, load-cell steps and pose
glitches (:func:`cdprid.episodes.find_episodes`) left out of the fit, as gaps are."""

from __future__ import annotations

from cdprid.base import CUTOFF_HZ
from cdprid.episodes import find_episodes

__all__ = ["without_episodes"]


def without_episodes(ds, sig, params: dict, keep, trim: float, run: bool, keep_episodes: bool,
                     notes: list):
    """The samples ``keep`` without the episodes' (unless kept), and the episodes found.

    Parameters
    ----------
    ds : Dataset
    sig : AlignedSignals
        The aligned window the fit uses.
    params : dict
        The differentiator's parameters (``cutoff_hz`` sets the episodes' matched filter,
        default :data:`cdprid.base.CUTOFF_HZ`).
    keep : ndarray (n,) of bool
        Samples the fit would use (trimmed), on ``sig.t``.
    trim : float
        Seconds left out at the edges of every segment, s.
    run : bool
        Locate the episodes at all.
    keep_episodes : bool
        Report them but keep their samples (``--keep-episodes``).
    notes : list of str
        One sentence appended when episodes are found.

    Returns
    -------
    keep : ndarray (n,) of bool
    episodes : Episodes or None
    """
    if not run:
        return keep, None
    eps = find_episodes(ds.robot, sig, cutoff_hz=float(params.get("cutoff_hz", CUTOFF_HZ)),
                        trim=trim)
    if eps.episodes and keep_episodes:
        notes.append(f"{len(eps.episodes)} episode(s) located and kept in the fit "
                     "(--keep-episodes)")
    elif eps.episodes:
        notes.append(eps.note())
        if (keep & ~eps.excluded).sum() >= 10:
            keep = keep & ~eps.excluded
    return keep, eps
