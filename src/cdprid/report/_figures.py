"""Shared figure helpers (matplotlib, Agg backend) and the diagnosis residual figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cdprid.base import save_figure

__all__ = ["diagnosis_figures", "pyplot", "save_fig"]

AXES = ("fx [N]", "fy [N]", "fz [N]", "mx [N m]", "my [N m]", "mz [N m]")


def pyplot():
    """``matplotlib.pyplot`` with the Agg backend (imported on first use only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_fig(fig, path: Path, caption: str | None = None) -> Path:
    """Save a figure as PNG (150 dpi) and close it."""
    path = Path(path)
    if caption:
        fig.text(0.01, 0.005, caption, fontsize=7, color="0.4")
    save_figure(fig, path, dpi=150, bbox_inches="tight")
    pyplot().close(fig)
    return path


def _acf(x, nlags):
    x = x - x.mean()
    c = np.correlate(x, x, mode="full")[len(x) - 1:len(x) + nlags]
    return c / c[0]


def diagnosis_figures(result, out_dir) -> list[Path]:
    """Residual figures of a :class:`cdprid.diagnose.DiagnosisResult`.

    Returns the list of written PNG paths: residuals over time (base and extended),
    residuals against candidate signals, autocorrelation and spectrum.
    """
    plt = pyplot()
    out = Path(out_dir)
    A = result.arrays
    t, rb, re_ = A["t"], A["residual_base"], A["residual_extended"]
    use = A["use"]
    paths = []
    fig, axs = plt.subplots(6, 1, figsize=(10, 11), sharex=True)
    for i, ax in enumerate(axs):
        ax.plot(t[use], rb[use, i], lw=0.6, label="base (paper) model")
        if result.findings:
            ax.plot(t[use], re_[use, i], lw=0.6, label="extended model")
        ax.set_ylabel(AXES[i])
        ax.grid(alpha=0.3)
    axs[0].legend(loc="upper right", fontsize=8)
    axs[-1].set_xlabel("t [s]")
    fig.suptitle("Residual W tau - A x per wrench axis (matched-filtered)")
    paths.append(save_fig(fig, out / "residual_time.png"))

    # residual against candidate signals
    v, a, tau, pos = A["velocity"], A["acceleration"], A["tension"], A["position"]
    jerk = np.gradient(a, t, axis=0)
    sig = {"velocity": v, "jerk": jerk, "position": pos - pos[use].mean(0)}
    fig, axs = plt.subplots(2, 3, figsize=(12, 7))
    for j, (name, s) in enumerate(sig.items()):
        ax = axs[0, j]
        for k, c in enumerate("xyz"):
            ax.plot(s[use, k], rb[use, k], ".", ms=1, alpha=0.3, label=f"f{c} vs {name} {c}")
        ax.set_xlabel(name)
        ax.set_ylabel("force residual [N]")
        ax.legend(fontsize=6, markerscale=5)
    ax = axs[1, 0]
    corr = [np.corrcoef(tau[use, i], np.linalg.norm(rb[use, :3], axis=1))[0, 1]
            for i in range(tau.shape[1])]
    ax.bar(np.arange(1, tau.shape[1] + 1), corr)
    ax.set_xlabel("cable")
    ax.set_ylabel("corr(tension, |force residual|)")
    ax = axs[1, 1]
    nl = min(300, int(use.sum()) // 2)
    dt = float(np.median(np.diff(t)))
    for i in range(3):
        ax.plot(np.arange(nl + 1) * dt, _acf(rb[use, i], nl), label=AXES[i])
    ax.set_xlabel("lag [s]")
    ax.set_ylabel("autocorrelation")
    ax.legend(fontsize=7)
    ax = axs[1, 2]
    for i in range(3):
        x = rb[use, i] - rb[use, i].mean()
        f = np.fft.rfftfreq(len(x), dt)
        P = np.abs(np.fft.rfft(x * np.hanning(len(x)))) ** 2
        ax.semilogy(f, P + 1e-30, lw=0.7, label=AXES[i])
    ax.set_xlim(0, 6)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("residual power")
    ax.legend(fontsize=7)
    fig.suptitle("What the base model gets wrong: residual vs signals, autocorrelation, spectrum")
    fig.tight_layout()
    paths.append(save_fig(fig, out / "residual_signals.png"))

    if result.ranking:
        fig, ax = plt.subplots(figsize=(8, 4))
        labels = [r.candidate for r in result.ranking][:12][::-1]
        vals = [max(r.statistic, 1e-3) for r in result.ranking][:12][::-1]
        ax.barh(labels, vals)
        ax.set_xscale("log")
        ax.set_xlabel("Wald statistic (HAC)")
        ax.set_title("Candidate effects, first step")
        fig.tight_layout()
        paths.append(save_fig(fig, out / "ranking.png"))
    return paths
