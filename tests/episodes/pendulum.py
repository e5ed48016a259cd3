"""An independent pendulum for the energy tests: RK4 on (angle, angular rate), written here
and not from the library's forward model."""

from __future__ import annotations

import numpy as np


def rk4_swing(accel, th0: float, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Integrate ``th'' = accel(th, om, t)`` by one RK4 step per sample of ``t`` (uniform).

    Parameters
    ----------
    accel : callable (th rad, om rad/s, t s) -> rad/s^2
    th0 : float
        Angle at ``t[0]``, rad, starting at rest.
    t : (n,) sample times, s.

    Returns
    -------
    th, om : (n,) angle (rad) and rate (rad/s) after each sample's step.
    """
    dt = float(t[1] - t[0])
    th, om, out = float(th0), 0.0, []
    for tk in t:
        def f(th, om, tk=tk):
            return om, accel(th, om, tk)
        k1 = f(th, om)
        k2 = f(th + dt / 2 * k1[0], om + dt / 2 * k1[1])
        k3 = f(th + dt / 2 * k2[0], om + dt / 2 * k2[1])
        k4 = f(th + dt * k3[0], om + dt * k3[1])
        th += dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        om += dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        out.append((th, om))
    th_, om_ = np.array(out).T
    return th_, om_
