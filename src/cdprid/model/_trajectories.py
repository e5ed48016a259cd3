"""Platform trajectories with exact derivatives: ramped orbits, sequences, small rotations.

An orbit (paper section 7) is a circle of radius R about a centre c, in a plane spanned by
the unit vectors ``e1 = Rz(azimuth) x`` and ``e2 = Rz(azimuth) Rx(tilt) y`` (azimuth 0,
tilt 0: the horizontal xy plane; azimuth 0, tilt pi/2: the xz plane; azimuth pi/2,
tilt pi/2: the yz plane), travelled at f Hz from the phase phi. Each orbit segment
``[t0, t0 + T]`` is blended in and out of the rest point r of the whole trajectory by the
envelope ``e(t) = S((t - t0) / T_r) S((t0 + T - t) / T_r)`` with the septic smoothstep
``S(x) = 35 x^4 - 84 x^5 + 70 x^6 - 20 x^7`` (``S, S', S'', S'''`` vanish at 0, and
``S' .. S'''`` at 1):

    B_p(t) = r + sum_segments e(t) [(c - r) + R (cos(theta) e1 + sin(theta) e2)],
    theta = phi + 2 pi f (t - t0),

so the platform starts and ends every segment at rest at r with zero velocity,
acceleration and jerk (a spiral in and out during the ramps of length T_r).

Small platform rotations: rotation vector ``rho(t) = E(t) sum_k A_k * sin(2 pi f_k t + phi_k)``
(component-wise, A in rad), E the global septic ramp-in/ramp-out over the trajectory, and
``q = exp(rho)`` (scalar first, platform -> base).

Velocity, acceleration, jerk, and ``dq/dt``, ``d2q/dt2`` are obtained by forward-mode
automatic differentiation of these closed forms in t — exact to rounding, not finite
differences; ``omega = 2 vec(dq/dt q*)``, ``alpha = 2 vec(d2q/dt2 q*)`` (base frame).

CSV form (also read by ``cdprid simulate --trajectory``): one header line, columns
``t,x,y,z,vx,vy,vz,ax,ay,az`` and, when the platform rotates,
``qw,qx,qy,qz,wx,wy,wz,alx,aly,alz`` (SI units, base frame). A loaded CSV is a
:class:`SampledTrajectory`: exact at its sample times, and between them a quintic Hermite
interpolant of (p, v, a) — and of (q, dq/dt, d2q/dt2), renormalised — so positions are C2
and consistent with their derivatives; outside its time range it holds the end pose.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.model._rotation_paths import Rotation, _identity, _rotation_state, small_rotation
from cdprid.model._smoothstep import _binom, smoothstep7_derivs

POSITION_COLUMNS = ("t", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az")


ROTATION_COLUMNS = ("qw", "qx", "qy", "qz", "wx", "wy", "wz", "alx", "aly", "alz")


PRESETS = ("paper-orbits", "rich")


class TrajectoryState(NamedTuple):
    """Motion of the platform at n times (all base frame, SI units).

    Attributes
    ----------
    t : (n,)
    p, v, a, j : (n, 3)
        Position of P and its first three time derivatives.
    q : (n, 4)
        Unit quaternion, scalar first, platform -> base.
    omega, alpha : (n, 3)
        Angular velocity and acceleration, base frame.
    """

    t: jnp.ndarray
    p: jnp.ndarray
    v: jnp.ndarray
    a: jnp.ndarray
    j: jnp.ndarray
    q: jnp.ndarray
    omega: jnp.ndarray
    alpha: jnp.ndarray


_smoothstep7_derivs = smoothstep7_derivs


@dataclasses.dataclass(frozen=True)
class Orbit:
    """One ramped orbit segment (a plain description; see :func:`orbit_sequence`).

    Attributes
    ----------
    radius : float
        m.
    frequency : float
        Hz (revolutions per second).
    duration : float
        Segment length including both ramps, s.
    azimuth, tilt : float
        Plane angles, rad: ``e1 = Rz(azimuth) x``, ``e2 = Rz(azimuth) Rx(tilt) y``.
    phase : float
        Angle on the circle at the segment start, rad.
    ramp : float
        Ramp-in and ramp-out time, s (at most half the duration).
    centre : tuple of 3 floats or None
        Orbit centre, base frame; None = the rest point of the trajectory.
    """

    radius: float
    frequency: float
    duration: float
    azimuth: float = 0.0
    tilt: float = 0.0
    phase: float = 0.0
    ramp: float = 2.0
    centre: tuple | None = None

    def __post_init__(self):
        for name in ("radius", "frequency", "duration", "ramp"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"Orbit {name} must be a finite number >= 0, got {v}.")
        if self.duration <= 0 or self.ramp <= 0 or 2 * self.ramp > self.duration + 1e-12:
            raise InputError(
                f"Orbit ramp ({self.ramp} s) must be positive and at most half the duration "
                f"({self.duration} s)."
            )


class TimedTrajectory(eqx.Module):
    """Base of the trajectories that start at t = 0 and last ``duration`` s: ``t_start`` and
    ``t_end`` (the interface that :class:`SampledTrajectory` gives from its samples)."""

    @property
    def t_start(self) -> float:
        """Start time, s."""
        return 0.0

    @property
    def t_end(self) -> float:
        """End time, s."""
        return float(self.duration)


class Trajectory(TimedTrajectory):
    """A sequence of ramped orbits about a rest point, optionally with small rotations.

    Build it with :func:`orbit_sequence` or :func:`preset`; evaluate it with :meth:`evaluate`.

    Attributes
    ----------
    rest : (3,)
        Rest point, base frame, m.
    t0, T, ramp, radius, freq, phase : (S,)
        Segment start, duration, ramp time, radius, frequency, start phase.
    centre, e1, e2 : (S, 3)
        Orbit centres and plane bases.
    rotation : Rotation or None
    duration : float
        End time (the motion is defined on ``[0, duration]`` and rests outside).
    name : str
    """

    rest: jnp.ndarray
    t0: jnp.ndarray
    T: jnp.ndarray
    ramp: jnp.ndarray
    radius: jnp.ndarray
    freq: jnp.ndarray
    phase: jnp.ndarray
    centre: jnp.ndarray
    e1: jnp.ndarray
    e2: jnp.ndarray
    rotation: Rotation | None = None
    duration: float = eqx.field(static=True, default=0.0)
    name: str = eqx.field(static=True, default="trajectory")

    @property
    def has_rotation(self) -> bool:
        """True when the platform rotates."""
        return self.rotation is not None and bool(np.any(np.asarray(self.rotation.amplitude) != 0))

    def position(self, t):
        """Position of P at a scalar time t (closed form of the module docstring).

        Parameters
        ----------
        t : float
            Time, s.

        Returns
        -------
        array (3,)
            Position, base frame, m.
        """
        return self._position_derivs(t, 0)[0]

    def _position_derivs(self, t, order: int):
        """[p, p', ..., p^(order)] at a scalar t, by hand (Leibniz rule on envelope x circle)."""
        u = t - self.t0
        g1 = _smoothstep7_derivs(u / self.ramp, self.ramp, 1.0, order)
        g2 = _smoothstep7_derivs((self.T - u) / self.ramp, self.ramp, -1.0, order)
        env = [
            sum(_binom(n, k) * g1[k] * g2[n - k] for k in range(n + 1)) for n in range(order + 1)
        ]
        w = 2.0 * jnp.pi * self.freq
        theta = self.phase + w * u
        circ = []
        for n in range(order + 1):
            c = self.radius * w**n
            th = theta + n * jnp.pi / 2
            term = c[:, None] * (jnp.cos(th)[:, None] * self.e1 + jnp.sin(th)[:, None] * self.e2)
            circ.append(term + (self.centre - self.rest) if n == 0 else term)
        out = []
        for n in range(order + 1):
            d = sum(_binom(n, k) * env[k][:, None] * circ[n - k] for k in range(n + 1))
            out.append(jnp.sum(d, axis=0) + (self.rest if n == 0 else 0.0))
        return out

    def _one(self, t):
        p, v, a, j = self._position_derivs(t, 3)
        if self.rotation is None:
            q, w, al = _identity()
        else:
            q, w, al = _rotation_state(self.rotation.quat, t)
        return p, v, a, j, q, w, al

    def evaluate(self, t) -> TrajectoryState:
        """Evaluate the motion at times t.

        Parameters
        ----------
        t : array (n,)
            Times, s.

        Returns
        -------
        TrajectoryState
        """
        return _evaluate_padded(self, t)


@eqx.filter_jit
def _evaluate(traj, t):
    out = jax.vmap(traj._one)(t)
    return TrajectoryState(t, *out)


def _evaluate_padded(traj, t) -> TrajectoryState:
    """Evaluate on t padded to a bucket size (8192 or the next power of two), so that
    calls with different numbers of samples share one compilation."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    n = t.shape[0]
    size = max(8192, 1 << max(n - 1, 1).bit_length())
    tp = np.concatenate([t, np.full(size - n, t[-1] if n else 0.0)])
    out = _evaluate(traj, jnp.asarray(tp))
    return TrajectoryState(*(x[:n] for x in out))


def _plane(azimuth: float, tilt: float):
    ca, sa, ct, st = np.cos(azimuth), np.sin(azimuth), np.cos(tilt), np.sin(tilt)
    Rz = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
    return Rz @ np.array([1.0, 0.0, 0.0]), Rz @ np.array([0.0, ct, st])


def orbit_sequence(
    orbits,
    rest,
    rest_before: float = 0.5,
    rest_between: float = 0.5,
    rest_after: float = 0.5,
    rotation_amplitude: float = 0.0,
    name: str = "orbits",
) -> Trajectory:
    """Chain ramped orbits, each starting and ending at rest at ``rest``.

    Parameters
    ----------
    orbits : sequence of Orbit
    rest : array (3,)
        Rest point (base frame, m); also the default orbit centre.
    rest_before, rest_between, rest_after : float
        Rest times before the first, between consecutive and after the last orbit, s.
    rotation_amplitude : float
        If > 0, add :func:`small_rotation` of that amplitude (rad).
    name : str

    Returns
    -------
    Trajectory
        Defined on ``[0, duration]``.
    """
    orbits = list(orbits)
    if not orbits:
        raise InputError("orbit_sequence needs at least one Orbit.")
    if min(rest_before, rest_between, rest_after) < 0:
        raise InputError("rest times must be >= 0 s.")
    rest = np.asarray(rest, float).reshape(3)
    t0, t = [], rest_before
    for k, o in enumerate(orbits):
        t0.append(t)
        t += o.duration + (rest_between if k < len(orbits) - 1 else 0.0)
    duration = t + rest_after
    planes = [_plane(o.azimuth, o.tilt) for o in orbits]
    traj = Trajectory(
        rest=jnp.asarray(rest),
        t0=jnp.asarray(t0),
        T=jnp.asarray([o.duration for o in orbits]),
        ramp=jnp.asarray([o.ramp for o in orbits]),
        radius=jnp.asarray([o.radius for o in orbits]),
        freq=jnp.asarray([o.frequency for o in orbits]),
        phase=jnp.asarray([o.phase for o in orbits]),
        centre=jnp.asarray(
            [rest if o.centre is None else np.asarray(o.centre, float) for o in orbits]
        ),
        e1=jnp.asarray(np.array([p[0] for p in planes])),
        e2=jnp.asarray(np.array([p[1] for p in planes])),
        rotation=None,
        duration=float(duration),
        name=name,
    )
    if rotation_amplitude > 0:
        traj = with_rotation(traj, rotation_amplitude)
    return traj


def with_rotation(traj, amplitude_rad: float, ramp: float = 2.0):
    """A copy of ``traj`` whose platform also performs :func:`small_rotation`.

    Parameters
    ----------
    traj : Trajectory or SampledTrajectory
        Must not rotate already.
    amplitude_rad : float
    ramp : float
        Envelope ramp time, s.

    Returns
    -------
    same type as ``traj``
    """
    if traj.has_rotation:
        raise InputError("the trajectory already rotates; cannot add another rotation to it.")
    rot = small_rotation(amplitude_rad, traj.t_start, traj.t_end, ramp)
    return eqx.tree_at(lambda tr: tr.rotation, traj, rot, is_leaf=lambda x: x is None)
