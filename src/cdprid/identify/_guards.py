"""identify's use of the plausibility guards of :mod:`cdprid.core` (issue 25): the
swapped-columns check run on the identification's own fit and matched filter."""

from __future__ import annotations

import numpy as np

from cdprid.core import SWAP_CHECK_MAX_SAMPLES
from cdprid.core import swapped_columns_warning as _swapped_columns

__all__ = ["swapped_columns_warning"]


def swapped_columns_warning(robot, report, tension) -> str | None:
    """:func:`cdprid.core.swapped_columns_warning` on an :class:`IdentificationReport`.

    Parameters
    ----------
    robot : CableRobot
    report : IdentificationReport
        Its motion, kept samples, regressor and wrench filter are used.
    tension : array (k, m)
        The raw tension stream (only its width is used).

    Returns
    -------
    str or None
        The warning, or None (no swap found, fewer than 2 cables, or too many samples to check).
    """
    from cdprid.identify._batch import _wrench_filter

    motion, reg = report.motion, report.regression
    n, m = len(motion.t), np.asarray(tension).shape[1]
    tau = np.asarray(report.signals.tension, float)
    if n > SWAP_CHECK_MAX_SAMPLES or m < 2 or len(reg.t) < 10 or tau.shape[0] != n:
        return None  # before the regressor is materialised
    wf, _, _ = _wrench_filter(robot, report.differentiator, report.params,
                              float(np.median(np.diff(motion.t))), report.wrench_filter)
    linear = report.differentiator == "euler-filtfilt" or hasattr(wf, "taps")
    return _swapped_columns(robot, motion, reg.A, np.searchsorted(motion.t, reg.t), tau, wf,
                            linear)
