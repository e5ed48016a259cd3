"""The winches' lengths stream of a dataset, on the pose times, for the energy balance."""

from __future__ import annotations

import numpy as np

__all__ = ["STREAMS", "winch_lengths"]

#: extra streams read as reeled cable lengths, m: the spec's ``lengths.csv`` (``t, l_1..l_m``)
#: and the UACDPR importer's ``cable_length.csv`` (``t, dl_1..dl_m``, relative to homing:
#: the energy balance needs only the lengths' range and rate)
STREAMS = (("lengths", "l_"), ("cable_length", "dl_"))


def winch_lengths(ds, t) -> np.ndarray | None:
    """The reeled cable lengths (n, m), m, at the times ``t`` (s), linearly interpolated, or
    None when the dataset has no such stream, its columns are not one per cable, a value is
    not finite or it does not cover ``t`` (never extrapolated).

    Parameters
    ----------
    ds : cdprid.io.Dataset
        Its ``extra`` streams (``lengths`` or ``cable_length``, :data:`STREAMS`).
    t : ndarray (n,)
        Times, s.

    Returns
    -------
    ndarray (n, m) or None
    """
    m, t = ds.robot.n_cables, np.asarray(t, float)
    extra = getattr(ds, "extra", None) or {}
    for name, prefix in STREAMS:
        if name not in extra:
            continue
        cols, vals = extra[name]
        vals = np.asarray(vals, float)
        if (list(cols) != ["t"] + [f"{prefix}{i + 1}" for i in range(m)] or len(vals) < 2
                or not np.all(np.isfinite(vals)) or np.any(np.diff(vals[:, 0]) <= 0)
                or t[0] < vals[0, 0] or t[-1] > vals[-1, 0]):
            continue
        return np.column_stack([np.interp(t, vals[:, 0], vals[:, 1 + i]) for i in range(m)])
    return None
