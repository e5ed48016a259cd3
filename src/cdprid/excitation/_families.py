"""Trajectory families of the excitation optimiser, and the move from and back to home.

Families (all smooth in their parameters, every motion ramps in and out of rest with the
septic smoothstep of :mod:`cdprid.model._trajectories`):

- ``orbit``: one orbit (centre, radius, frequency, plane azimuth and tilt, phase);
- ``orbits``: K orbits (default 4, as in the paper) about a common centre, each in its own
  plane with its own radius, frequency and phase;
- ``fourier``: a Fourier series (H harmonics of a base frequency) of the position and of a
  small rotation vector, for the 10-parameter model (omega and alpha enter the regressor).

:class:`HomedTrajectory` adds a rest-to-rest move (septic smoothstep: continuous jerk) from
the home pose to the family's start point, and the same move back at the end
(:mod:`cdprid.excitation._homed`); :class:`FourierTrajectory` and the ramped envelopes are in
:mod:`cdprid.excitation._fourier_trajectory`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.excitation._fourier_trajectory import FourierTrajectory, _envelope, _leibniz
from cdprid.excitation._homed import HomedTrajectory, move_duration
from cdprid.model import (
    Trajectory,
    TrajectoryState,
)

__all__ = [
    "FAMILIES",
    "REST_S",
    "OrbitFamily",
    "FourierFamily",
    "FourierTrajectory",
    "HomedTrajectory",
    "make_family",
    "move_duration",
]

FAMILIES = ("orbit", "orbits", "fourier")
REST_S = 0.5  # s, rest before, between and after orbits
_REST = REST_S

# =============================================================================== families


def _sig(z, lo, hi):
    return lo + (hi - lo) * jax.nn.sigmoid(z)


def _logit(x, lo, hi):
    u = np.clip((np.asarray(x, float) - lo) / (hi - lo), 1e-6, 1 - 1e-6)
    return np.log(u / (1 - u))


def _plane(azimuth, tilt):
    ca, sa, ct, st = jnp.cos(azimuth), jnp.sin(azimuth), jnp.cos(tilt), jnp.sin(tilt)
    e1 = jnp.stack([ca, sa, jnp.zeros_like(ca)], axis=-1)
    e2 = jnp.stack([-sa * ct, ca * ct, st], axis=-1)
    return e1, e2


class OrbitFamily(eqx.Module):
    """K ramped orbits about a common centre (K = 1: the ``orbit`` family).

    Physical parameters (dict): ``centre`` (3,), ``radius``, ``frequency``, ``azimuth``,
    ``tilt``, ``phase`` (each (K,)). The optimiser works on unconstrained coordinates z;
    centre, radius and frequency are mapped into boxes by sigmoids.
    """

    n_orbits: int = eqx.field(static=True)
    duration: float = eqx.field(static=True)
    box_lo: tuple = eqx.field(static=True)
    box_hi: tuple = eqx.field(static=True)
    radius_max: float = eqx.field(static=True, default=1.2)
    freq_max: float = eqx.field(static=True, default=1.0)
    name: str = eqx.field(static=True, default="orbit")

    @property
    def rotates(self) -> bool:
        """False: orbits do not rotate the platform."""
        return False

    @property
    def segment(self) -> float:
        """Duration of each orbit, s (the rests of :data:`REST_S` excluded)."""
        K = self.n_orbits
        return (self.duration - (K + 1) * _REST) / K

    @property
    def ramp(self) -> float:
        """Ramp-in and ramp-out time of each orbit, s (at most 2 s)."""
        return min(2.0, 0.5 * self.segment)

    @property
    def n_params(self) -> int:
        """Number of coordinates, ``3 + 5 K``."""
        return 3 + 5 * self.n_orbits

    def to_params(self, z) -> dict:
        """Physical parameters of coordinates z (differentiable).

        Parameters
        ----------
        z : array (n_params,)
            Unconstrained coordinates.

        Returns
        -------
        dict
            ``centre`` (3,) m; ``radius`` (K,) m; ``frequency`` (K,) Hz; ``azimuth``, ``tilt``,
            ``phase`` (K,) rad.
        """
        K = self.n_orbits
        lo, hi = jnp.asarray(self.box_lo), jnp.asarray(self.box_hi)
        return {
            "centre": _sig(z[:3], lo, hi),
            "radius": _sig(z[3:3 + K], 0.02, self.radius_max),
            "frequency": _sig(z[3 + K:3 + 2 * K], 0.05, self.freq_max),
            "azimuth": z[3 + 2 * K:3 + 3 * K],
            "tilt": z[3 + 3 * K:3 + 4 * K],
            "phase": z[3 + 4 * K:3 + 5 * K],
        }

    def from_params(self, params: dict) -> np.ndarray:
        """Coordinates of physical parameters (inverse of :meth:`to_params`).

        Parameters
        ----------
        params : dict
            As returned by :meth:`to_params`; a scalar per-orbit entry is broadcast to K.

        Returns
        -------
        ndarray (n_params,)
            Values at the sigmoid boxes' edges are clipped just inside.
        """
        K = self.n_orbits
        lo, hi = np.asarray(self.box_lo), np.asarray(self.box_hi)

        def vec(key):
            return np.broadcast_to(np.asarray(params[key], float), (K,))

        return np.concatenate([
            _logit(params["centre"], lo, hi),
            _logit(vec("radius"), 0.02, self.radius_max),
            _logit(vec("frequency"), 0.05, self.freq_max),
            vec("azimuth"), vec("tilt"), vec("phase"),
        ])

    def initial_params(self, robot=None, radius=0.4, frequency=0.25) -> dict:
        """The paper-like design: horizontal orbits (radius 0.4 m, 0.25 Hz) about the box centre.

        With K > 1 the orbits are in the xy, xz, yz, xy... planes (paper section 7). The radius
        is reduced to fit a small workspace (70 % of the smaller horizontal half extent).

        Parameters
        ----------
        robot : CableRobot, optional
            Unused (the same signature as :meth:`FourierFamily.initial_params`).
        radius : float
            Orbit radius before the workspace fit, m.
        frequency : float
            Orbit frequency, Hz.

        Returns
        -------
        dict
            Physical parameters (:meth:`to_params`).
        """
        radius = _fitting_radius(self.box_lo, self.box_hi, radius)
        K = self.n_orbits
        planes = [(0.0, 0.0), (0.0, np.pi / 2), (np.pi / 2, np.pi / 2), (np.pi / 4, 0.0)]
        az = [planes[k % 4][0] for k in range(K)]
        tl = [planes[k % 4][1] for k in range(K)]
        return {
            "centre": _box_centre(self.box_lo, self.box_hi),
            "radius": np.full(K, radius),
            "frequency": np.full(K, frequency),
            "azimuth": np.array(az),
            "tilt": np.array(tl),
            "phase": np.zeros(K),
        }

    def scale_amplitude(self, params: dict, k: float) -> dict:
        """The same design with every radius multiplied by k (peaks scale about linearly).

        Parameters
        ----------
        params : dict
            Physical parameters.
        k : float
            Factor; radii are kept at 0.021 m or more.

        Returns
        -------
        dict
        """
        return dict(params, radius=np.maximum(np.asarray(params["radius"], float) * k, 0.021))

    def trajectory(self, z) -> Trajectory:
        """The :class:`cdprid.model.Trajectory` of coordinates z (differentiable).

        Parameters
        ----------
        z : array (n_params,)
            Unconstrained coordinates.

        Returns
        -------
        Trajectory
        """
        P = self.to_params(z)
        K = self.n_orbits
        seg = self.segment
        t0 = _REST + jnp.arange(K) * (seg + _REST)
        e1, e2 = _plane(P["azimuth"], P["tilt"])
        return Trajectory(
            rest=P["centre"],
            t0=t0,
            T=jnp.full(K, seg),
            ramp=jnp.full(K, self.ramp),
            radius=P["radius"],
            freq=P["frequency"],
            phase=P["phase"],
            centre=jnp.broadcast_to(P["centre"], (K, 3)),
            e1=e1,
            e2=e2,
            rotation=None,
            duration=float(self.duration),
            name=f"excitation-{self.name}",
        )

    def states(self, z, t) -> TrajectoryState:
        """Motion at times t, closed-form derivatives, vectorised over t and the K orbits.

        Envelope x circle, Leibniz rule, as in :mod:`cdprid.model._trajectories`.

        Parameters
        ----------
        z : array (n_params,)
            Unconstrained coordinates.
        t : array (n,)
            Times, s.

        Returns
        -------
        TrajectoryState
            Position (m), velocity, acceleration, jerk, quaternion, angular velocity (rad/s) and
            acceleration (rad/s^2), base frame, each with n rows.
        """
        P = self.to_params(z)
        K = self.n_orbits
        seg = self.segment
        t0 = _REST + jnp.arange(K) * (seg + _REST)
        e1, e2 = _plane(P["azimuth"], P["tilt"])  # (K, 3)
        u = t[:, None] - t0[None, :]  # (n, K)
        env = _envelope(u, seg, self.ramp)
        w = 2.0 * jnp.pi * P["frequency"]
        th = P["phase"] + w * u
        circ = []
        for k in range(4):
            c = P["radius"] * w**k
            thk = th + k * jnp.pi / 2
            circ.append(c[..., None] * (jnp.cos(thk)[..., None] * e1
                                        + jnp.sin(thk)[..., None] * e2))
        d = [jnp.sum(x, axis=1) for x in _leibniz(env, circ)]  # (n, 3) each
        n = t.shape[0]
        q = jnp.broadcast_to(jnp.array([1.0, 0.0, 0.0, 0.0]), (n, 4))
        zero = jnp.zeros((n, 3))
        return TrajectoryState(t, P["centre"] + d[0], d[1], d[2], d[3], q, zero, zero)


class FourierFamily(eqx.Module):
    """Fourier series of position and rotation vector (``fourier`` family).

    Physical parameters: ``centre`` (3,), ``P_cos``, ``P_sin`` (H, 3) in m, ``R_cos``,
    ``R_sin`` (H, 3) in rad; base frequency ``f0`` fixed.
    """

    harmonics: int = eqx.field(static=True)
    f0: float = eqx.field(static=True)
    duration: float = eqx.field(static=True)
    box_lo: tuple = eqx.field(static=True)
    box_hi: tuple = eqx.field(static=True)
    ramp: float = eqx.field(static=True, default=2.0)
    name: str = eqx.field(static=True, default="fourier")

    @property
    def rotates(self) -> bool:
        """True: the family rotates the platform."""
        return True

    @property
    def n_params(self) -> int:
        """Number of coordinates, ``3 + 12 H``."""
        return 3 + 12 * self.harmonics

    # coordinates: position coefficients in units of 0.1 m, rotation ones of 0.05 rad
    def to_params(self, z) -> dict:
        """Physical parameters of coordinates z (differentiable).

        Coordinates: the centre through a sigmoid into the box, position coefficients in units of
        0.1 m, rotation ones of 0.05 rad.

        Parameters
        ----------
        z : array (n_params,)
            Unconstrained coordinates.

        Returns
        -------
        dict
            ``centre`` (3,) m; ``P_cos``, ``P_sin`` (H, 3) m; ``R_cos``, ``R_sin`` (H, 3) rad.
        """
        H = self.harmonics
        lo, hi = jnp.asarray(self.box_lo), jnp.asarray(self.box_hi)
        c = z[3:].reshape(4, H, 3)
        return {"centre": _sig(z[:3], lo, hi), "P_cos": 0.1 * c[0], "P_sin": 0.1 * c[1],
                "R_cos": 0.05 * c[2], "R_sin": 0.05 * c[3]}

    def from_params(self, params: dict) -> np.ndarray:
        """Coordinates of physical parameters (inverse of :meth:`to_params`).

        Parameters
        ----------
        params : dict
            As returned by :meth:`to_params`.

        Returns
        -------
        ndarray (n_params,)
        """
        lo, hi = np.asarray(self.box_lo), np.asarray(self.box_hi)
        parts = [np.asarray(params[k], float).reshape(self.harmonics, 3) / s
                 for k, s in (("P_cos", 0.1), ("P_sin", 0.1), ("R_cos", 0.05), ("R_sin", 0.05))]
        return np.concatenate([_logit(params["centre"], lo, hi)] + [p.ravel() for p in parts])

    def initial_params(self, robot=None, radius=0.4, frequency=None, rotation=0.05) -> dict:
        """Paper-like horizontal orbit (first harmonic) plus a small rotation per axis.

        Parameters
        ----------
        robot : CableRobot, optional
            Unused (the same signature as :meth:`OrbitFamily.initial_params`).
        radius : float
            Orbit radius before the workspace fit (70 % of the smaller horizontal half extent), m.
        frequency : float, optional
            Unused: the orbit runs at the family's ``f0``.
        rotation : float
            Rotation amplitude per axis, rad.

        Returns
        -------
        dict
            Physical parameters (:meth:`to_params`).
        """
        radius = _fitting_radius(self.box_lo, self.box_hi, radius)
        H = self.harmonics
        P_cos = np.zeros((H, 3))
        P_sin = np.zeros((H, 3))
        P_cos[0, 0] = radius
        P_sin[0, 1] = radius
        R_cos = np.zeros((H, 3))
        R_sin = np.zeros((H, 3))
        R_sin[0] = [rotation, 0.0, 0.0]
        R_cos[0] = [0.0, rotation, 0.0]
        R_sin[min(1, H - 1), 2] = rotation
        return {"centre": _box_centre(self.box_lo, self.box_hi), "P_cos": P_cos, "P_sin": P_sin,
                "R_cos": R_cos, "R_sin": R_sin}

    def scale_amplitude(self, params: dict, k: float) -> dict:
        """The same design with every position and rotation coefficient multiplied by k.

        Parameters
        ----------
        params : dict
            Physical parameters.
        k : float
            Factor.

        Returns
        -------
        dict
        """
        return dict(params, **{key: np.asarray(params[key], float) * k
                               for key in ("P_cos", "P_sin", "R_cos", "R_sin")})

    def trajectory(self, z) -> FourierTrajectory:
        """The :class:`FourierTrajectory` of coordinates z (differentiable).

        Parameters
        ----------
        z : array (n_params,)
            Unconstrained coordinates.

        Returns
        -------
        FourierTrajectory
        """
        P = self.to_params(z)
        return FourierTrajectory(
            centre=P["centre"], P_cos=P["P_cos"], P_sin=P["P_sin"], R_cos=P["R_cos"],
            R_sin=P["R_sin"], f0=float(self.f0), t_a=_REST, t_b=float(self.duration) - _REST,
            ramp=float(self.ramp), duration=float(self.duration),
        )

    def states(self, z, t) -> TrajectoryState:
        """Motion at times t (:meth:`FourierTrajectory.states` of :meth:`trajectory`).

        Parameters
        ----------
        z : array (n_params,)
            Unconstrained coordinates.
        t : array (n,)
            Times, s.

        Returns
        -------
        TrajectoryState
            Position (m), velocity, acceleration, jerk, quaternion, angular velocity (rad/s) and
            acceleration (rad/s^2), base frame, each with n rows.
        """
        return self.trajectory(z).states(t)


def _box_centre(box_lo, box_hi) -> np.ndarray:
    return 0.5 * (np.asarray(box_lo, float) + np.asarray(box_hi, float))


def _fitting_radius(box_lo, box_hi, radius: float) -> float:
    """The paper's 0.4 m orbit radius, reduced to 70 % of the smaller horizontal half extent."""
    h = 0.5 * (np.asarray(box_hi) - np.asarray(box_lo))
    return float(min(radius, 0.7 * min(h[0], h[1])))


def make_family(name: str, box_lo, box_hi, duration: float | None = None,
                n_orbits: int = 4, harmonics: int = 3, f0: float = 0.25):
    """Build a family by name (``orbit``, ``orbits`` or ``fourier``) for a workspace box.

    Parameters
    ----------
    name : {"orbit", "orbits", "fourier"}
    box_lo, box_hi : sequence of 3 floats
        Workspace box of P, base frame, m.
    duration : float, optional
        Duration of the exciting part, s (default 20 orbit, 52 orbits, 30 fourier).
    n_orbits : int
        Number of orbits of the ``orbits`` family.
    harmonics : int
        Number of harmonics of the ``fourier`` family.
    f0 : float
        Base frequency of the ``fourier`` family, Hz.

    Returns
    -------
    OrbitFamily or FourierFamily

    Raises
    ------
    InputError
        Unknown ``name``, or a duration too short for the family.
    """
    lo = tuple(float(v) for v in box_lo)
    hi = tuple(float(v) for v in box_hi)
    rmax = float(min(1.2, 0.5 * max(hi[k] - lo[k] for k in range(3))))
    if name == "orbit":
        d = 20.0 if duration is None else float(duration)
        fam = OrbitFamily(1, d, lo, hi, radius_max=rmax, name="orbit")
    elif name == "orbits":
        d = 52.0 if duration is None else float(duration)
        fam = OrbitFamily(int(n_orbits), d, lo, hi, radius_max=rmax, name="orbits")
    elif name == "fourier":
        d = 30.0 if duration is None else float(duration)
        fam = FourierFamily(int(harmonics), float(f0), d, lo, hi)
    else:
        raise InputError(f"unknown excitation family {name!r}; use one of {', '.join(FAMILIES)}.")
    min_d = (5.0 * (n_orbits if name == "orbits" else 1) + 2 * _REST)
    if not np.isfinite(d) or d < min_d:
        raise InputError(f"the duration of the {name!r} family must be at least {min_d:g} s, "
                         f"got {d:g} s.")
    return fam
