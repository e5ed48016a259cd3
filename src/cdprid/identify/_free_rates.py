"""Accelerations and angular rates for the free motion's rows, accurate to fourth order in the
sampling period (``identify --source free-motion``).

The free-motion rows ``F[N^T S Z] x = 0`` hold exactly at the true rates; any error of the rates
is a force the fit reads as a parameter. The tension path's central differences
(:func:`cdprid.core.reference_rates`: second differences from samples ``k +- 1, k +- 3`` with
error ``(5/6) dt^2 x''''``, first differences with error ``dt^2 x''' / 6``) lose
``(5/6) (2 pi f dt)^2`` of an acceleration at frequency ``f``: 1.3 % of a 2 Hz swing sampled at
100 Hz. With the tensions unknown nothing else carries the scale of the dynamics, and on a
noise-free simulated swing (tests/identify/free_sim.py, 100 Hz) that loss biased every
parameter by 0.4-1 % (z_G -0.9 %), 2 to 50 times its std; at 400 Hz the bias fell 16 times,
as ``dt^2`` says. The stencils here are exact for polynomials up to degree 5:

* second derivative ``sum_j w_j (x[k+j] + x[k-j]) / dt^2`` over ``j = 1, 3, 5`` with
  ``sum w_j = 0``, ``sum w_j j^2 = 1``, ``sum w_j j^4 = 0``; sample ``k`` itself is never used
  (its noise stays uncorrelated with the rotation of the same sample that multiplies the rate,
  as in the core's stencil); error ``sum_j w_j j^6 / 360 dt^4 x^(6) = -0.72 dt^4 x^(6)``
  (a 2 Hz swing at 100 Hz: 1.8e-4 of its acceleration), white-noise gain ``2 sum w_j^2 =
  0.147 / dt^4`` (the core's: 0.0625 / dt^4; the excess lies above the rows' low-pass);
* first derivative ``(x[k-2] - 8 x[k-1] + 8 x[k+1] - x[k+2]) / (12 dt)``, error
  ``-dt^4 x^(5) / 30``.

Segment ends (the first and last 5 samples) take the nearest interior value, as the core does;
they lie within the trimmed edges.
"""

from __future__ import annotations

import numpy as np

from cdprid.core import angular_rates

__all__ = ["SECOND_WEIGHTS", "free_rates", "first_derivative", "second_derivative"]


def _second_weights() -> np.ndarray:
    """The weights ``w_1, w_3, w_5`` of :func:`second_derivative` (see the module docstring)."""
    j = np.array([1.0, 3.0, 5.0])
    return np.linalg.solve(np.stack([j ** 0, j ** 2, j ** 4]), np.array([0.0, 1.0, 0.0]))


#: ``(w_1, w_3, w_5)``: -17/96, 13/64, -5/192
SECOND_WEIGHTS = _second_weights()


def second_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """Second time derivative, samples ``k +- 1, 3, 5`` (exact to degree 5).

    Parameters
    ----------
    x : ndarray (n, d)
        Samples.
    dt : float
        Sampling period, s.

    Returns
    -------
    ndarray (n, d)
        Units of ``x`` per s^2; the 5 samples at each end repeat the nearest interior value
        (zeros when ``n <= 10``).
    """
    x = np.asarray(x, float)
    out = np.zeros_like(x)
    n = len(x)
    if n <= 10:
        return out
    for w, j in zip(SECOND_WEIGHTS, (1, 3, 5), strict=True):
        out[5:-5] += w * (x[5 + j:n - 5 + j] + x[5 - j:n - 5 - j])
    out[5:-5] /= dt ** 2
    out[:5], out[-5:] = out[5], out[-6]
    return out


def first_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    """First time derivative, samples ``k +- 1, 2`` (exact to degree 4).

    Parameters
    ----------
    x : ndarray (n, d)
        Samples.
    dt : float
        Sampling period, s.

    Returns
    -------
    ndarray (n, d)
        Units of ``x`` per s; the 2 samples at each end repeat the nearest interior value
        (zeros when ``n <= 4``).
    """
    x = np.asarray(x, float)
    out = np.zeros_like(x)
    n = len(x)
    if n <= 4:
        return out
    out[2:-2] = (x[:n - 4] - 8.0 * x[1:n - 3] + 8.0 * x[3:n - 1] - x[4:]) / (12.0 * dt)
    out[:2], out[-2:] = out[2], out[-3]
    return out


def free_rates(motion, quaternion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Accelerations, angular rates and angular accelerations per segment (base frame).

    Parameters
    ----------
    motion : Motion
        Positions (m), times (s) and segments.
    quaternion : ndarray (n, 4)
        Measured quaternions ``(w, x, y, z)``; signs may flip between samples.

    Returns
    -------
    a : ndarray (n, 3)
        Accelerations, m/s^2.
    omega : ndarray (n, 3)
        Angular rates, rad/s (``2 vec(qd q*)``).
    alpha : ndarray (n, 3)
        Angular accelerations, rad/s^2 (``2 vec(qdd q*)``).
    """
    n = len(motion.t)
    dt = float(np.median(np.diff(motion.t)))
    q = np.asarray(quaternion, float).copy()
    a = np.zeros((n, 3))
    qd, qdd = np.zeros((n, 4)), np.zeros((n, 4))
    for s0, s1 in motion.segments:
        qs = q[s0:s1]
        qs[1:] *= np.cumprod(np.where(np.sum(qs[1:] * qs[:-1], axis=1) < 0, -1.0, 1.0))[:, None]
        a[s0:s1] = second_derivative(np.asarray(motion.position)[s0:s1], dt)
        qd[s0:s1] = first_derivative(qs, dt)
        qdd[s0:s1] = second_derivative(qs, dt)
    om, al = angular_rates(q, qd, qdd)
    return a, np.asarray(om), np.asarray(al)
