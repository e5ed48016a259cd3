"""Rotation-consistent matched filtering for the zero-phase Euler recipe (issue 24).

``euler-filtfilt`` returns the accelerations through its zero-phase low-pass ``F`` (the
Butterworth and the second difference's response, :func:`cdprid.signal.acceleration_filter`):
``a_hat = F[a]``, and ``W tau`` is filtered by the same ``F``. On rotating data the regressor's
rotation terms are *products* (``R I R^T alpha``, ``omega x I omega``, ``R m s x (a - g)``) and
``F`` does not commute with products: built from the filtered states, they differ from ``F``
of the true terms at the rotation's harmonics. The inertia is a small share of the moment rows,
so this mismatch, 1-2e-4 N m at a 2 Hz cutoff on noise-free data, moved an 8-cable robot's
Ixx by 0.36 % (``studies/bias_sources.py --mode mismatch --cutoff 2``; 1e-5 N m and 0.01 %
with this path).

Here, as :mod:`cdprid.core._linear_match` does for the causal differentiators, the
rotation-dependent part of the regressor is formed from accurate rates (central differences of
the poses and quaternions, :func:`cdprid.core._linear_match.reference_rates`) and passed
through ``F`` term by term; its part linear in the translational acceleration at the mean
orientation uses the differentiator's own ``a_hat`` (``= F[a]``):

``A = Y(R0, a_hat, 0, 0) - Y(R0, 0, 0, 0) + F[Y(R, a, omega, alpha) - Y(R0, a, 0, 0)
+ Y(R0, 0, 0, 0)]``, ``y = F[W tau]``.

On noise-free data this holds term by term (to the central differences' truncation); with
noise, every term goes through the same linear filter.
"""

from __future__ import annotations

import numpy as np

from cdprid.core._linear_match import rotation_remainder
from cdprid.core._motion import Motion
from cdprid.core._regression import StreamedRegression, cable_wrench

__all__ = ["platform_radius", "regressor_scale", "seen_mass", "uses_zero_phase_match",
           "zero_phase_matched_regression"]


def uses_zero_phase_match(model: str, differentiator: str, wrench_filter: str,
                          quaternion) -> bool:
    """Whether identification takes the zero-phase rotation-consistent path: the full model,
    ``euler-filtfilt``, matched filtering and a quaternion stream.

    Parameters
    ----------
    model : {"translation", "full"}
    differentiator : str
    wrench_filter : str
    quaternion : ndarray (n, 4) or None
        The quaternion stream, if any.

    Returns
    -------
    bool
    """
    return (model == "full" and differentiator == "euler-filtfilt"
            and wrench_filter == "matched" and quaternion is not None)


def platform_radius(robot) -> float:
    """The largest attachment distance from the platform's reference point (>= 1 mm): the
    moment rows' scale.

    Parameters
    ----------
    robot : CableRobot

    Returns
    -------
    float
        Radius, m.
    """
    return max(float(np.max(np.linalg.norm(np.asarray(robot.P_b), axis=1))), 1e-3)


def seen_mass(robot, y: np.ndarray) -> float:
    """The mass the mean force of the wrenches ``y`` holds against gravity (>= 1e-6 kg).

    Parameters
    ----------
    robot : CableRobot
        Its gravity vector (m/s^2).
    y : ndarray (n, 6)
        Wrenches, N and N m.

    Returns
    -------
    float
        Mass, kg.
    """
    gnorm = max(float(np.linalg.norm(np.asarray(robot.gravity))), 1e-9)
    return max(float(np.linalg.norm(y[:, :3].mean(axis=0))) / gnorm, 1e-6)


def regressor_scale(robot, y: np.ndarray, p: int) -> np.ndarray:
    """Amplitude of each row and column channel of the regressor, the filter's ``scale``: the
    seen mass (from the filtered wrench ``y``), the first moment and the inertia at the
    platform's radius, forces and moments apart.

    Parameters
    ----------
    robot : CableRobot
    y : ndarray (n, 6)
        Filtered cable wrenches, N and N m.
    p : int
        Parameters of the model (4 or 10).

    Returns
    -------
    ndarray (6, p)
        Row scale over parameter scale (1/kg, 1/(kg m), 1/(kg m^2) for force rows; times the
        radius for moment rows).
    """
    m_seen = seen_mass(robot, y)
    r = platform_radius(robot)
    typical = np.array([m_seen] + [m_seen * r] * 3 + [m_seen * r * r] * 6)[:p]
    rows = np.array([1.0] * 3 + [r] * 3)
    return rows[:, None] / typical[None, :]


def zero_phase_matched_regression(robot, motion: Motion, quaternion, tension, wf, keep,
                                  chunk: int) -> StreamedRegression:
    """The kept samples' regression with every rotation term through the wrench filter ``wf``.

    Holds the (n, 6 p) filtered regressor.

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
        The differentiator's motion (its ``acceleration`` is ``F[a]``).
    quaternion : ndarray (n, 4)
        Measured quaternions at the pose times.
    tension : ndarray (n, m)
        Tensions at the pose times, N.
    wf : callable
        The matched wrench filter (``wf(u, scale)`` filters (n, k) channels).
    keep : ndarray (n,) of bool
        The samples kept (trimmed ends).
    chunk : int
        Samples per regressor block.

    Returns
    -------
    StreamedRegression
        The full model's rows (k, 6, 10) and filtered wrenches (k, 6), N and N m, at the kept
        samples.
    """
    n = len(motion.t)
    y = np.asarray(wf(cable_wrench(robot, motion.position, motion.B_R_P, tension, chunk)))
    rem, linear_part = rotation_remainder(robot, motion, quaternion, "full", keep, chunk)
    scale = regressor_scale(robot, y, rem.shape[-1]).reshape(-1)
    flat = rem.reshape(n, -1)
    A = np.empty_like(flat)
    for j in range(0, flat.shape[1], 6):  # 6 channels at a time: the filter's temporaries
        A[:, j:j + 6] = np.asarray(wf(flat[:, j:j + 6], scale[j:j + 6]))  # stay (n, 6)
    del rem, flat
    A = A.reshape(n, 6, -1)
    A += linear_part(motion.acceleration)
    idx = np.flatnonzero(keep)
    y, t = y[idx], motion.t[idx]
    return StreamedRegression(t, y, "full", lambda i0, i1: A[idx[i0:i1]])
