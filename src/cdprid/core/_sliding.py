"""The sliding speed of the cables over their pulleys and its expected sign (pulley friction).

A Coulomb friction force follows the sign of the sliding speed ``dl/dt``; the diagnosis'
friction effects (:data:`cdprid.effects.DIAGNOSIS`) read :func:`sliding_sign`. The rate is a
Gaussian-derivative estimate (:func:`gauss_derivative`: no overshoot, so a reversal of the
true rate is not doubled by ringing), its noise from the lengths' white-noise level
(:func:`cdprid.core.estimate_noise`, third differences).
"""

from __future__ import annotations

import math

import numpy as np

from cdprid.base import InputError
from cdprid.core._noise import estimate_noise

__all__ = ["SLIDE_NOISE_M_S", "expected_sign", "gauss_derivative", "sliding_sign"]

#: floor of the sliding-speed std, m/s (motion capture better than this is not trusted)
SLIDE_NOISE_M_S = 1e-3


def gauss_derivative(x, dt: float, sigma_s: float):
    """Derivative of ``x`` (n, k) by a sampled Gaussian-derivative kernel, and the kernel.

    The kernel has no overshoot (unlike a Butterworth), so a sign change of the true rate is
    not doubled by ringing; it is exact on linear signals (normalised so), and the ends are
    extended by odd reflection.

    Parameters
    ----------
    x : ndarray (n, k)
        Sampled signals, one per column.
    dt : float
        Sampling period, s.
    sigma_s : float
        Standard deviation of the Gaussian, s (the kernel spans +-4 sigma).

    Returns
    -------
    dx : ndarray (n, k)
        Rates, units of ``x`` per s.
    h : ndarray (2 half + 1,)
        The kernel (``dx = x * h``, per s).

    Raises
    ------
    InputError
        Fewer samples than the kernel's half-width.
    """
    half = max(1, int(math.ceil(4.0 * sigma_s / dt)))
    tk = np.arange(-half, half + 1) * dt
    g = np.exp(-0.5 * (tk / sigma_s) ** 2)
    h = -tk * g
    h /= np.sum(-h * tk)  # sum_k h_k (t - t_k) = 1: exact on x = t
    n = x.shape[0]
    if n <= half:
        raise InputError(f"the recording holds {n} pose samples; too few to differentiate.")
    xp = np.pad(x, ((half, half), (0, 0)), mode="reflect", reflect_type="odd")
    out = np.stack([np.convolve(xp[:, j], h, mode="valid") for j in range(x.shape[1])], 1)
    return out, h


_erf = np.vectorize(math.erf, otypes=[float])


def expected_sign(v, std) -> np.ndarray:
    """``E[sign(v_true)]`` given an estimate ``v`` with Gaussian noise of std ``std`` (flat
    prior): ``erf(v / (sqrt(2) std))``, ``sign(v)`` where ``std`` is 0. Where the estimate
    hovers about zero (a cable that nearly stops, a reversal) the sign is not known, and a hard
    sign would put a full friction step where there is none. The one implementation of the
    sliding sign's expectation (the diagnosis, the episodes' null model and the drives' fit).

    Parameters
    ----------
    v : array_like
        The estimate (a speed), any shape.
    std : float or array_like
        Its noise std, broadcast against ``v`` (per column: shape ``(m,)`` for ``v`` (n, m)).

    Returns
    -------
    ndarray
        In [-1, 1], the shape of ``v``.
    """
    v = np.asarray(v, float)
    s = np.broadcast_to(np.asarray(std, float), v.shape)
    out = np.array(np.sign(v), float)  # an array also for a 0-d v
    known = s > 0
    # the standard library's erf (no scipy.special on identify's path: ~0.1 s of its start)
    out[known] = _erf(v[known] / (math.sqrt(2.0) * s[known]))
    return out


def sliding_sign(lengths, dt: float, cutoff_hz: float):
    """The expected sign of each cable's sliding speed over its pulley, given the data.

    The rate of the nominal cable lengths ``lengths`` (n, m) by a Gaussian derivative whose
    -3 dB frequency is ``cutoff_hz``; its noise std per cable is the lengths' white-noise
    level (:func:`cdprid.core.estimate_noise` of order 3, robust) times the kernel's norm, at
    least :data:`SLIDE_NOISE_M_S`. The Coulomb regressor is ``E[sign(dl/dt) | estimate] =
    erf(speed / (sqrt(2) std))``: near reversals, where the estimated sign is a coin toss,
    it goes to 0. The sign of the estimate itself would attenuate a fitted Coulomb level (an
    errors-in-variables bias), and a sign set to 0 in a dead zone inflates it once the
    regression is filtered; the conditional expectation leaves a residual uncorrelated with
    the regressor (``tests/core/test_sliding.py`` measures the three).

    Parameters
    ----------
    lengths : ndarray (n, m)
        Nominal cable lengths at the pose samples, m.
    dt : float
        Sampling period, s.
    cutoff_hz : float
        -3 dB frequency of the rate estimate, Hz.

    Returns
    -------
    sign : ndarray (n, m)
        In [-1, 1].
    speed : ndarray (n, m)
        The sliding speed, m/s.
    std : ndarray (m,)
        Its noise std, m/s.
    """
    lengths = np.asarray(lengths, float)
    sigma_s = math.sqrt(math.log(2.0)) / (2.0 * math.pi * cutoff_hz)
    speed, h = gauss_derivative(lengths, dt, sigma_s)
    noise = estimate_noise(lengths, order=3)
    std = np.maximum(noise * math.sqrt(float(np.sum(h**2))), SLIDE_NOISE_M_S)
    return expected_sign(speed, std), speed, std
