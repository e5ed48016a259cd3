"""Figures of the real-data identification (:mod:`cdprid.identify._real`): wrench, residuals,
tensions and nuisances of the cumulative extensions (:func:`cdprid.identify.compare_extensions`).

``data`` is a :class:`cdprid.identify.RealData`; ``steps`` the list returned by
``compare_extensions`` (dicts with ``"step"`` and ``"result"``); ``path`` the figure file
(written atomically by :func:`cdprid.base.save_figure`).
"""

from __future__ import annotations

import numpy as np

from cdprid.base import save_figure
from cdprid.signal import zero_phase_filter

__all__ = ["fig_nuisance", "fig_residuals", "fig_tensions", "fig_wrench"]


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def fig_wrench(data, steps, path, train_until: float):
    """Measured vs model force (paper model and the final one) and the raw tensions.

    Parameters
    ----------
    data : RealData
        The prepared recording (:func:`cdprid.identify.prepare_real`).
    steps : list of dict
        :func:`cdprid.identify.compare_extensions`'s steps (``"step"``, ``"result"``).
    path : path-like
        PNG written atomically (an existing file is replaced).
    train_until : float
        End of the training part, s (a dashed line).
    """
    base, final = steps[0]["result"], next(s["result"] for s in steps if "final" in s["step"])
    plt = _pyplot()
    fig, ax = plt.subplots(4, 1, figsize=(11, 10), sharex=True)
    lab = ["F_x, N", "F_y, N", "F_z, N"]
    for i in range(3):
        ax[i].plot(data.t, final.measured[:, i], "k", lw=0.8,
                   label="measured W tau (final nuisances)")
        ax[i].plot(data.t, base.predicted[:, i], "tab:red", lw=0.7, label="paper model")
        ax[i].plot(data.t, final.predicted[:, i], "tab:blue", lw=0.7, label="final model")
        ax[i].set_ylabel(lab[i])
        ax[i].axvline(train_until, color="gray", ls="--")
    ax[0].legend(fontsize=8, ncol=3)
    slack = ~(final.train | final.test)
    ax[3].plot(data.t, data.tension_at(data.t), lw=0.6)
    ax[3].fill_between(data.t, -10, 120, where=slack, color="0.85", step="mid",
                       label="excluded (slack < 5 N, ends)")
    ax[3].set_ylim(-10, 120)
    ax[3].set_ylabel("raw tensions, N")
    ax[3].set_xlabel("t, s (train < 25 s | held-out >= 25 s)")
    ax[3].legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def fig_residuals(data, steps, path, train_until: float):
    """Force and moment residual norms of every cumulative step (taut samples).

    Parameters
    ----------
    data : RealData
        The prepared recording (:func:`cdprid.identify.prepare_real`).
    steps : list of dict
        :func:`cdprid.identify.compare_extensions`'s steps (``"step"``, ``"result"``).
    path : path-like
        PNG written atomically (an existing file is replaced).
    train_until : float
        End of the training part, s (a dashed line).
    """
    plt = _pyplot()
    fig, ax = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    for s in steps:
        if s["step"].startswith("alt"):
            continue
        r = s["result"]
        e = np.where((r.train | r.test)[:, None], r.residual, np.nan)
        ax[0].plot(data.t, np.linalg.norm(e[:, :3], axis=1), lw=0.6, label=s["step"])
        ax[1].plot(data.t, np.linalg.norm(e[:, 3:], axis=1), lw=0.6)
    for a in ax:
        a.axvline(train_until, color="gray", ls="--")
    ax[0].set_ylabel("|force residual|, N")
    ax[1].set_ylabel("|moment residual|, N m")
    ax[1].set_xlabel("t, s (taut samples only)")
    ax[0].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def fig_tensions(data, r, path, train_until: float):
    """Measured tensions vs the tensions the final model asks for (least-norm W^+ w_model).

    Parameters
    ----------
    data : RealData
        The prepared recording (:func:`cdprid.identify.prepare_real`).
    r : RealResult
        The final model's fit (offsets N, gains, delay s).
    path : path-like
        PNG written atomically (an existing file is replaced).
    train_until : float
        End of the training part, s (a dashed line).
    """
    pinv = np.linalg.pinv(data.W)

    tau_meas = zero_phase_filter((data.tension_at(data.t + r.delay) - r.offset) * r.gain, data.dt)
    tau_model = np.einsum("nij,nj->ni", pinv, r.predicted)
    plt = _pyplot()
    fig, ax = plt.subplots(4, 1, figsize=(11, 9), sharex=True)
    for i in range(4):
        ax[i].plot(data.t, tau_meas[:, i], "k", lw=0.7, label="measured (filtered, corrected)")
        ax[i].plot(data.t, tau_model[:, i], "tab:blue", lw=0.7, label="final model, W^+ w")
        ax[i].set_ylabel(f"tau_{i + 1}, N")
        ax[i].axvline(train_until, color="gray", ls="--")
    ax[0].legend(fontsize=8)
    ax[3].set_xlabel("t, s")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)


def fig_nuisance(steps, path):
    """Relative gains, zero-sum offsets (N) and the delay (ms) per model.

    Parameters
    ----------
    steps : list of dict
        :func:`cdprid.identify.compare_extensions`'s steps (``"step"``, ``"result"``).
    path : path-like
        PNG written atomically (an existing file is replaced).
    """
    r = next(s["result"] for s in steps if "final" in s["step"])
    ro = next(s["result"] for s in steps if "zero-sum" in s["step"])
    plt = _pyplot()
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.5))
    c = np.arange(1, 5)
    ax[0].errorbar(c, r.gain, yerr=[r.std[f"gain_{i}"] for i in c], fmt="o")
    ax[0].axhline(1, color="gray")
    ax[0].set_title("relative gains (final)")
    ax[1].errorbar(c, ro.offset, yerr=[ro.std[f"offset_{i}"] for i in c], fmt="o")
    ax[1].axhline(0, color="gray")
    ax[1].set_title("offsets, N (zero-sum alternative)")
    d = [s["result"].delay * 1e3 for s in steps if s["result"].options["delay"]]
    e = [s["result"].std["delay"] * 1e3 for s in steps if s["result"].options["delay"]]
    ax[2].errorbar(range(len(d)), d, yerr=e, fmt="o")
    ax[2].set_title("delay, ms (per model with delay)")
    for a in ax[:2]:
        a.set_xlabel("cable")
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)
