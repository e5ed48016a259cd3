"""One jit wrapper for the excitation trajectories' states (Fourier and homed alike).

:meth:`cdprid.excitation.FourierTrajectory.evaluate` and
:meth:`cdprid.excitation.HomedTrajectory.evaluate` both call :func:`states_jit`.
"""

from __future__ import annotations

import equinox as eqx

from cdprid.model import TrajectoryState

__all__ = ["states_jit"]


@eqx.filter_jit
def states_jit(traj, t) -> TrajectoryState:
    """``traj.states(t)``, compiled once per trajectory type and shape of ``t``.

    Parameters
    ----------
    traj : eqx.Module
        A trajectory with a pure-JAX ``states(t)`` method (its arrays are traced, its other
        fields static).
    t : jax.Array (n,)
        Times, s.

    Returns
    -------
    TrajectoryState
        ``traj.states(t)``: position (m), velocity, acceleration, jerk, quaternion, angular
        velocity (rad/s) and acceleration (rad/s^2), base frame, each with n rows.
    """
    return traj.states(t)
