"""Figures of the tuning feature: the tuned differentiator's acceleration frequency response."""

from __future__ import annotations

from pathlib import Path

__all__ = ["plot_response"]


def plot_response(resp, path, method: str = "", force: bool = False) -> Path:
    """Gain and phase of the acceleration vs frequency, bandwidth and bounds marked.

    Parameters
    ----------
    resp : cdprid.tuning.FrequencyResponse
    path : path-like
        PNG to write (atomically; refused if it exists unless ``force``).
    method : str
        Title.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..outputs import save_figure
    from ..tuning import GAIN_MAX_ABOVE, GAIN_MAX_BELOW

    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6.5, 5.5), sharex=True)
    ax1.semilogx(resp.freqs_hz, resp.gain, "o-", ms=3)
    ax1.axhline(GAIN_MAX_BELOW, color="r", ls=":", lw=1, label=f"bound {GAIN_MAX_BELOW:g}")
    ax1.axhline(GAIN_MAX_ABOVE, color="k", ls=":", lw=1)
    if resp.bandwidth_hz > 0:
        for ax in (ax1, ax2):
            ax.axvline(resp.bandwidth_hz, color="g", ls="--", lw=1)
    ax1.set_ylabel("acceleration gain")
    ax1.set_title(f"{method}: acceleration response (amplitude {resp.amplitude_m:g} m); "
                  f"bandwidth {resp.bandwidth_hz:.3g} Hz", fontsize=9)
    ax1.legend(fontsize=8)
    ax2.semilogx(resp.freqs_hz, resp.phase_deg, "o-", ms=3)
    ax2.set_ylabel("phase (deg)")
    ax2.set_xlabel("frequency (Hz)")
    fig.tight_layout()
    out = save_figure(fig, Path(path), force=force)
    plt.close(fig)
    return out
