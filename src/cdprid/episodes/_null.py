"""The scan's null model beyond the rigid body: the load-cell effects that persist over the
whole recording, as a few columns per cable (never per sample).

Where the sensor sits decides their form. Cable j's cell reads, on the pose clock,

    tau~_j(t) = H_j[tau_j - c_j sign(dl_j/dt)](t - delta) + o_j + noise,

with ``tau_j`` the platform-side tension the rigid body balances (``W tau = A x``),
``l_j`` the cable's length from the pulley to the platform, ``c_j`` the pulley's Coulomb
friction (a cell on the winch side of the pulley reads the platform side's tension minus the
friction that opposes the sliding; on the platform side ``c_j = 0``), ``H_j`` a hysteretic
cell (a play operator of width ``w_j``: on a rising branch it reads ``w_j / 2`` low, on a
falling one ``w_j / 2`` high), ``delta`` the clock offset of the tension stream and ``o_j``
the cell's zero. To first order the measured wrench ``W tau~`` then departs from the rigid
body's by

    sum_j W_j (o_j - c_j sign(dl_j/dt) - (w_j / 2) h_j - delta dtau~_j/dt),

with ``h_j`` where the cell's force sits in its band (+1 on a rising branch, -1 on a falling
one, in between while the force crosses the band after a reversal; :func:`band_positions`),
linear in ``(o_j, c_j, w_j, delta)``: the columns ``W_j``, ``W_j sign(dl_j/dt)``,
``W_j h_j`` per cable and one ``sum_j W_j dtau~_j/dt`` (one clock for every cell), each
through the same zero-phase filter as ``W tau~`` (matched). The cable's sliding speed over
its pulley is minus the platform twist along its column, ``dl_j/dt = -W_j . (v, omega)``
(``W_j = (u_j, b_j x u_j)``, ``u_j`` from the attachment towards the exit point; the
pulley's wrap changes the speed, not its sign). ``h_j`` needs the widths: a first fit with
``h_j`` the sign of the reading's rate gives them (:func:`persistent_null`). Fitted once for
the whole recording, these columns take the reversals of the cables' velocities and tension
rates, where a rigid body alone leaves a step at every reversal; a push is local in time and
not aligned with the reversals, and stays in the residual.

Not among them: a relative gain (``(g_j - 1) W_j tau_j``; the columns ``W_j tau~_j`` sum
to the measured wrench itself, so they would explain anything) and the winches' own work.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.effects import play_operator

__all__ = ["STILL_FRACTION", "Cells", "cells", "columns", "band_positions",
           "persistent_null"]

#: a reading stands still below this share of ``2 pi f_c sigma`` (:func:`still_rate`); chosen
#: by measurement on the floor-winch robot's seeds 0, 2, 4, 8 (``tests._testbench.floor8_case``,
#: hysteretic cells 2-4 N, friction 1-3 N): 1 and 0.5 left 1-3 false episodes on three of them
#: (a reading moving at 7 N/s taken for still, the tension interpolated across it), 0.3 none
STILL_FRACTION = 0.3


@dataclasses.dataclass(frozen=True)
class Cells:
    """What the columns are made of, per pose sample and cable.

    Attributes
    ----------
    W : ndarray (n, 6, m)
        Wrench matrices (unfiltered).
    sliding : ndarray (n, m)
        ``sign(dl_j/dt)``: +1 paying out, -1 reeling in, 0 at rest.
    reading : ndarray (n, m)
        The cells' readings through the matched filter, N.
    rate : ndarray (n, m)
        Their rates, N/s.
    moving : ndarray (n, m) of bool
        Where a reading moves faster than :func:`still_rate` (elsewhere a hysteretic cell
        may hold its reading while the force crosses its band).
    segments : tuple of (int, int)
    filt : callable
        The matched filter, segment by segment.
    """

    W: np.ndarray
    sliding: np.ndarray
    reading: np.ndarray
    rate: np.ndarray
    moving: np.ndarray
    segments: tuple
    filt: object


def still_rate(x: np.ndarray, xf: np.ndarray, cutoff_hz: float) -> np.ndarray:
    """Per cell, the rate (N/s) below which its filtered reading counts as standing still:
    :data:`STILL_FRACTION` of ``2 pi f_c sigma``, the rate of a swing of the reading's fast
    noise (``sigma``, the robust std of ``x - xf``: what the filter takes away) at the cutoff
    ``f_c``; ``2 pi f_c sigma`` is 3 to 7 std of the filtered rate's own noise (7 for white
    noise at 100 Hz, about 3.5 with the floor-winch robot's slow AR(1) part), so the floor is
    about one std of it."""
    d = x - xf
    sigma = 1.4826 * np.median(np.abs(d - np.median(d, 0)), 0)
    return STILL_FRACTION * 2.0 * np.pi * cutoff_hz * np.maximum(sigma, 1e-9)


def cells(W, twist, tension, dt: float, segments, filt, cutoff_hz: float) -> Cells:
    """The :class:`Cells` of a recording.

    Parameters
    ----------
    W : ndarray (n, 6, m)
        Wrench matrices at the pose samples (unfiltered).
    twist : ndarray (n, 6)
        Platform velocity and angular velocity (base frame), m/s and rad/s, as the motion
        estimate gives them (already low-passed).
    tension : ndarray (n, m)
        The cells' readings at the pose samples, N.
    dt : float
        Sampling period, s.
    segments : sequence of (int, int)
        Gap-free index ranges; rates are taken inside each.
    filt : callable
        ``filt(x)`` the zero-phase filter along time of an (n, ...) array, segment by
        segment (the one ``W tau`` goes through).
    cutoff_hz : float
        Its cutoff, Hz.

    Returns
    -------
    Cells
    """
    W = np.asarray(W, float)
    ldot = -np.einsum("nim,ni->nm", W, np.asarray(twist, float))
    floor = 1e-3 * max(float(np.max(np.abs(ldot), initial=0.0)), 1e-12)
    x = np.asarray(tension, float)
    xf = np.asarray(filt(x), float)
    rate = np.zeros_like(xf)
    for a, b in segments:
        if b - a >= 3:
            rate[a:b] = np.gradient(xf[a:b], dt, axis=0)
    return Cells(W, np.where(np.abs(ldot) > floor, np.sign(ldot), 0.0), xf, rate,
                 np.abs(rate) > still_rate(x, xf, cutoff_hz), tuple(segments), filt)


def across_still(x: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """``x`` (n,) where ``moving``, linearly interpolated in time across the other samples
    (constant beyond the first and last moving sample; ``x`` itself when none moves)."""
    idx = np.flatnonzero(moving)
    if idx.size == 0:
        return np.asarray(x, float).copy()
    return np.interp(np.arange(len(x)), idx, np.asarray(x, float)[idx])


def _per_segment(fn, c: Cells, *arrays) -> np.ndarray:
    """``fn(*column slices)`` per segment and cable, into an (n, m) array."""
    out = np.zeros_like(c.reading)
    for a, b in c.segments:
        for j in range(out.shape[1]):
            out[a:b, j] = fn(*(x[a:b, j] for x in arrays))
    return out


def columns(c: Cells, band=None) -> np.ndarray:
    """The columns (n, 6, 3 m + 1), through the matched filter: ``W_j`` (per N of offset),
    ``W_j sign(dl_j/dt)`` (per N of friction), ``W_j h_j`` (per N of half-width) and
    ``sum_j W_j dtau_j/dt`` (per s of clock offset). ``h_j`` is ``band`` (n, m) when given
    (:func:`band_positions`), else the sign of the reading's rate, interpolated across the
    stretches where the reading stands still."""
    if band is None:
        band = _per_segment(across_still, c, np.sign(c.rate), c.moving)
    W = c.W
    cols = np.concatenate([W, W * c.sliding[:, None, :], W * np.asarray(band)[:, None, :],
                           np.einsum("nim,nm->ni", W, c.rate)[:, :, None]], axis=2)
    return np.asarray(c.filt(cols), float)


def band_positions(c: Cells, offset, friction, half) -> np.ndarray:
    """Where each cell's force sits in its hysteresis band, +1 (rising) to -1 (falling), from a
    first fit's coefficients (``offset``, ``friction`` = minus the Coulomb force, ``half`` =
    minus the half-width, N, per cable; the reading's error is ``offset + friction s + half
    h``).

    Where the reading moves, the platform-side tension is the reading less that error
    (``tau = y - offset - friction s - half sign(dy/dt)``); where it stands still the
    tension is interpolated linearly in time (it is smooth: the cell, not the cable, holds
    still). The cell's input ``x = tau + friction s`` (the friction's step at a reversal of
    the sliding is in it) goes through a play operator of the fitted width, and the band
    position is ``(x - H[x]) / half-width``: +1 on a rising branch, -1 on a falling one, in
    between while the force crosses the band (also when a friction step smaller than the
    band is swallowed). Cables whose ``half`` is not negative keep the sign
    of their reading's rate."""
    offset, friction, half = (np.asarray(v, float) for v in (offset, friction, half))
    err = offset + friction * c.sliding + half * np.sign(c.rate)
    tau = _per_segment(across_still, c, c.reading - err, c.moving)
    x = tau + friction * c.sliding
    hw = np.maximum(-half, 1e-9)
    band = np.zeros_like(x)
    for a, b in c.segments:
        band[a:b] = (x[a:b] - play_operator(x[a:b], 2.0 * hw)) / hw
    fallback = _per_segment(across_still, c, np.sign(c.rate), c.moving)
    return np.where(half < 0, band, fallback)


def persistent_null(A, c: Cells, rows, fit) -> np.ndarray:
    """The scan's regressor: the rigid body ``A`` (n, k, p) and the columns, the hysteresis
    columns from the band positions of a first fit (``fit(Z) -> coefficients``, on the
    recording's used samples). ``rows`` selects the wrench rows in use (k of 6)."""
    m, p = c.W.shape[2], A.shape[2]
    Z1 = np.concatenate([A, columns(c)[:, rows]], axis=2)
    beta = fit(Z1)
    band = band_positions(c, beta[p:p + m], beta[p + m:p + 2 * m], beta[p + 2 * m:p + 3 * m])
    return np.concatenate([A, columns(c, band)[:, rows]], axis=2)
