"""Sensors of the test simulator: the load cells and their clock, the motion capture.

Where the load cell sits decides the sign of pulley friction. A cell on the winch side reads
the tension between the winch and the pulley, tau_w. Over the pulley the (massless) cable
is in balance: the platform side pulls with tau_p towards the platform, the winch side with
tau_w towards the winch, and friction F opposes the cable's sliding: paying out (the length
l from the pulley entry to the platform grows, dl/dt > 0) it acts towards the winch, so
``tau_p = tau_w + F`` and the cell reads ``tau_p - F`` with ``F = coulomb sign(dl/dt) +
viscous dl/dt``. A cell at the platform reads tau_p: no friction in the reading.
"""

from __future__ import annotations

import dataclasses

import numpy as np


def play(x, width):
    """Play (backlash) operator along time, as a plain loop: ``y_0 = x_0 - w/2``,
    ``y_k = y_{k-1}`` while ``|x_k - y_{k-1}| <= w/2``, else the band's edge follows x.

    Parameters
    ----------
    x : (k,) or (k, m) force, N
    width : float or (m,) N
    """
    x = np.asarray(x, float)
    x2 = x.reshape(len(x), -1)
    half = 0.5 * np.broadcast_to(np.asarray(width, float), (x2.shape[1],))
    y = np.empty_like(x2)
    y[0] = x2[0] - half
    for j in range(1, len(x2)):
        prev = y[j - 1]
        up = x2[j] - prev > half
        down = prev - x2[j] > half
        y[j] = np.where(up, x2[j] - half, np.where(down, x2[j] + half, prev))
    return y.reshape(x.shape)


def ar1_noise(rng, n: int, m: int, white_N: float, ar_N: float, rho: float):
    """White noise of std ``white_N`` plus a stationary AR(1) of std ``ar_N`` and pole rho."""
    e = rng.normal(size=(n, m))
    ar = np.empty((n, m))
    ar[0] = ar_N * rng.normal(size=m)
    innov = ar_N * np.sqrt(1.0 - rho * rho) * e
    for j in range(1, n):
        ar[j] = rho * ar[j - 1] + innov[j]
    return white_N * rng.normal(size=(n, m)) + ar


@dataclasses.dataclass(frozen=True)
class Sensors:
    """What the sensors of one recording do (the truth; every field is written to meta.toml).

    Attributes
    ----------
    tension_rate_hz : float
        Load-cell sampling rate on the cells' own clock.
    clock_offset_s : float
        The tension sample stamped t holds the force of (pose-clock) time ``t - offset``.
    clock_phase_s : float
        First tension time stamp (the two clocks are not sampled together).
    pose_rate_hz : float
    white_N, ar_N, ar_rho : float
        Tension noise: white std, AR(1) std and pole per sample.
    offset_N, gain : (m,) per-cell zero offset and gain (reading = gain * cell force + offset)
    coulomb_N, viscous_Ns_per_m : (m,) pulley friction
    cell_at_winch : bool
        The cells sit on the winch side of the pulleys (friction in the reading).
    hysteresis_N : (m,) play width of each cell, N (0: none)
    position_m, orientation_rad : float
        Motion-capture noise (std per axis).
    """

    tension_rate_hz: float
    clock_offset_s: float
    clock_phase_s: float
    pose_rate_hz: float
    white_N: float
    ar_N: float
    ar_rho: float
    offset_N: tuple
    gain: tuple
    coulomb_N: tuple
    viscous_Ns_per_m: tuple
    cell_at_winch: bool
    hysteresis_N: tuple
    position_m: float
    orientation_rad: float


def cell_reading(s: Sensors, tau_platform, ldot, rng, noise: bool = True):
    """What the load cells report ``(k, m)`` from the platform-side tensions and the
    cables' sliding speeds ``dl/dt`` at the tension samples."""
    x = np.array(tau_platform, float)
    if s.cell_at_winch:
        x = x - np.asarray(s.coulomb_N) * np.sign(ldot) - np.asarray(s.viscous_Ns_per_m) * ldot
    x = play(x, np.asarray(s.hysteresis_N))
    y = np.asarray(s.gain) * x + np.asarray(s.offset_N)
    if noise:
        y = y + ar1_noise(rng, y.shape[0], y.shape[1], s.white_N, s.ar_N, s.ar_rho)
    return y


def rotvec_quat(r):
    """Unit quaternions (n, 4) of rotation vectors (n, 3)."""
    ang = np.linalg.norm(r, axis=1)
    half = 0.5 * ang
    scale = np.where(ang > 1e-12, np.sin(half) / np.where(ang > 1e-12, ang, 1.0), 0.5)
    return np.column_stack([np.cos(half), r * scale[:, None]])


def mocap(s: Sensors, p, q, rng, noise: bool = True):
    """Motion-capture positions and quaternions (noise: a small random rotation applied)."""
    if not noise:
        return p.copy(), q.copy()
    from tests._testbench._motion import _qmul

    dq = rotvec_quat(s.orientation_rad * rng.normal(size=(len(q), 3)))
    qn = np.array([_qmul(a, b) for a, b in zip(dq, q, strict=True)])
    qn *= np.sign(qn[:, :1] + (qn[:, :1] == 0))
    return p + s.position_m * rng.normal(size=p.shape), qn
