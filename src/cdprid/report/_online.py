"""Figure of an online identification: parameters vs time with +-2 sigma bands."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from cdprid.identify import OnlineResult
from cdprid.report._figures import pyplot, save_fig

__all__ = ["plot_online"]


def plot_online(res: OnlineResult, path, truth=None, title: str | None = None) -> Path:
    """Parameters vs time with +-2 sigma bands (one panel per parameter), saved as PNG.

    Parameters
    ----------
    res : OnlineResult
    path : str or Path
    truth : array (p,) or (n, p), optional
        Reference values drawn as dashed lines.
    title : str, optional

    Returns
    -------
    Path
        The PNG written (atomically, 150 dpi).
    """
    plt = pyplot()
    p = len(res.names)
    ncol = 2 if p > 4 else 1
    nrow = int(math.ceil(p / ncol)) + 1
    fig, axs = plt.subplots(nrow, ncol, figsize=(9 if ncol == 1 else 12, 1.7 * nrow),
                            sharex=True, squeeze=False)
    t = res.t
    u = res.used
    for i, name in enumerate(res.names):
        ax = axs[i // ncol if ncol == 1 else i // 2][0 if ncol == 1 else i % 2]
        x, s = res.x[:, i], res.sigma[:, i]
        ax.fill_between(t[u], (x - 2 * s)[u], (x + 2 * s)[u], color="C0", alpha=0.25, lw=0,
                        label="+-2 sigma")
        ax.plot(t[u], x[u], color="C0", lw=1.0, label="online estimate")
        if truth is not None:
            tr = np.asarray(truth, float)
            ax.plot(t, tr[:, i] if tr.ndim == 2 else np.full_like(t, tr[i]), "k--", lw=0.8,
                    label="reference")
        final = x[-1]
        span = 10 * max(np.nanmedian(s[u][len(s[u]) // 2:]) if u.any() else 0.0,
                        1e-3 * abs(final), 1e-9)
        lo, hi = final - span, final + span
        if truth is not None:  # keep every reference value (e.g. before a payload step) in view
            ref = tr[:, i] if tr.ndim == 2 else np.array([tr[i]])
            pad = 0.1 * (max(hi, ref.max()) - min(lo, ref.min()))
            lo, hi = min(lo, ref.min() - pad), max(hi, ref.max() + pad)
        ax.set_ylim(lo, hi)
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
    for j in range(p, (nrow - 1) * ncol):
        axs[j // ncol][j % ncol].set_visible(False)
    axs[0][0].legend(loc="upper right", fontsize=7)
    for c in range(ncol):
        ax = axs[-1][c]
        ax.plot(t, res.excitation, color="C2", lw=0.8, label="excitation [m/s^2]")
        ax.fill_between(t, 0, np.nanmax(res.excitation) if res.excitation.size else 1.0,
                        where=~res.excitation_ok, color="C3", alpha=0.15, lw=0,
                        label="not exciting")
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    fig.suptitle(title or f"online identification ({res.model} model, lambda = "
                          f"{res.forgetting:g}, wrench filter {res.wrench_filter})")
    return save_fig(fig, path)
