"""The move from home to a family's start point and back (rest to rest, continuous jerk).

:class:`HomedTrajectory` wraps a family's trajectory (:mod:`cdprid.excitation._families`)
with a septic-smoothstep move from the home pose in and the same move back at the end.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.model import TimedTrajectory, TrajectoryState, smoothstep7_derivs

__all__ = ["HomedTrajectory", "move_duration"]


def move_duration(distance: float, speed_max: float, acceleration_max: float, jerk_max: float,
                  fraction: float = 0.5, minimum: float = 2.0) -> float:
    """Duration of a septic-smoothstep move whose peaks stay below a fraction of the limits.

    Peaks of ``S(t / T)`` times D: speed 2.1875 D/T, acceleration 7.5133 D/T^2, jerk 52.5 D/T^3.

    Parameters
    ----------
    distance : float
        Length of the move, m.
    speed_max, acceleration_max, jerk_max : float
        Limits, m/s, m/s^2, m/s^3.
    fraction : float
        Fraction of each limit the peaks stay within.
    minimum : float
        Shortest duration, s.

    Returns
    -------
    float
        Duration, s, rounded up to a multiple of 0.1 s.
    """
    D = float(distance)
    T = max(minimum, 2.1875 * D / (fraction * speed_max),
            np.sqrt(7.5133 * D / (fraction * acceleration_max)),
            np.cbrt(52.5 * D / (fraction * jerk_max)))
    return float(np.ceil(T * 10.0 - 1e-9) / 10.0)


class HomedTrajectory(TimedTrajectory):
    """A family's trajectory (coordinates z) preceded by a move from rest at ``home`` to its
    start point and followed by the move back (rest to rest, continuous jerk).

    Times: the move in over ``[0, t_move]``, the exciting part over
    ``[t_move, t_move + family.duration]``, the move back until ``t_end``. The same interface
    as :class:`cdprid.model.Trajectory` (``evaluate``, ``t_start``, ``t_end``,
    ``has_rotation``, ``name``).
    """

    family: eqx.Module
    z: jnp.ndarray
    home: jnp.ndarray
    t_move: float = eqx.field(static=True)

    @property
    def has_rotation(self) -> bool:
        """Whether the family rotates the platform."""
        return bool(self.family.rotates)

    @property
    def duration(self) -> float:
        """Whole duration (moves and exciting part), s; ``t_end`` of :class:`TimedTrajectory`."""
        return float(2.0 * self.t_move + self.family.duration)

    @property
    def name(self) -> str:
        """``excitation-<family>``."""
        return f"excitation-{self.family.name}"

    @property
    def start_point(self):
        """Where the exciting part starts and ends (at rest), base frame, m."""
        return self.family.to_params(self.z)["centre"]

    def states(self, t) -> TrajectoryState:
        """Motion at times t (pure JAX).

        Parameters
        ----------
        t : array (n,)
            Times from 0 (rest at home) to ``t_end``, s.

        Returns
        -------
        TrajectoryState
            Position (m), velocity, acceleration, jerk, quaternion, angular velocity (rad/s) and
            acceleration (rad/s^2), base frame, each with n rows.
        """
        T, D = self.t_move, float(self.family.duration)
        s = self.family.states(self.z, jnp.clip(t - T, 0.0, D))
        gin = smoothstep7_derivs(t / T, T, 1.0, 3)
        gout = smoothstep7_derivs((t - T - D) / T, T, 1.0, 3)
        delta = self.home - self.start_point
        # p = start + (1 - S_in) (home - start) + S_out (home - start) + exciting displacement
        k = [(1.0 - gin[0]) + gout[0]] + [gout[n] - gin[n] for n in range(1, 4)]
        moves = [kn[:, None] * delta[None, :] for kn in k]
        return TrajectoryState(t, s.p + moves[0], s.v + moves[1], s.a + moves[2], s.j + moves[3],
                               s.q, s.omega, s.alpha)

    def evaluate(self, t) -> TrajectoryState:
        """Evaluate the motion at times t, jit-compiled.

        Parameters
        ----------
        t : float or array (n,)
            Times, s.

        Returns
        -------
        TrajectoryState
            Position (m), velocity, acceleration, jerk, quaternion, angular velocity (rad/s) and
            acceleration (rad/s^2), base frame, each with n rows.
        """
        return _homed_eval(self, jnp.atleast_1d(jnp.asarray(t, float)))


@eqx.filter_jit
def _homed_eval(traj, t):
    return traj.states(t)
