"""The differentiator's bandwidth chosen from the data (issue 24).

A fixed 4 Hz zero-phase cutoff lets the orientation noise through the angular acceleration:
the inertia's regressor then carries noise that the least squares cannot tell from signal, and
the estimate is attenuated towards zero (errors in variables: -10 to -30 % on the CRAFT-like
robot with 0.3 mrad). Matched filtering makes any cutoff unbiased on noise-free data, so the
cutoff only trades information (signal above it is discarded) against this attenuation.

:func:`choose_cutoff` takes the *widest* cutoff of a grid (1 to 4 Hz) whose predicted
attenuation stays below :data:`BUDGET` for every channel group: the translational
accelerations (position noise) and, with rotation, the angular accelerations (orientation
noise). For each candidate cutoff ``fc``, with the filter's power gain ``G`` (zero-phase
Butterworth: ``1 / (1 + (f / fc)^(2 n))^2``) and the second difference's ``D``:

* noise power: ``sum_f 2 s^2 dt |D(f)|^2 G(f)`` (white noise of std ``s``, estimated from the
  data by :func:`cdprid.core.estimate_noise`);
* signal power: the same sum over the measured acceleration spectrum (Hann-windowed
  periodogram of the second differences) minus the noise's;
* predicted attenuation: their ratio (a regressor with noise variance ``r`` times its signal's
  has its coefficient shrunk by about ``r / (1 + r)``).

Noise-free data keep 4 Hz; noisier data get a narrower filter.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["BUDGET", "BandwidthChoice", "choose_cutoff"]

BUDGET = 1e-3
"""Largest predicted errors-in-variables attenuation (noise over signal power of the
differentiated accelerations) accepted for the chosen cutoff."""

GRID_HZ = tuple(float(f) for f in np.arange(1.0, 4.0001, 0.25))
"""Candidate cutoffs, Hz (4 Hz: the paper's, the widest considered)."""


@dataclasses.dataclass(frozen=True)
class BandwidthChoice:
    """The cutoff chosen from the data and why.

    Attributes
    ----------
    cutoff_hz : float
    ratio : dict
        Predicted attenuation (noise over signal power) per channel group at ``cutoff_hz``.
    limited_by : str
        The group that set the cutoff (``"noise-free"`` when none limits it).
    within_budget : bool
        False when even the narrowest cutoff exceeds :data:`BUDGET`.
    """

    cutoff_hz: float
    ratio: dict
    limited_by: str
    within_budget: bool

    def note(self) -> str:
        """One sentence for the report: the cut-off chosen, why, and how to override it.

        Returns
        -------
        str
            The note (cut-off in Hz, the errors-in-variables budget, the noise over signal power
            per motion kind).
        """
        r = ", ".join(f"{k} {v:.1e}" for k, v in self.ratio.items())
        why = ("the widest with a predicted errors-in-variables attenuation below "
               f"{BUDGET:.0e}" if self.within_budget else
               f"the narrowest considered; the predicted attenuation still exceeds {BUDGET:.0e}")
        return (f"differentiator bandwidth chosen from the data: cutoff {self.cutoff_hz:g} Hz, "
                f"{why} (noise over signal power: {r}; set --params cutoff_hz to override)")


def _spectrum(x: np.ndarray, dt: float, segments) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean one-sided PSD of the second differences of ``x`` (n, k) summed over channels, on
    the frequency grid of the longest segment; and that grid and the segment's length."""
    segs = [(a, b) for a, b in segments if b - a >= 64] or [(0, len(x))]
    a0, b0 = max(segs, key=lambda s: s[1] - s[0])
    n = b0 - a0 - 2
    f = np.fft.rfftfreq(n, dt)
    acc = np.zeros_like(f)
    wsum = 0.0
    for a, b in segs:
        d2 = (x[a + 2:b] - 2.0 * x[a + 1:b - 1] + x[a:b - 2]) / dt ** 2
        m = len(d2)
        w = np.hanning(m)[:, None]
        spec = np.abs(np.fft.rfft((d2 - d2.mean(axis=0)) * w, axis=0)) ** 2
        psd = 2.0 * dt * spec.sum(axis=1) / np.sum(w ** 2)
        acc += np.interp(f, np.fft.rfftfreq(m, dt), psd) * m
        wsum += m
    return acc / wsum, f, float(n)


def choose_cutoff(position, quaternion, dt: float, segments, s_pos: float,
                  s_rot: float | None, order: int = 2, budget: float = BUDGET) -> BandwidthChoice:
    """The widest cutoff of :data:`GRID_HZ` whose predicted attenuation is below ``budget``.

    Parameters
    ----------
    position : ndarray (n, 3)
    quaternion : ndarray (n, 4) or None
        Unit quaternions (sign flips allowed); None or ``s_rot`` None: translation only.
    dt : float
        Sampling period, s.
    segments : sequence of (int, int)
        Gap-free segments (each differenced on its own).
    s_pos, s_rot : float
        White-noise std of each position axis (m) and orientation axis (rad).
    order : int
        Butterworth order of the zero-phase filter (filtfilt doubles it).
    budget : float
        Largest accepted noise-over-signal power ratio.

    Returns
    -------
    BandwidthChoice
    """
    groups = {"translation": (np.asarray(position, float), float(s_pos))}
    if quaternion is not None and s_rot is not None:
        q = np.asarray(quaternion, float)
        q = q * np.where(np.sum(q * q[0], axis=1) < 0, -1.0, 1.0)[:, None]
        groups["rotation"] = (2.0 * q[:, 1:], float(s_rot))
    ratios = {}
    for name, (x, s) in groups.items():
        psd, f, _ = _spectrum(x, dt, segments)
        D2 = (4.0 * np.sin(np.pi * f * dt) ** 2 / dt ** 2) ** 2
        noise = 2.0 * dt * s ** 2 * D2 * x.shape[1]
        signal = psd - noise
        ratios[name] = []
        for fc in GRID_HZ:
            G = 1.0 / (1.0 + (f / fc) ** (2 * order)) ** 2
            ps = max(float(np.sum(signal * G)), 1e-300)
            ratios[name].append(float(np.sum(noise * G)) / ps)
    ok = [i for i in range(len(GRID_HZ)) if all(r[i] <= budget for r in ratios.values())]
    i = max(ok) if ok else 0
    at = {k: v[i] for k, v in ratios.items()}
    if i == len(GRID_HZ) - 1:
        limited = "noise-free" if all(v <= budget for v in at.values()) else "cap"
    else:
        limited = max(groups, key=lambda k: ratios[k][i + 1] if i + 1 < len(GRID_HZ) else 0.0)
    return BandwidthChoice(GRID_HZ[i], at, limited, bool(ok))
