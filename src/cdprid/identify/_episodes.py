"""Identification without the episodes: the samples of pushes, load-cell steps and pose
glitches (:func:`cdprid.episodes.find_episodes`) left out of the fit, as gaps are."""

from __future__ import annotations

from cdprid.base import CUTOFF_HZ, InputError
from cdprid.episodes import find_episodes, winch_lengths

__all__ = ["without_episodes"]


def without_episodes(ds, sig, params: dict, trim: float, keep_episodes: bool | None,
                     notes: list):
    """The samples more than ``trim`` from both ends without the episodes' (unless kept), and
    the episodes found.

    Parameters
    ----------
    ds : Dataset
    sig : AlignedSignals
        The aligned window the fit uses.
    params : dict
        The differentiator's parameters (``cutoff_hz`` sets the episodes' matched filter,
        default :data:`cdprid.base.CUTOFF_HZ`).
    trim : float
        Seconds left out at both ends (and at the edges of every segment), s.
    keep_episodes : bool or None
        Report them but keep their samples (``--keep-episodes``); None: do not locate them.
    notes : list of str
        One sentence appended when episodes are found.

    Returns
    -------
    keep : ndarray (n,) of bool
    episodes : Episodes or None
    """
    keep = _trimmed(sig.t, trim, ds.path)
    if keep_episodes is None:
        return keep, None
    eps = find_episodes(ds.robot, sig, cutoff_hz=float(params.get("cutoff_hz", CUTOFF_HZ)),
                        trim=trim, lengths=winch_lengths(ds, sig.t))
    if eps.episodes and keep_episodes:
        notes.append(f"{len(eps.episodes)} episode(s) located and kept in the fit "
                     "(--keep-episodes)")
    elif eps.episodes:
        notes.append(eps.note())
        if (keep & ~eps.excluded).sum() >= 10:
            keep = keep & ~eps.excluded
    return keep, eps


def _trimmed(t, trim: float, path):
    """Samples more than ``trim`` s from both ends (at least 10, else one sentence)."""
    keep = (t >= t[0] + trim) & (t <= t[-1] - trim)
    if keep.sum() < 10:
        raise InputError(
            f"{path}: fewer than 10 samples remain after trimming {trim:g} s at each end."
        )
    return keep
