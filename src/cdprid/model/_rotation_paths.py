"""Small platform rotations along a trajectory: the Rotation module and its state."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.model._rotations import angular_rates_from_quat, rotvec_to_quat
from cdprid.model._smoothstep import _derivs, smoothstep7


class Rotation(eqx.Module):
    """Small platform rotation ``rho(t) = E(t) sum_k A_k sin(2 pi f_k t + phi_k)`` (per axis).

    Attributes
    ----------
    amplitude : (K, 3) rad
    frequency : (K, 3) Hz
    phase : (K, 3) rad
    t_start, t_end, ramp : float
        The envelope E ramps in over ``[t_start, t_start + ramp]`` and out over
        ``[t_end - ramp, t_end]`` (septic smoothstep); E = 0 outside.
    """

    amplitude: jnp.ndarray
    frequency: jnp.ndarray
    phase: jnp.ndarray
    t_start: float = eqx.field(static=True, default=0.0)
    t_end: float = eqx.field(static=True, default=1.0)
    ramp: float = eqx.field(static=True, default=2.0)

    def rotvec(self, t):
        """Rotation vector at a scalar time t.

        Parameters
        ----------
        t : float
            Time, s.

        Returns
        -------
        array (3,)
            Rotation vector, rad.
        """
        env = smoothstep7((t - self.t_start) / self.ramp) * smoothstep7(
            (self.t_end - t) / self.ramp
        )
        s = jnp.sin(2.0 * jnp.pi * self.frequency * t + self.phase)
        return env * jnp.sum(self.amplitude * s, axis=0)

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
        return rotvec_to_quat(self.rotvec(t))


def small_rotation(
    amplitude_rad: float, t_start: float, t_end: float, ramp: float = 2.0
) -> Rotation:
    """A deterministic small rotation of amplitude ``amplitude_rad`` about every base axis.

    Parameters
    ----------
    amplitude_rad : float
        Peak rotation about each axis, rad (the total angle stays below sqrt(3) times it).
    t_start, t_end : float
        Time span of the motion, s.
    ramp : float
        Ramp-in/ramp-out time of the envelope, s.

    Returns
    -------
    Rotation
        Three incommensurate frequencies (0.17, 0.29, 0.23 Hz about x, y, z).
    """
    a = float(amplitude_rad)
    if not np.isfinite(a) or a < 0:
        raise InputError(
            f"the rotation amplitude must be a finite number >= 0 rad, got {amplitude_rad}."
        )
    ramp = min(ramp, 0.5 * (t_end - t_start))
    return Rotation(
        amplitude=jnp.full((1, 3), a),
        frequency=jnp.array([[0.17, 0.29, 0.23]]),
        phase=jnp.array([[0.0, 1.0, 2.0]]),
        t_start=float(t_start),
        t_end=float(t_end),
        ramp=float(ramp),
    )


def _rotation_state(quat_fn, t):
    q, qd, qdd = _derivs(quat_fn, t, 2)
    omega, alpha = angular_rates_from_quat(q, qd, qdd)
    return q, omega, alpha


def _identity():
    """``(q, omega, alpha)`` of no rotation, created when called (an array made at import time
    would start JAX's backend on ``import cdprid`` and be float32 before x64 is enabled)."""
    return jnp.array([1.0, 0.0, 0.0, 0.0]), jnp.zeros(3), jnp.zeros(3)
