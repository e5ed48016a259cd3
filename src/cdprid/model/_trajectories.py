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

from cdprid.model._rotations import angular_rates_from_quat, quat_multiply, rotvec_to_quat

__all__ = [
    "Orbit",
    "Rotation",
    "TimedTrajectory",
    "Trajectory",
    "SampledTrajectory",
    "TrajectoryState",
    "orbit_sequence",
    "small_rotation",
    "with_rotation",
    "preset",
    "PRESETS",
    "check_workspace",
    "smoothstep7",
    "smoothstep7_derivs",
    "POSITION_COLUMNS",
    "ROTATION_COLUMNS",
]

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


def smoothstep7(x):
    """Septic smoothstep ``35 x^4 - 84 x^5 + 70 x^6 - 20 x^7`` of ``clip(x, 0, 1)``.

    Its first three derivatives vanish at 0 and 1.
    """
    x = jnp.clip(x, 0.0, 1.0)
    return x**4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)))


def _binom(n: int, k: int) -> int:
    from math import comb

    return comb(n, k)


def smoothstep7_derivs(x, scale, sign, order: int):
    """[g, g', ..., g^(order)] of ``g(u) = S(x)`` with ``dx/du = sign / scale``.

    S is :func:`smoothstep7`; outside [0, 1] the derivatives are 0 (S is constant there).
    """
    inside = (x > 0.0) & (x < 1.0)
    x = jnp.clip(x, 0.0, 1.0)
    # S and its derivatives as polynomials in x (exact)
    polys = [
        x**4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x))),
        x**3 * (140.0 + x * (-420.0 + x * (420.0 - 140.0 * x))),
        x**2 * (420.0 + x * (-1680.0 + x * (2100.0 - 840.0 * x))),
        x * (840.0 + x * (-5040.0 + x * (8400.0 - 4200.0 * x))),
    ]
    out = [polys[0]]
    for k in range(1, order + 1):
        out.append(jnp.where(inside, polys[k], 0.0) * (sign / scale) ** k)
    return out


_smoothstep7_derivs = smoothstep7_derivs


def _derivs(f, t, order):
    """[f(t), f'(t), ..., f^(order)(t)] by nested forward-mode differentiation (scalar t)."""
    out = [f]
    for _ in range(order):
        out.append(jax.jacfwd(out[-1]))
    return [g(t) for g in out]


# ----------------------------------------------------------------------------- rotation


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
        """Rotation vector (3,) at a scalar time t."""
        env = smoothstep7((t - self.t_start) / self.ramp) * smoothstep7(
            (self.t_end - t) / self.ramp
        )
        s = jnp.sin(2.0 * jnp.pi * self.frequency * t + self.phase)
        return env * jnp.sum(self.amplitude * s, axis=0)

    def quat(self, t):
        """Quaternion (4,) scalar first, platform -> base, at a scalar time t."""
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
        raise ValueError(
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


_IDENTITY = (jnp.array([1.0, 0.0, 0.0, 0.0]), jnp.zeros(3), jnp.zeros(3))


# ----------------------------------------------------------------------------- orbits


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
                raise ValueError(f"Orbit {name} must be a finite number >= 0, got {v}.")
        if self.duration <= 0 or self.ramp <= 0 or 2 * self.ramp > self.duration + 1e-12:
            raise ValueError(
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
        """Position of P (3,) at a scalar time t (closed form of the module docstring)."""
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
            q, w, al = _IDENTITY
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
        raise ValueError("orbit_sequence needs at least one Orbit.")
    if min(rest_before, rest_between, rest_after) < 0:
        raise ValueError("rest times must be >= 0 s.")
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
        raise ValueError("the trajectory already rotates; cannot add another rotation to it.")
    rot = small_rotation(amplitude_rad, traj.t_start, traj.t_end, ramp)
    return eqx.tree_at(lambda tr: tr.rotation, traj, rot, is_leaf=lambda x: x is None)


# ----------------------------------------------------------------------------- presets


def _centre_of(robot) -> np.ndarray:
    if robot is None or robot.limits.workspace_min is None or robot.limits.workspace_max is None:
        return np.array([0.0, 0.0, 1.2])
    lo = np.asarray(robot.limits.workspace_min)
    hi = np.asarray(robot.limits.workspace_max)
    c = 0.5 * (lo + hi)
    c[2] = float(np.clip(1.2, lo[2], hi[2]))
    return c


def _half_extent(robot, centre) -> float:
    if robot is None or robot.limits.workspace_min is None or robot.limits.workspace_max is None:
        return np.inf
    lo = np.asarray(robot.limits.workspace_min)
    hi = np.asarray(robot.limits.workspace_max)
    return float(np.min(np.minimum(centre - lo, hi - centre)))


def preset(
    name: str, robot=None, duration: float | None = None, rotation_amplitude: float = 0.0
) -> Trajectory:
    """A named trajectory, centred in the robot's workspace box.

    Parameters
    ----------
    name : {'paper-orbits', 'rich'}
        ``paper-orbits``: four ramped 0.25 Hz orbits in the xy, xz, yz and again xy planes
        (radii 0.4, 0.35, 0.35, 0.3 m), 52 s in total (paper section 7).
        ``rich``: six orbits at 0.2-0.6 Hz in six planes (radius decreasing with frequency),
        52 s, for diagnosis and identification of more parameters.
    robot : CableRobot, optional
        Its workspace box gives the centre (box centre in x, y; z = 1.2 m clipped into
        the box) and caps the radii at 90 % of the smallest half-extent, so the
        trajectory stays in the box.
    duration : float, optional
        Total time, s (default 52); segment durations are scaled to fit.
    rotation_amplitude : float
        Small rotation amplitude, rad (0: pure translation).

    Returns
    -------
    Trajectory
    """
    if name == "paper-orbits":
        spec = [  # (radius, freq, azimuth, tilt, phase)
            (0.40, 0.25, 0.0, 0.0, 0.0),
            (0.35, 0.25, 0.0, np.pi / 2, 0.0),
            (0.35, 0.25, np.pi / 2, np.pi / 2, 0.0),
            (0.30, 0.25, np.pi / 4, 0.0, np.pi / 2),
        ]
    elif name == "rich":
        spec = [
            (0.40, 0.20, 0.0, 0.0, 0.0),
            (0.30, 0.30, 0.0, np.pi / 2, 0.5),
            (0.25, 0.40, np.pi / 2, np.pi / 2, 1.0),
            (0.18, 0.50, np.pi / 4, np.pi / 3, 1.5),
            (0.12, 0.60, -np.pi / 4, 2 * np.pi / 3, 2.0),
            (0.20, 0.35, np.pi / 3, np.pi / 6, 2.5),
        ]
    else:
        raise ValueError(
            f"unknown trajectory preset {name!r}; valid presets: {', '.join(PRESETS)}."
        )
    total = 52.0 if duration is None else float(duration)
    rests = 0.5
    n = len(spec)
    seg = (total - (n + 1) * rests) / n
    if not np.isfinite(seg) or seg < 2.0:
        raise ValueError(
            f"duration {total:g} s is too short for the {name!r} preset (needs at least "
            f"{n * 2.0 + (n + 1) * rests:g} s)."
        )
    ramp = min(2.0, seg / 2)
    centre = _centre_of(robot)
    cap = 0.9 * _half_extent(robot, centre)
    orbits = [
        Orbit(min(r, cap), f, seg, azimuth=az, tilt=tl, phase=ph, ramp=ramp)
        for r, f, az, tl, ph in spec
    ]
    # |P - centre| <= radius <= 0.9 x the smallest half-extent: inside the box by construction
    return orbit_sequence(orbits, centre, rests, rests, rests, rotation_amplitude, name=name)


def check_workspace(
    traj, robot, rate_hz: float = 50.0, state: TrajectoryState | None = None
) -> None:
    """Raise ``ValueError`` (one sentence) if P leaves the robot's workspace box.

    Parameters
    ----------
    traj : Trajectory or SampledTrajectory
    robot : CableRobot
        Nothing is checked when its limits give no workspace box.
    rate_hz : float
        Checking rate.
    state : TrajectoryState, optional
        An evaluation to check instead of sampling ``traj`` at ``rate_hz``.
    """
    lo, hi = robot.limits.workspace_min, robot.limits.workspace_max
    if lo is None or hi is None:
        return
    if state is None:
        state = traj.evaluate(np.arange(traj.t_start, traj.t_end + 0.5 / rate_hz, 1.0 / rate_hz))
    t = np.asarray(state.t)
    p = np.asarray(state.p)
    bad = np.nonzero(np.any((p < np.asarray(lo) - 1e-9) | (p > np.asarray(hi) + 1e-9), axis=1))[0]
    if bad.size:
        k = int(bad[0])
        raise ValueError(
            f"the trajectory leaves the workspace box {list(lo)}..{list(hi)} m at t = {t[k]:.3g} s "
            f"(P = [{p[k, 0]:.3f}, {p[k, 1]:.3f}, {p[k, 2]:.3f}] m)."
        )


# ----------------------------------------------------------------------------- sampled


def _hermite5(s, h, y0, d0, dd0, y1, d1, dd1):
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    s5 = s4 * s
    H0 = 1 - 10 * s3 + 15 * s4 - 6 * s5
    H1 = s - 6 * s3 + 8 * s4 - 3 * s5
    H2 = 0.5 * (s2 - 3 * s3 + 3 * s4 - s5)
    H3 = 10 * s3 - 15 * s4 + 6 * s5
    H4 = -4 * s3 + 7 * s4 - 3 * s5
    H5 = 0.5 * (s3 - 2 * s4 + s5)
    return H0 * y0 + H1 * h * d0 + H2 * h * h * dd0 + H3 * y1 + H4 * h * d1 + H5 * h * h * dd1


class SampledTrajectory(eqx.Module):
    """A trajectory given by samples (e.g. read from CSV); see the module docstring.

    Attributes
    ----------
    t : (n,)
    p, v, a : (n, 3)
    q : (n, 4) or None
    omega, alpha : (n, 3) or None
    rotation : Rotation or None
        An analytic rotation added by :func:`with_rotation` (only when q is None).
    """

    t: jnp.ndarray
    p: jnp.ndarray
    v: jnp.ndarray
    a: jnp.ndarray
    q: jnp.ndarray | None = None
    omega: jnp.ndarray | None = None
    alpha: jnp.ndarray | None = None
    rotation: Rotation | None = None
    name: str = eqx.field(static=True, default="sampled")

    @property
    def has_rotation(self) -> bool:
        """True when the platform rotates."""
        return self.q is not None or (
            self.rotation is not None and bool(np.any(np.asarray(self.rotation.amplitude) != 0))
        )

    @property
    def t_start(self) -> float:
        """First sample time, s."""
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        """Last sample time, s."""
        return float(self.t[-1])

    @property
    def duration(self) -> float:
        """Last sample time, s."""
        return float(self.t[-1])

    def _segment(self, t):
        tc = jnp.clip(t, self.t[0], self.t[-1])
        k = jnp.clip(jnp.searchsorted(self.t, tc, side="right") - 1, 0, self.t.shape[0] - 2)
        h = self.t[k + 1] - self.t[k]
        return k, h, (tc - self.t[k]) / h

    def position(self, t):
        """Interpolated position (3,) at a scalar time t."""
        k, h, s = self._segment(t)
        return _hermite5(
            s, h, self.p[k], self.v[k], self.a[k], self.p[k + 1], self.v[k + 1], self.a[k + 1]
        )

    def quat(self, t):
        """Interpolated, renormalised quaternion (4,) at a scalar time t."""
        k, h, s = self._segment(t)

        def qdots(i):
            q = self.q[i]
            wq = jnp.concatenate([jnp.zeros(1), self.omega[i]])
            aq = jnp.concatenate([jnp.zeros(1), self.alpha[i]])
            qd = 0.5 * quat_multiply(wq, q)
            qdd = 0.5 * (quat_multiply(aq, q) + quat_multiply(wq, qd))
            return q, qd, qdd

        q0, d0, dd0 = qdots(k)
        q1, d1, dd1 = qdots(k + 1)
        q1 = jnp.where(q0 @ q1 < 0, -1.0, 1.0) * q1
        d1 = jnp.where(q0 @ self.q[k + 1] < 0, -1.0, 1.0) * d1
        dd1 = jnp.where(q0 @ self.q[k + 1] < 0, -1.0, 1.0) * dd1
        h_ = _hermite5(s, h, q0, d0, dd0, q1, d1, dd1)
        return h_ / jnp.linalg.norm(h_)

    def _one(self, t):
        p, v, a, j = _derivs(self.position, t, 3)
        if self.q is not None:
            q, w, al = _rotation_state(self.quat, t)
        elif self.rotation is not None:
            q, w, al = _rotation_state(self.rotation.quat, t)
        else:
            q, w, al = _IDENTITY
        return p, v, a, j, q, w, al

    def evaluate(self, t) -> TrajectoryState:
        """Evaluate the motion at times t (exact at the sample times).

        Parameters
        ----------
        t : array (n,)

        Returns
        -------
        TrajectoryState
        """
        return _evaluate_padded(self, t)
