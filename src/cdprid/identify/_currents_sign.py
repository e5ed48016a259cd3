"""The Coulomb friction's sign for ``identify --source currents``: the winch velocity on the
encoders' own clock and the samples where the sign is unknown
(:mod:`cdprid.identify._currents`)."""

from __future__ import annotations

import numpy as np

from cdprid.core import estimate_noise, expected_sign
from cdprid.signal import zero_phase_filter

__all__ = ["SIGN_CUTOFF_HZ", "STILL_S"]

SIGN_CUTOFF_HZ = 10.0
"""Low-pass (Hz) of the encoder velocity that gives the Coulomb friction's sign."""
STILL_S = 0.05
"""A winch in the zero-velocity zone longer than this (s) is at rest: friction undefined."""


def _fast_rate(t_src, l_src, t, seed: int = 2):
    """The winches' velocity for the Coulomb sign (n, m): the lengths on their own clock
    through a zero-phase low-pass at ``SIGN_CUTOFF_HZ`` (or 0.2 of their rate), central
    differences, interpolated onto ``t``; and its noise std per cable (m/s), the encoder noise
    passed through the same chain. The accelerations' filter is too narrow for this: it moves
    the zero crossings, and the current jumps by ``f_c / k`` exactly there."""
    dt = float(np.median(np.diff(t_src)))
    fc = min(SIGN_CUTOFF_HZ, 0.2 / dt)
    v = np.gradient(zero_phase_filter(l_src, dt, fc), dt, axis=0)
    out = np.column_stack([np.interp(t, t_src, v[:, c]) for c in range(v.shape[1])])
    x = np.random.default_rng(seed).normal(size=(4000, 1))
    gain = float(np.std(np.gradient(zero_phase_filter(x, dt, fc), dt, axis=0)[400:-400]))
    return out, estimate_noise(np.asarray(l_src, float)) * gain


def _friction_sign(v_fast, s_v, params: dict, dt: float):
    """``sign(l')`` for the Coulomb column and the samples to leave out.

    The column takes the expected sign under the velocity's noise, ``erf(l' / (sqrt(2)
    s_v))`` (the sign itself on exact data): where the velocity is within its noise of zero
    the true sign is a guess, and a guess of zero mean spreads no bias through the filter.
    Samples with ``|l'| < 3 s_v`` on some winch are left out. Where a winch stays below
    ``v_z = max(0.5 mm/s, 3 s_v)`` longer than ``STILL_S`` (at rest, or turning slowly) its
    friction is anywhere within +-f_c (stiction): the matched filter's reach around it (half
    a period of its cutoff) is left out too."""
    s_v = np.maximum(np.asarray(s_v, float), 1e-9)
    sign = _expected_sign(v_fast, s_v)
    zone = np.abs(v_fast) < 3.0 * s_v
    v_z = np.maximum(5e-4, 3.0 * s_v)
    w = int(np.ceil(0.5 / (float(params.get("cutoff_hz", 4.0)) * dt)))
    n_still = max(1, int(round(STILL_S / dt)))
    long = np.zeros(len(v_fast), bool)
    for z in (np.abs(v_fast) < v_z).T:
        long |= np.convolve(z.astype(float), np.ones(n_still), mode="same") >= n_still - 0.5
    long = np.convolve(long.astype(float), np.ones(2 * w + 1), mode="same") > 0
    return sign, np.any(zone, axis=1) | long, float(np.max(v_z))


def _expected_sign(v, s_v):
    """``E[sign(v_true)]`` for a velocity estimate ``v`` of noise std ``s_v`` (at least
    1e-9 m/s): :func:`cdprid.core.expected_sign`."""
    return expected_sign(v, np.maximum(np.asarray(s_v, float), 1e-9))
