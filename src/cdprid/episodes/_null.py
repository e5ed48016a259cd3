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
``h_j`` the direction of the reading's motion (told from its noise by a play operator,
:func:`motion`) gives them (:func:`persistent_null`). Fitted once for
the whole recording, these columns take the reversals of the cables' velocities and tension
rates, where a rigid body alone leaves a step at every reversal; a push is local in time and
not aligned with the reversals, and stays in the residual.

Two more terms a real recording needs (the UACDPR's cells): a relative gain per cell (a cell
reading ``g_j tau_j``: ``(g_j - 1) W_j tau~_j`` to first order; the gains' common part is the
rigid body's scale, so ``m - 1`` columns ``W_j tau~_j - W_m tau~_m``; with all m the columns
would sum to the measured wrench and explain anything) and a zero that drifts slowly (strain
gauges creep and warm): per cell ``W_j P_k(t)``, Legendre polynomials of degree 1..K over the
recording, its shortest time scale :data:`ZERO_DRIFT_S`, three times the longest push the
scan is for, so a push stays in the residual. The winches' own work is not among them.

The friction column takes the expected sign of the sliding (:func:`cdprid.core.expected_sign`: the
estimated speed's noise makes the sign uncertain near a stop), and the reading's motion is
told from its noise by a play operator whose width follows from :data:`REVERSAL_P`
(:func:`motion`), never from a tuned rate floor.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.polynomial import legendre

from cdprid.core import expected_sign
from cdprid.effects import play_operator

__all__ = ["REVERSAL_P", "ZERO_DRIFT_S", "Cells", "cells", "with_noise", "reversal_half_width",
           "motion", "drift_basis", "n_columns", "columns", "fixed_columns", "cell_error",
           "band_positions",
           "persistent_null"]


@dataclasses.dataclass(frozen=True)
class Cells:
    """What the columns are made of, per pose sample and cable.

    Attributes
    ----------
    W : ndarray (n, 6, m)
        Wrench matrices (unfiltered).
    sliding : ndarray (n, m)
        ``sign(dl_j/dt)``: +1 paying out, -1 reeling in, its expected value where the
        estimate's noise leaves it uncertain (:func:`cdprid.core.expected_sign`).
    reading : ndarray (n, m)
        The cells' readings through the matched filter, N.
    rate : ndarray (n, m)
        Their rates, N/s.
    moving : ndarray (n, m) of bool
        Where a reading moves by more than its noise can (:func:`motion`; elsewhere a
        hysteretic cell may hold its reading while the force crosses its band).
    direction : ndarray (n, m)
        The sign of that motion, 0 where still.
    noise : ndarray (m,)
        The std of each filtered reading's noise the motion was told from, N.
    tension : ndarray (n, m)
        The cells' raw readings, N (the gain columns).
    drift : ndarray (n, K)
        The zero's drift basis in time (:func:`drift_basis`; K may be 0).
    segments : tuple of (int, int)
    filt : callable
        The matched filter, segment by segment.
    """

    W: np.ndarray
    sliding: np.ndarray
    reading: np.ndarray
    rate: np.ndarray
    moving: np.ndarray
    direction: np.ndarray
    noise: np.ndarray
    tension: np.ndarray
    drift: np.ndarray
    segments: tuple
    filt: object


#: the zeros' drift is resolved to this time scale or longer, s (:func:`drift_basis`): three
#: times the longest push the scan is for (3 s) and its longest window (3.2 s)
ZERO_DRIFT_S = 10.0

#: probability that the filtered noise alone, between two independent samples, moves a still
#: reading far enough to be taken for a reversal (:func:`reversal_half_width`)
REVERSAL_P = 1e-3


def reversal_half_width(noise_N) -> np.ndarray:
    """Half-width (N) of the play operator that tells a reading's motion from its noise
    (:func:`motion`): a standing reading is taken for moving only when the filtered noise
    changes by the full width ``2 delta`` between two samples; for two independent samples
    of std ``sigma_f`` the change has std ``sqrt(2) sigma_f``, so
    ``delta = Phi^-1(1 - p / 2) sigma_f / sqrt(2)`` with ``p`` = :data:`REVERSAL_P`
    (about 2.3 sigma_f). Correlated samples change less: the rate is lower still.

    Parameters
    ----------
    noise_N : float or ndarray (m,)
        Std of each cell's filtered reading noise, N.

    Returns
    -------
    ndarray (m,) or float, N
    """
    from cdprid.base import normal_isf

    return normal_isf(0.5 * REVERSAL_P) / np.sqrt(2.0) * np.asarray(noise_N, float)


def motion(xf: np.ndarray, half_N, segments):
    """Where each filtered reading moves, and its direction, told from its noise by a play
    operator (a Schmitt trigger) of half-width ``half_N``: its output follows the reading
    only once the reading has left the band ``+-half_N`` about it, so a reading that turns
    counts as moving again only after it has moved ``2 half_N`` from its turning point;
    noise smaller than that never makes a still reading (a hysteretic cell holding its value
    while the force crosses its band) look like a reversal.

    Parameters
    ----------
    xf : ndarray (n, m)
        Filtered readings, N.
    half_N : ndarray (m,)
        :func:`reversal_half_width`, N.
    segments : sequence of (int, int)

    Returns
    -------
    moving : ndarray (n, m) of bool
        The operator's output changes at this sample.
    direction : ndarray (n, m)
        The sign of that change (0 where still).
    """
    direction = np.zeros_like(xf)
    for a, b in segments:
        if b - a < 2:
            continue
        g = play_operator(xf[a:b], 2.0 * np.asarray(half_N, float))
        d = np.diff(g, axis=0, prepend=g[:1])
        direction[a:b] = np.sign(np.where(np.abs(d) > 1e-12, d, 0.0))
    return direction != 0, direction


def cells(W, twist, tension, dt: float, segments, filt, t=None, speed_noise=0.0) -> Cells:
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
    t : ndarray (n,), optional
        Sample times, s: the zeros' drift (:func:`drift_basis`); None: no drift columns.
    speed_noise : float
        Std of the estimated sliding speeds' noise, m/s (:func:`cdprid.core.expected_sign`).

    Returns
    -------
    Cells
    """
    W = np.asarray(W, float)
    ldot = -np.einsum("nim,ni->nm", W, np.asarray(twist, float))
    x = np.asarray(tension, float)
    xf = np.asarray(filt(x), float)
    rate = np.zeros_like(xf)
    for a, b in segments:
        if b - a >= 3:
            rate[a:b] = np.gradient(xf[a:b], dt, axis=0)
    d = x - xf  # first guess of the noise: what the filter takes away (robust std)
    sigma = 1.4826 * np.median(np.abs(d - np.median(d, 0)), 0)
    c = Cells(W, expected_sign(ldot, speed_noise), xf, rate,
              np.zeros(xf.shape, bool), np.zeros_like(xf), sigma, x,
              drift_basis(t) if t is not None else np.zeros((len(x), 0)), tuple(segments),
              filt)
    return with_noise(c, sigma)


def speed_noise(position, dt: float, cutoff_hz: float) -> float:
    """Std (m/s) of a sliding speed's noise from white marker noise: the positions' noise
    (the robust std of what the zero-phase filter at ``cutoff_hz`` takes away, per axis,
    their mean square) times the white-noise gain of the filtered difference quotient
    (``sqrt(sum h'^2)``, ``h`` the filter's impulse response). The orientation's part
    (marker noise over the platform's size times the attachment's lever) is left out."""
    from cdprid.signal import zero_phase_filter

    x = np.asarray(position, float)
    if len(x) < 16:
        return 0.0
    d = x - np.asarray(zero_phase_filter(x, dt, cutoff_hz, 2))
    sig = 1.4826 * np.median(np.abs(d - np.median(d, 0)), 0)
    n = 2 * int(math.ceil(8.0 / (cutoff_hz * dt))) + 1
    imp = np.zeros(n)
    imp[n // 2] = 1.0
    h = np.gradient(np.asarray(zero_phase_filter(imp, dt, cutoff_hz, 2)), dt)
    return float(np.sqrt(np.mean(sig ** 2)) * np.sqrt(np.sum(h ** 2)))


def with_noise(c: Cells, noise_N) -> Cells:
    """``c`` with its motion told from noise of std ``noise_N`` (N, per cell or one for
    all; :func:`motion`)."""
    noise = np.broadcast_to(np.maximum(np.asarray(noise_N, float), 1e-9),
                            (c.reading.shape[1],)).copy()
    moving, direction = motion(c.reading, reversal_half_width(noise), c.segments)
    return dataclasses.replace(c, moving=moving, direction=direction, noise=noise)


def residual_noise(r: np.ndarray, m: int) -> float:
    """The std (N) of one filtered reading's noise from a fit's force residual ``r`` (n, 3):
    with independent cells of equal noise ``sigma_f`` along unit directions ``u_j``, the
    residual's covariance is ``sigma_f^2 sum_j u_j u_j^T``, whose trace is ``m sigma_f^2``
    (robust variances, MAD). What the model misses counts as noise here: the estimate errs
    high, which makes still stretches longer, never a reversal out of noise."""
    r = np.asarray(r, float)
    mad = 1.4826 * np.median(np.abs(r - np.median(r, 0)), 0)
    return float(np.sqrt(np.sum(mad ** 2) / m))


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


def drift_basis(t) -> np.ndarray:
    """The zeros' drift in time: Legendre polynomials of degree 1..K over the recording
    (the constant is the offset column), ``K = ceil(duration / ZERO_DRIFT_S)``, so that the
    drift's shortest time scale (the spacing of the highest one's zeros, about
    duration / K) is :data:`ZERO_DRIFT_S` or more.

    Parameters
    ----------
    t : ndarray (n,)
        Sample times, s.

    Returns
    -------
    ndarray (n, K), dimensionless (within [-1, 1])
    """
    t = np.asarray(t, float)
    span = float(t[-1] - t[0]) if t.size > 1 else 0.0
    K = int(math.ceil(span / ZERO_DRIFT_S)) if span > 0 else 0
    if K == 0:
        return np.zeros((t.size, 0))
    x = 2.0 * (t - t[0]) / span - 1.0
    return np.stack([legendre.legval(x, np.eye(K + 1)[k]) for k in range(1, K + 1)], axis=1)


def n_columns(c: Cells) -> int:
    """How many columns :func:`columns` gives: ``3 m + 1 + (m - 1) + m K``."""
    m = c.W.shape[2]
    return 3 * m + 1 + (m - 1) + m * c.drift.shape[1]


def columns(c: Cells, band=None, fixed=None) -> np.ndarray:
    """The columns (n, 6, :func:`n_columns`), through the matched filter: ``W_j`` (per N of
    offset), ``W_j sign(dl_j/dt)`` (per N of friction), ``W_j h_j`` (per N of half-width),
    ``sum_j W_j dtau_j/dt`` (per s of clock offset), the relative gains
    ``W_j tau~_j - W_m tau~_m`` (j < m; per unit of gain, the gains' sum fixed: a common
    gain is the rigid body's scale) and the zeros' drift ``W_j P_k(t)`` (per N; cable by
    cable, :func:`drift_basis`). ``h_j`` is ``band`` (n, m) when given
    (:func:`band_positions`), else the direction of the reading's motion (:func:`motion`),
    interpolated across the stretches where the reading stands still. ``fixed``: the
    columns that do not depend on ``h`` (:func:`fixed_columns` of the same cells), filtered
    once for several calls (the filter acts on each column alone: the same numbers)."""
    if band is None:
        band = _per_segment(across_still, c, c.direction, c.moving)
    m = c.W.shape[2]
    if fixed is None:
        fixed = fixed_columns(c)
    hyst = np.asarray(c.filt(c.W * np.asarray(band)[:, None, :]), float)
    return np.concatenate([fixed[:, :, :2 * m], hyst, fixed[:, :, 2 * m:]], axis=2)


def fixed_columns(c: Cells) -> np.ndarray:
    """The columns of :func:`columns` that do not depend on the band positions, through the
    matched filter (n, 6, :func:`n_columns` - m): ``W_j``, ``W_j sign(dl_j/dt)``, the clock,
    the relative gains and the drift, in that order. They depend on the cells' wrench
    matrices, sliding signs, rates, readings and drift basis only (not on ``moving`` or
    ``direction``: :func:`with_noise` keeps them)."""
    W = c.W
    n, k, m = W.shape
    Wt = W * c.tension[:, None, :]
    drift = (W[:, :, :, None] * c.drift[:, None, None, :]).reshape(n, k, -1)
    cols = np.concatenate([W, W * c.sliding[:, None, :],
                           np.einsum("nim,nm->ni", W, c.rate)[:, :, None],
                           Wt[:, :, :-1] - Wt[:, :, -1:], drift], axis=2)
    return np.asarray(c.filt(cols), float)


def cell_error(c: Cells, coef, band=None) -> np.ndarray:
    """Each cell's reading error (n, m), N, through the matched filter, from the columns'
    coefficients ``coef`` (:func:`columns`' order; the clock left out): offset, friction,
    hysteresis (``band`` or the rough position), gain and drift."""
    m, K = c.W.shape[2], c.drift.shape[1]
    coef = np.asarray(coef, float)
    if band is None:
        band = _per_segment(across_still, c, c.direction, c.moving)
    gain = np.append(coef[3 * m + 1:4 * m], -np.sum(coef[3 * m + 1:4 * m]))
    drift = coef[4 * m:4 * m + m * K].reshape(m, K)
    raw = (coef[:m] + coef[m:2 * m] * c.sliding + coef[2 * m:3 * m] * band
           + gain * c.tension + c.drift @ drift.T)
    return np.asarray(c.filt(raw), float)


def band_positions(c: Cells, coef, residual, rows, quiet=None, Wf=None) -> np.ndarray:
    """Where each cell's force sits in its hysteresis band, +1 (rising) to -1 (falling), from a
    fit's coefficients of the columns (``coef``, :func:`columns`' order; per cable an offset,
    ``friction`` = minus the Coulomb force and ``half`` = minus the half-width, N, ...;
    :func:`cell_error`, with ``h`` the rough band position) and its ``residual`` (n, k).

    The platform-side tension is the reading less that error, corrected by the wrench balance:
    with every other cell read right, the residual is ``W_j`` times cable j's error, so
    ``tau_j = y_j - err_j - W_j . r / |W_j|^2`` (least squares over the wrench rows in use;
    cable j's own noise cancels, the others' stays). No sample of the cell's own reading is
    trusted to tell whether the cell holds or follows its force: a hysteretic cell holds while
    the force crosses its band, which its noisy reading cannot show. The cell's input
    ``x = tau + friction s`` (the friction's step at a reversal of the sliding is in it) goes
    through a play operator of the fitted width, and the band position is
    ``(x - H[x]) / half-width``: +1 on a rising branch, -1 on a falling one, in between
    while the force crosses the band (also when a friction step smaller than the band is
    swallowed). Cables whose ``half`` is not negative keep the rough position.

    ``quiet`` (n,) marks samples whose residual is not the cells' error (a push, a pose
    glitch's transient): there the balance would move every cell's tension by the push's
    share (its force is real, the cells read it right) and put false reversals into the
    play operator, whose state then stays wrong until the next full reversal; the
    correction is left out there (the reading less its error). ``Wf``: the wrench matrices
    through the matched filter, when already at hand (n, 6, m)."""
    m = c.W.shape[2]
    coef = np.asarray(coef, float)
    friction, half = coef[m:2 * m], coef[2 * m:3 * m]
    rough = _per_segment(across_still, c, c.direction, c.moving)
    Wf = (np.asarray(c.filt(c.W), float) if Wf is None else np.asarray(Wf))[:, rows]
    residual = np.asarray(residual, float)
    if quiet is not None:
        residual = np.where(np.asarray(quiet, bool)[:, None], 0.0, residual)
    share = np.einsum("nim,ni->nm", Wf, residual) / np.maximum(
        np.einsum("nim,nim->nm", Wf, Wf), 1e-300)
    x = c.reading - cell_error(c, coef, rough) - share + friction * c.sliding
    hw = np.maximum(-half, 1e-9)
    band = np.zeros_like(x)
    for a, b in c.segments:
        band[a:b] = (x[a:b] - play_operator(x[a:b], 2.0 * hw)) / hw
    return np.where(half < 0, band, rough)


def persistent_null(A, c: Cells, rows, fit, quiet=None) -> np.ndarray:
    """The scan's regressor: the rigid body ``A`` (n, k, p) and the columns, the hysteresis
    columns from the band positions of a fit (``fit(Z) -> (residual (n, k), coefficients)``,
    on the recording's used samples). ``rows`` selects the wrench rows in use (k of 6);
    ``quiet`` (n,) the samples whose residual is an episode's, not the cells'
    (:func:`band_positions`).

    A first fit, with the cells' motion told from their fast noise (:func:`cells`), gives
    the force residual and from it the filtered readings' noise (:func:`residual_noise`);
    the motion told from that, a second fit gives the widths for :func:`band_positions`."""
    m, p = c.W.shape[2], A.shape[2]
    fixed = fixed_columns(c)  # with_noise below keeps what these are made of
    r, _ = fit(np.concatenate([A, columns(c, fixed=fixed)[:, rows]], axis=2))
    c = with_noise(c, residual_noise(r[:, :int(np.sum(np.asarray(rows)[:3]))], m))
    r, beta = fit(np.concatenate([A, columns(c, fixed=fixed)[:, rows]], axis=2))
    band = band_positions(c, beta[p:], r, rows, quiet, Wf=fixed[:, :, :m])
    return np.concatenate([A, columns(c, band, fixed)[:, rows]], axis=2)
