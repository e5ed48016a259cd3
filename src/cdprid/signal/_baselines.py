"""Baseline differentiators: central differences, Butterworth zero-phase and causal
filters, Savitzky-Golay."""

from __future__ import annotations

import math

import numpy as np

from cdprid.base import InputError
from cdprid.signal import _sihd_high as _sihd_high
from cdprid.signal._filters import butter_sos, sosfilt, sosfilt_zi, sosfiltfilt


def _butter(order, cutoff_hz, dt):
    """Second-order sections of the Butterworth low-pass (:func:`cdprid.signal.butter_sos`)."""
    fs = 1.0 / dt
    if not 0.0 < cutoff_hz < 0.5 * fs:
        raise InputError(
            f"cutoff_hz must lie in (0, Nyquist = {0.5 * fs:g} Hz), got {cutoff_hz!r}."
        )
    return butter_sos(int(order), cutoff_hz, fs)


def zero_phase_filter(x, dt, cutoff_hz=4.0, order=2):
    """Zero-phase low-pass Butterworth filter used by ``euler-filtfilt``.

    The identification pipeline applies this same filter to the cable wrench
    (matched filtering), so that positions and forces share the same
    (zero) phase and magnitude distortion.

    Parameters
    ----------
    x : array_like, shape (n,) or (n, k)
        Time-first signal.
    dt : float
        Sampling period in seconds.
    cutoff_hz : float, optional
        -3 dB cutoff of the single-pass filter (default 4 Hz, seed paper).
    order : int, optional
        Order of the Butterworth design (default 2); ``filtfilt`` applies it
        forward and backward, so the magnitude response is squared
        (effective order ``2 * order``) and the phase is zero.

    Returns
    -------
    numpy.ndarray
        Filtered float64 signal, same shape as ``x``.

    Notes
    -----
    The signal is extended at both ends by odd reflection over
    ``min(n - 1, ceil(5 / (cutoff_hz * dt)))`` samples (scipy's default of
    ``3 * (order + 1)`` samples leaves a visible start-up transient), so
    straight lines are reproduced exactly; curvature near the two ends is
    distorted over roughly ``1 / cutoff_hz`` seconds.
    """
    x = np.asarray(x, dtype=np.float64)
    sos = _butter(order, cutoff_hz, float(dt))
    # odd (point-symmetric) extension long enough (5 / cutoff seconds) for the
    # start-up transient to die out inside the padding: straight lines pass
    # exactly, end effects stay confined to about 1/cutoff seconds
    padlen = min(x.shape[0] - 1, int(math.ceil(5.0 / (cutoff_hz * float(dt)))))
    return sosfiltfilt(sos, x, padlen)


def _central(x, dt):
    """Central first and second differences, same length (2nd order one-sided ends)."""
    d1 = np.gradient(x, dt, axis=0, edge_order=2)
    d2 = np.empty_like(x)
    d2[1:-1] = (x[2:] - 2.0 * x[1:-1] + x[:-2]) / dt**2
    d2[0] = d2[1]
    d2[-1] = d2[-2]
    return d1, d2


def _euler_filtfilt(y, dt, cutoff_hz, order):
    return _central(zero_phase_filter(y, dt, cutoff_hz, order), dt)


def _euler_butter_causal(y, dt, cutoff_hz, order):
    sos = _butter(order, cutoff_hz, dt)
    xf = sosfilt(sos, y, sosfilt_zi(sos)[:, :, None] * y[0][None, None, :])
    d1 = np.zeros_like(xf)
    d2 = np.zeros_like(xf)
    d1[1:] = (xf[1:] - xf[:-1]) / dt
    d2[2:] = (xf[2:] - 2.0 * xf[1:-1] + xf[:-2]) / dt**2
    return d1, d2


def _savgol(y, dt, window_s, polyorder):
    n = y.shape[0]
    w = int(round(window_s / dt))
    w += 1 - w % 2  # odd
    polyorder = int(polyorder)
    if w <= polyorder or polyorder < 2:
        raise InputError(
            f"savgol needs polyorder >= 2 and an odd window of more than polyorder samples "
            f"(window_s={window_s!r} -> {w} samples, polyorder={polyorder!r})."
        )
    if w > n:
        raise InputError(f"savgol window ({w} samples) is longer than the signal ({n} samples).")
    from scipy.signal import savgol_filter  # lazy: scipy.signal costs ~1 s of start-up

    kw = dict(window_length=w, polyorder=polyorder, delta=dt, axis=0, mode="interp")
    return savgol_filter(y, deriv=1, **kw), savgol_filter(y, deriv=2, **kw)
