"""Figures of the tuning feature: the tuned differentiator's acceleration frequency response."""

from __future__ import annotations

from pathlib import Path

__all__ = ["plot_response"]


def plot_response(resp, path, method: str = "", force: bool = False) -> Path:
    """Gain and phase of the acceleration vs frequency, bandwidth and bounds marked.

    Parameters
    ----------
    resp : cdprid.tuning._tuning.FrequencyResponse
    path : path-like
        PNG to write (atomically; refused if it exists unless ``force``).
    method : str
        Title.
    force : bool
        Replace an existing file.

    Returns
    -------
    Path
        The PNG written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cdprid.base import save_figure
    from cdprid.tuning import GAIN_MAX_ABOVE, GAIN_MAX_BELOW

    b = resp.bounds
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(6.5, 5.5), sharex=True)
    ax1.semilogx(resp.freqs_hz, resp.gain, "o-", ms=2)
    if b is None:
        ax1.axhline(GAIN_MAX_BELOW, color="r", ls=":", lw=1, label=f"bound {GAIN_MAX_BELOW:g}")
        ax1.axhline(GAIN_MAX_ABOVE, color="k", ls=":", lw=1)
        bw, title = resp.bandwidth_hz, f"bandwidth {resp.bandwidth_hz:.3g} Hz"
    else:
        bw = b.bandwidth_hz
        f = resp.freqs_hz
        ax1.fill_between([f[0], bw], 1 - b.gain_tol, 1 + b.gain_tol, color="g", alpha=0.15,
                         label=f"|gain - 1| <= {b.gain_tol:g} up to B")
        ax1.hlines(b.gain_max_above, bw, f[-1], color="r", ls=":", lw=1,
                   label=f"gain <= {b.gain_max_above:g} above B")
        ax2.fill_between([f[0], bw], -b.phase_max_deg, b.phase_max_deg, color="g", alpha=0.15,
                         label=f"|phase| <= {b.phase_max_deg:g} deg up to B")
        ax2.legend(fontsize=8)
        title = (f"stated bandwidth B {bw:.3g} Hz: "
                 + ("within bounds" if resp.ok else "NOT within bounds"))
    if bw > 0:
        for ax in (ax1, ax2):
            ax.axvline(bw, color="g", ls="--", lw=1)
    ax1.set_ylabel("acceleration gain")
    kind = "" if resp.linear else f", describing response at {resp.amplitude_m:g} m"
    ax1.set_title(f"{method}: acceleration response{kind}; {title}", fontsize=9)
    ax1.legend(fontsize=8)
    ax2.semilogx(resp.freqs_hz, resp.phase_deg, "o-", ms=2)
    ax2.set_ylabel("phase (deg)")
    ax2.set_xlabel("frequency (Hz)")
    fig.tight_layout()
    out = save_figure(fig, Path(path), force=force)
    plt.close(fig)
    return out
