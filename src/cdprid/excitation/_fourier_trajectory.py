"""Ramped envelopes with their derivatives (Leibniz rule), and the ``fourier`` family's
trajectory :class:`FourierTrajectory` (:mod:`cdprid.excitation._families`)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from cdprid.model import (
    TimedTrajectory,
    TrajectoryState,
    angular_rates_from_quat,
    rotvec_to_quat,
    smoothstep7_derivs,
)

__all__ = ["FourierTrajectory"]

_BINOM = ((1,), (1, 1), (1, 2, 1), (1, 3, 3, 1))


def _envelope(u, T, ramp):
    """Envelope ``e(u) = S(u / ramp) S((T - u) / ramp)`` and 3 derivatives (Leibniz rule)."""
    g1 = smoothstep7_derivs(u / ramp, ramp, 1.0, 3)
    g2 = smoothstep7_derivs((T - u) / ramp, ramp, -1.0, 3)
    return [sum(_BINOM[n][k] * g1[k] * g2[n - k] for k in range(n + 1)) for n in range(4)]


def _leibniz(env, f):
    """Derivatives 0..3 of ``env * f`` (env[..., None] broadcast against f)."""
    return [sum(_BINOM[n][k] * env[k][..., None] * f[n - k] for k in range(n + 1))
            for n in range(4)]


class FourierTrajectory(TimedTrajectory):
    """Position and small rotation as ramped Fourier series (duck-types ``Trajectory``).

    ``B_p(t) = c + E(t) sum_k (P_cos[k] cos(2 pi k f0 s) + P_sin[k] sin(2 pi k f0 s))`` and the
    rotation vector ``rho(t)`` likewise (rad), ``s = t - t_a``, ``q = exp(rho)``; E ramps in over
    ``[t_a, t_a + ramp]`` and out over ``[t_b - ramp, t_b]``.
    """

    centre: jnp.ndarray
    P_cos: jnp.ndarray
    P_sin: jnp.ndarray
    R_cos: jnp.ndarray
    R_sin: jnp.ndarray
    f0: float = eqx.field(static=True)
    t_a: float = eqx.field(static=True)
    t_b: float = eqx.field(static=True)
    ramp: float = eqx.field(static=True)
    duration: float = eqx.field(static=True)
    name: str = eqx.field(static=True, default="excitation-fourier")

    @property
    def has_rotation(self) -> bool:
        """True: the platform rotates."""
        return True

    def _series_derivs(self, C, S, t):
        """Derivatives 0..3 (each (n, 3)) of ``E(t) sum_k (C_k cos + S_k sin)`` at times t (n,)."""
        k = jnp.arange(1, C.shape[0] + 1)
        wk = 2.0 * jnp.pi * self.f0 * k
        th = wk * (t[:, None] - self.t_a)  # (n, H)
        g = [(jnp.cos(th + n * jnp.pi / 2) * wk**n) @ C + (jnp.sin(th + n * jnp.pi / 2) * wk**n) @ S
             for n in range(4)]
        env = _envelope(t - self.t_a, self.t_b - self.t_a, self.ramp)
        return _leibniz(env, g)

    def position(self, t):
        """Position of P at a scalar time t.

        Parameters
        ----------
        t : float
            Time, s.

        Returns
        -------
        array (3,)
            Base frame, m.
        """
        return self.centre + self._series_derivs(self.P_cos, self.P_sin, jnp.atleast_1d(t))[0][0]

    def quat(self, t):
        """Quaternion, scalar first, platform -> base, at a scalar time t.

        Parameters
        ----------
        t : float
            Time, s.

        Returns
        -------
        array (4,)
        """
        return rotvec_to_quat(self._series_derivs(self.R_cos, self.R_sin, jnp.atleast_1d(t))[0][0])

    def states(self, t) -> TrajectoryState:
        """Motion at times t, closed-form derivatives.

        q = exp(rho), omega and alpha from dq/dt and d2q/dt2 (nested forward-mode derivatives of
        exp along rho(t)).

        Parameters
        ----------
        t : array (n,)
            Times, s.

        Returns
        -------
        TrajectoryState
            Position (m), velocity, acceleration, jerk, quaternion, angular velocity (rad/s) and
            acceleration (rad/s^2), base frame, each with n rows.
        """
        p = self._series_derivs(self.P_cos, self.P_sin, t)
        r = self._series_derivs(self.R_cos, self.R_sin, t)

        def rot(r0, r1, r2):
            def dq(x, dx):
                return jax.jvp(rotvec_to_quat, (x,), (dx,))

            (q, qd), (_, qdd1) = jax.jvp(dq, (r0, r1), (r1, r2))
            return (q,) + tuple(angular_rates_from_quat(q, qd, qdd1))

        q, om, al = jax.vmap(rot)(r[0], r[1], r[2])
        return TrajectoryState(t, self.centre + p[0], p[1], p[2], p[3], q, om, al)

    def evaluate(self, t) -> TrajectoryState:
        """Evaluate the motion at times t (same contract as ``Trajectory.evaluate``), jit-compiled.

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
        return _fourier_eval(self, jnp.atleast_1d(jnp.asarray(t, float)))


@eqx.filter_jit
def _fourier_eval(traj, t):
    return traj.states(t)
