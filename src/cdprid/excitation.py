"""Optimal excitation trajectories: a differentiable identifiability objective, constraints,
a jit-compiled multi-start optimiser and a CasADi tension-feasibility certificate.

Objective (paper section 4). Along a trajectory sampled at times t_k the identification stacks
``W_ID = [A_1; ...; A_ne]`` (eq. 11) with ``A_k`` the regressor of eq. (10)
(:func:`cdprid.dynamics.regressor_translation`) or of the 10-parameter model
(:func:`cdprid.dynamics.regressor_full`), built here from the trajectory's *analytic*
accelerations. With the information matrix ``M = W_ID^T W_ID`` (p x p):

- ``cond(W_ID) = sqrt(lambda_max(M) / lambda_min(M))`` (raw) and the same after scaling
  every column of W_ID to unit norm (``cond_scaled``);
- D-optimality ``-log det(M / n_rows + delta I)``;
- predicted standard deviations ``sigma_x = sigma_rho sqrt(diag(M^-1))`` (eq. 20), and
  relative ones ``sigma_x / |x_nominal|`` (eq. 21).

Inside the optimiser the condition number is replaced by a smooth surrogate without any
eigen-decomposition (no trouble at repeated singular values):
``lambda_max ~ tr(M^k)^(1/k)`` and ``lambda_min ~ tr(M^-k)^(-1/k)`` with k = 32, computed by
repeated normalised squaring; it bounds the exact value from above by at most a factor
``p^(1/k)`` (< 1.08 for p = 10).

Constraints, evaluated on the samples:

- the workspace box of robot.toml ``[limits]`` (position of P);
- the cable speed ``|dl_i/dt| <= cable_speed_max`` with ``dl/dt`` the exact directional
  derivative of :func:`cdprid.geometry.cable_lengths` along (v, omega);
- tension feasibility: some ``tau`` in ``[tension_min, tension_max]`` with ``W tau = w``, w the
  wrench of :func:`cdprid.dynamics.platform_wrench` for the nominal platform of robot.toml.
  The optimiser uses a smooth, conservative margin: the centred least-norm distribution
  ``tau = tau_mid + W^+ (w - W tau_mid)`` and a soft minimum of its distances to the bounds.
  Afterwards a per-sample linear programme solved through CasADi's conic interface (HiGHS)
  certifies the largest achievable margin ``max s : W tau = w, tmin + s <= tau <= tmax - s`` on
  a 100 Hz grid. An uncertified trajectory is never returned: the optimiser falls back to the
  best certified start, else to the initial design (if certified), and says so.

Families (all smooth in their parameters, every motion ramps in and out of rest with the
septic smoothstep of :mod:`cdprid.trajectories`):

- ``orbit``: one orbit (centre, radius, frequency, plane azimuth and tilt, phase);
- ``orbits``: K orbits (default 4, as in the paper) about a common centre, each in its own
  plane with its own radius, frequency and phase;
- ``fourier``: a Fourier series (H harmonics of a base frequency) of the position and of a
  small rotation vector, for the 10-parameter model (omega and alpha enter the regressor).
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .dynamics import PARAMETER_NAMES, InertialParameters, platform_wrench, regressor
from .geometry import CableRobot, wrench_matrix
from .rotations import angular_rates_from_quat, quat_to_matrix, rotvec_to_quat
from .trajectories import Trajectory, TrajectoryState, _smoothstep7_derivs

__all__ = [
    "FAMILIES",
    "OBJECTIVES",
    "ExcitationProblem",
    "ExcitationResult",
    "DesignReport",
    "OrbitFamily",
    "FourierFamily",
    "FourierTrajectory",
    "make_family",
    "make_problem",
    "stacked_regressor",
    "information_cond",
    "soft_log_cond",
    "d_optimality",
    "predicted_sigma",
    "tension_margin_smooth",
    "certify_tensions",
    "evaluate_design",
    "optimise_excitation",
    "start_points",
    "slsqp_baseline",
]

FAMILIES = ("orbit", "orbits", "fourier")
OBJECTIVES = ("cond", "cond_scaled", "dopt", "sigma")

_REST = 0.5  # s, rest before, between and after orbits


# =============================================================================== objective


def stacked_regressor(states: TrajectoryState, gravity, model: str = "translation"):
    """W_ID (6 n, p) of eq. (11) from analytic motion states (vmapped per-sample regressor)."""
    R = jax.vmap(quat_to_matrix)(states.q)
    A = jax.vmap(lambda R_, a, w, al: regressor(model, R_, a, w, al, gravity))(
        R, states.a, states.omega, states.alpha
    )
    return A.reshape(-1, A.shape[-1])


def _scale_columns(M):
    d = jnp.sqrt(jnp.diag(M))
    return M / (d[:, None] * d[None, :])


def information_cond(W_ID, scaled: bool = False):
    """Exact cond(W_ID) from the eigenvalues of ``M = W_ID^T W_ID`` (differentiable when the
    extreme eigenvalues are simple). ``scaled=True``: columns scaled to unit norm first."""
    M = W_ID.T @ W_ID
    if scaled:
        M = _scale_columns(M)
    lam = jnp.linalg.eigvalsh(M)
    return jnp.sqrt(lam[-1] / lam[0])


def _log_trace_power(M, n_squarings: int):
    """log tr(M^(2^n)) by normalised repeated squaring (M symmetric positive definite)."""
    s0 = jnp.trace(M)
    X = M / s0
    L = jnp.log(s0)
    for _ in range(n_squarings):
        X = X @ X
        s = jnp.trace(X)
        X = X / s
        L = 2.0 * L + jnp.log(s)
    return L


def soft_log_cond(M, n_squarings: int = 5):
    """Smooth upper bound of ``log cond(W_ID)`` from the information matrix M (p x p).

    ``0.5 (log tr(M^k) - log tr(M^-k)) / k`` with ``k = 2^n_squarings``; exceeds the exact
    value by at most ``log(p) / k``.
    """
    k = 2.0**n_squarings
    p = M.shape[0]
    Minv = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(M), jnp.eye(p))
    Minv = 0.5 * (Minv + Minv.T)
    return 0.5 * (_log_trace_power(M, n_squarings) + _log_trace_power(Minv, n_squarings)) / k


def d_optimality(W_ID, delta: float = 1e-9):
    """D-optimality criterion ``-log det(W_ID^T W_ID / n_rows + delta I)`` (smaller is better)."""
    p = W_ID.shape[1]
    M = W_ID.T @ W_ID / W_ID.shape[0] + delta * jnp.eye(p)
    return -2.0 * jnp.sum(jnp.log(jnp.diag(jnp.linalg.cholesky(M))))


def predicted_sigma(W_ID, sigma_rho: float = 1.0):
    """Predicted standard deviations (p,) ``sigma_rho sqrt(diag((W^T W)^-1))`` (eq. 20), via QR."""
    R = jnp.linalg.qr(W_ID, mode="r")
    Rinv = jax.scipy.linalg.solve_triangular(R, jnp.eye(R.shape[0]), lower=False)
    return sigma_rho * jnp.sqrt(jnp.sum(Rinv**2, axis=1))


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


_BINOM = ((1,), (1, 1), (1, 2, 1), (1, 3, 3, 1))


def _envelope(u, T, ramp):
    """Envelope ``e(u) = S(u / ramp) S((T - u) / ramp)`` and 3 derivatives (Leibniz rule)."""
    g1 = _smoothstep7_derivs(u / ramp, ramp, 1.0, 3)
    g2 = _smoothstep7_derivs((T - u) / ramp, ramp, -1.0, 3)
    return [sum(_BINOM[n][k] * g1[k] * g2[n - k] for k in range(n + 1)) for n in range(4)]


def _leibniz(env, f):
    """Derivatives 0..3 of ``env * f`` (env[..., None] broadcast against f)."""
    return [sum(_BINOM[n][k] * env[k][..., None] * f[n - k] for k in range(n + 1)) for n in range(4)]


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
        return False

    @property
    def segment(self) -> float:
        K = self.n_orbits
        return (self.duration - (K + 1) * _REST) / K

    @property
    def ramp(self) -> float:
        return min(2.0, 0.5 * self.segment)

    @property
    def n_params(self) -> int:
        return 3 + 5 * self.n_orbits

    def to_params(self, z) -> dict:
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

    def initial_params(self, robot: CableRobot, radius=0.4, frequency=0.25) -> dict:
        """The paper-like design: horizontal orbits (radius 0.4 m, 0.25 Hz) about the box centre.

        With K > 1 the orbits are in the xy, xz, yz, xy... planes (paper section 7).
        """
        K = self.n_orbits
        planes = [(0.0, 0.0), (0.0, np.pi / 2), (np.pi / 2, np.pi / 2), (np.pi / 4, 0.0)]
        az = [planes[k % 4][0] for k in range(K)]
        tl = [planes[k % 4][1] for k in range(K)]
        return {
            "centre": _box_centre(robot),
            "radius": np.full(K, radius),
            "frequency": np.full(K, frequency),
            "azimuth": np.array(az),
            "tilt": np.array(tl),
            "phase": np.zeros(K),
        }

    def trajectory(self, z) -> Trajectory:
        """The :class:`cdprid.trajectories.Trajectory` of coordinates z (differentiable)."""
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
        """Motion at times t (n,): closed-form derivatives (envelope x circle, Leibniz rule,
        as in :mod:`cdprid.trajectories`), vectorised over t and the K orbits."""
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
            circ.append(c[..., None] * (jnp.cos(thk)[..., None] * e1 + jnp.sin(thk)[..., None] * e2))
        d = [jnp.sum(x, axis=1) for x in _leibniz(env, circ)]  # (n, 3) each
        n = t.shape[0]
        q = jnp.broadcast_to(jnp.array([1.0, 0.0, 0.0, 0.0]), (n, 4))
        zero = jnp.zeros((n, 3))
        return TrajectoryState(t, P["centre"] + d[0], d[1], d[2], d[3], q, zero, zero)


class FourierTrajectory(eqx.Module):
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
        return True

    @property
    def t_start(self) -> float:
        return 0.0

    @property
    def t_end(self) -> float:
        return float(self.duration)

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
        """Position of P (3,) at a scalar time t."""
        return self.centre + self._series_derivs(self.P_cos, self.P_sin, jnp.atleast_1d(t))[0][0]

    def quat(self, t):
        """Quaternion (4,), scalar first, platform -> base, at a scalar time t."""
        return rotvec_to_quat(self._series_derivs(self.R_cos, self.R_sin, jnp.atleast_1d(t))[0][0])

    def states(self, t) -> TrajectoryState:
        """Motion at times t (n,), closed-form derivatives; q = exp(rho), omega and alpha from
        dq/dt and d2q/dt2 (nested forward-mode derivatives of exp along rho(t))."""
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
        """Evaluate the motion at times t (n,) (same contract as ``Trajectory.evaluate``)."""
        return _fourier_eval(self, jnp.atleast_1d(jnp.asarray(t, float)))


@eqx.filter_jit
def _fourier_eval(traj, t):
    return traj.states(t)


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
        return True

    @property
    def n_params(self) -> int:
        return 3 + 12 * self.harmonics

    # coordinates: position coefficients in units of 0.1 m, rotation ones of 0.05 rad
    def to_params(self, z) -> dict:
        H = self.harmonics
        lo, hi = jnp.asarray(self.box_lo), jnp.asarray(self.box_hi)
        c = z[3:].reshape(4, H, 3)
        return {"centre": _sig(z[:3], lo, hi), "P_cos": 0.1 * c[0], "P_sin": 0.1 * c[1],
                "R_cos": 0.05 * c[2], "R_sin": 0.05 * c[3]}

    def from_params(self, params: dict) -> np.ndarray:
        lo, hi = np.asarray(self.box_lo), np.asarray(self.box_hi)
        parts = [np.asarray(params[k], float).reshape(self.harmonics, 3) / s
                 for k, s in (("P_cos", 0.1), ("P_sin", 0.1), ("R_cos", 0.05), ("R_sin", 0.05))]
        return np.concatenate([_logit(params["centre"], lo, hi)] + [p.ravel() for p in parts])

    def initial_params(self, robot: CableRobot, radius=0.4, frequency=None, rotation=0.05) -> dict:
        """Paper-like horizontal orbit (first harmonic) plus a small rotation (rad) about each axis."""
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
        return {"centre": _box_centre(robot), "P_cos": P_cos, "P_sin": P_sin,
                "R_cos": R_cos, "R_sin": R_sin}

    def trajectory(self, z) -> FourierTrajectory:
        P = self.to_params(z)
        return FourierTrajectory(
            centre=P["centre"], P_cos=P["P_cos"], P_sin=P["P_sin"], R_cos=P["R_cos"],
            R_sin=P["R_sin"], f0=float(self.f0), t_a=_REST, t_b=float(self.duration) - _REST,
            ramp=float(self.ramp), duration=float(self.duration),
        )

    def states(self, z, t) -> TrajectoryState:
        return self.trajectory(z).states(t)


def _box(robot: CableRobot):
    lim = robot.limits
    if lim.workspace_min is not None and lim.workspace_max is not None:
        return tuple(lim.workspace_min), tuple(lim.workspace_max)
    # no box in robot.toml: the exit points' bounding box shrunk by 25 %, below the exits
    A = np.asarray(robot.B_A)
    lo, hi = A.min(axis=0), A.max(axis=0)
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    lo2, hi2 = c - 0.75 * h, c + 0.75 * h
    hi2[2] = max(hi2[2] - 0.3, lo2[2] + 0.1)
    return tuple(float(v) for v in lo2), tuple(float(v) for v in hi2)


def _box_centre(robot: CableRobot) -> np.ndarray:
    lo, hi = (np.asarray(b) for b in _box(robot))
    c = 0.5 * (lo + hi)
    c[2] = float(np.clip(1.2, lo[2], hi[2]))  # as trajectories.preset
    return c


def make_family(name: str, robot: CableRobot, duration: float | None = None,
                n_orbits: int = 4, harmonics: int = 3, f0: float = 0.25):
    """Build a family by name (``orbit``, ``orbits`` or ``fourier``) for a robot's workspace box."""
    lo, hi = _box(robot)
    if name == "orbit":
        d = 20.0 if duration is None else float(duration)
        fam = OrbitFamily(1, d, lo, hi, name="orbit")
    elif name == "orbits":
        d = 52.0 if duration is None else float(duration)
        fam = OrbitFamily(int(n_orbits), d, lo, hi, name="orbits")
    elif name == "fourier":
        d = 30.0 if duration is None else float(duration)
        fam = FourierFamily(int(harmonics), float(f0), d, lo, hi)
    else:
        raise ValueError(f"unknown excitation family {name!r}; use one of {', '.join(FAMILIES)}.")
    min_d = (5.0 * (n_orbits if name == "orbits" else 1) + 2 * _REST)
    if not np.isfinite(d) or d < min_d:
        raise ValueError(f"the duration of the {name!r} family must be at least {min_d:g} s, got {d:g} s.")
    return fam


# =============================================================================== constraints


def _nominal(robot: CableRobot) -> InertialParameters:
    pl = robot.platform
    mass = 10.0 if pl.mass is None else pl.mass
    com = (0.0, 0.0, 0.0) if pl.com is None else pl.com
    inertia = np.diag([0.1, 0.1, 0.1]) if pl.inertia is None else np.asarray(pl.inertia)
    return InertialParameters(mass, com, inertia)


def _tension_limits(robot: CableRobot, nominal: InertialParameters):
    lim = robot.limits
    tmin = 0.0 if lim.tension_min is None else lim.tension_min
    tmax = 20.0 * float(nominal.mass) * 9.81 if lim.tension_max is None else lim.tension_max
    if not tmax > tmin:
        raise ValueError(f"tension_max ({tmax} N) must exceed tension_min ({tmin} N).")
    return float(tmin), float(tmax)


def _wrench_no_pulleys(robot, B_p, B_R_P):
    """W (6, m) of eq. (2) for a robot without pulleys (same as geometry.wrench_matrix there)."""
    b = B_R_P @ robot.P_b.T  # (3, m)
    L = robot.B_A.T - (B_p[:, None] + b)
    u = L / jnp.linalg.norm(L, axis=0, keepdims=True)
    return jnp.concatenate([u, jnp.cross(b.T, u.T).T], axis=0)


def _required_wrench(robot, nominal, states, pulleys: bool = True):
    R = jax.vmap(quat_to_matrix)(states.q)
    wfn = wrench_matrix if pulleys else _wrench_no_pulleys
    Wm = jax.vmap(lambda p, R_: wfn(robot, p, R_))(states.p, R)
    w = jax.vmap(lambda R_, a, om, al: platform_wrench(nominal, R_, a, om, al, robot.gravity))(
        R, states.a, states.omega, states.alpha
    )
    return Wm, w


def _softmin(x, temperature):
    return -temperature * jax.nn.logsumexp(-x / temperature, axis=-1)


def tension_margin_smooth(W, w, tmin: float, tmax: float, temperature: float = 0.5):
    """Smooth, conservative tension margin (N) of one sample.

    ``tau = tau_mid + W^T (W W^T)^-1 (w - W tau_mid)`` (centred least-norm distribution); the
    margin is a soft minimum of ``tau - tmin`` and ``tmax - tau`` (never above the true
    minimum). A positive value proves feasibility; the LP margin can be larger.
    """
    mid = 0.5 * (tmin + tmax)
    tau0 = jnp.full(W.shape[1], mid)
    tau = tau0 + W.T @ _cholesky_solve(W @ W.T, w - W @ tau0)
    return _softmin(jnp.concatenate([tau - tmin, tmax - tau]), temperature)


def _cholesky_solve(A, b):
    """``A^-1 b`` for a small symmetric positive-definite ``A`` by an unrolled Cholesky.

    Written with scalar entries so that, vmapped over the samples of a trajectory, every
    operation is one fused vector operation across samples (cheaper than a batched LAPACK
    solve of 6 x 6 systems, gradients included). Same result as
    ``jnp.linalg.solve`` to rounding (tested).
    """
    n = A.shape[0]
    L = [[None] * n for _ in range(n)]
    for j in range(n):
        d = A[j, j] - sum((L[j][k] ** 2 for k in range(j)), 0.0)
        L[j][j] = jnp.sqrt(d)
        for i in range(j + 1, n):
            L[i][j] = (A[i, j] - sum((L[i][k] * L[j][k] for k in range(j)), 0.0)) / L[j][j]
    y = []
    for i in range(n):
        y.append((b[i] - sum((L[i][k] * y[k] for k in range(i)), 0.0)) / L[i][i])
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum((L[k][i] * x[k] for k in range(i + 1, n)), 0.0)) / L[i][i]
    return jnp.stack(x)


def _cable_speeds(Wm, states):
    """Cable speeds dl/dt (n, m) = J [v; omega] = -W^T [v; omega] (W = -J^T, see geometry)."""
    tw = jnp.concatenate([states.v, states.omega], axis=1)
    return -jnp.einsum("nim,ni->nm", Wm, tw)


# =============================================================================== certificate


def certify_tensions(W, w, tmin: float, tmax: float):
    """Per-sample largest tension margin (N) by a linear programme through CasADi (HiGHS).

    Parameters
    ----------
    W : array (n, 6, m)
        Wrench matrices (eq. 2). For a translation-only platform with fewer than 6 useful
        rows the equality still uses all 6.
    w : array (n, 6)
        Required wrenches.
    tmin, tmax : float
        Tension limits, N.

    Returns
    -------
    margin : ndarray (n,)
        ``max s`` such that some tau with ``W tau = w`` lies in ``[tmin + s, tmax - s]``;
        ``-inf`` where even a negative s is infeasible (W tau = w has no solution).
        Positive means the sample is feasible with that margin.
    """
    from .tensions import feasibility_margin

    return np.atleast_1d(feasibility_margin(np.asarray(W, float), np.asarray(w, float), tmin, tmax))


# =============================================================================== problem


@dataclasses.dataclass(frozen=True)
class ExcitationProblem:
    """Everything the objective needs (robot, family, model, limits, grids, weights)."""

    robot: CableRobot
    family: object
    model: str
    objective: str
    nominal: InertialParameters
    tmin: float
    tmax: float
    speed_max: float
    rate_opt_hz: float = 10.0
    sigma_rho: float = 1.0
    tension_margin_target: float = 3.0
    workspace_margin: float = 0.02
    speed_fraction: float = 0.95
    penalty: float = 30.0

    @property
    def pulleys(self) -> bool:
        return self.robot.has_pulleys

    @property
    def names(self) -> tuple:
        return PARAMETER_NAMES[self.model]

    def grid(self, rate_hz: float) -> np.ndarray:
        d = self.family.duration
        n = int(np.floor(d * rate_hz + 1e-9)) + 1
        return np.arange(n) / rate_hz


def make_problem(robot: CableRobot, family: str = "orbit", objective: str = "cond",
                 model: str | None = None, duration: float | None = None, **kw) -> ExcitationProblem:
    """An :class:`ExcitationProblem` for a robot (nominal platform and limits from robot.toml).

    ``model`` defaults to ``translation`` for the orbit families and ``full`` for ``fourier``.
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective {objective!r}; use one of {', '.join(OBJECTIVES)}.")
    fam = make_family(family, robot, duration)
    model = model or ("full" if family == "fourier" else "translation")
    if model not in PARAMETER_NAMES:
        raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")
    if model == "full" and not fam.rotates:
        raise ValueError(f"the 10-parameter model needs rotations; the {family!r} family does not "
                         "rotate (use --family fourier).")
    nominal = _nominal(robot)
    tmin, tmax = _tension_limits(robot, nominal)
    vmax = robot.limits.cable_speed_max
    return ExcitationProblem(robot, fam, model, objective, nominal, tmin, tmax,
                             np.inf if vmax is None else float(vmax), **kw)


def _objective_value(prob: ExcitationProblem, W_ID):
    M = W_ID.T @ W_ID
    if prob.objective == "cond":
        return soft_log_cond(M)
    if prob.objective == "cond_scaled":
        return soft_log_cond(_scale_columns(M))
    if prob.objective == "dopt":
        return d_optimality(W_ID, 1e-9)
    # sigma: soft maximum of the log relative predicted sigma (nominal |x| floored at 5 % of
    # the parameter group's scale so that near-zero nominal values do not dominate)
    x = prob.nominal.vector(prob.model)
    floor = jnp.where(jnp.arange(x.shape[0]) < 4, 0.05 * x[0] * 0.1, 0.01)
    floor = floor.at[0].set(0.0)
    rel = predicted_sigma(W_ID, prob.sigma_rho) / jnp.maximum(jnp.abs(x), floor)
    return jax.nn.logsumexp(jnp.log(rel) * 8.0) / 8.0


def _constraint_margins(prob: ExcitationProblem, states):
    """Per-sample margins (>= 0 feasible), each normalised: workspace, speed, tension."""
    lo = jnp.asarray(prob.family.box_lo) + prob.workspace_margin
    hi = jnp.asarray(prob.family.box_hi) - prob.workspace_margin
    ws = jnp.minimum(states.p - lo, hi - states.p) / 0.05  # (n, 3)
    Wm, w = _required_wrench(prob.robot, prob.nominal, states, prob.pulleys)
    if np.isfinite(prob.speed_max):
        sp = (prob.speed_fraction * prob.speed_max - jnp.abs(_cable_speeds(Wm, states)))
        sp = sp / (0.05 * prob.speed_max)
    else:
        sp = jnp.zeros((states.p.shape[0], 1)) + 1.0
    tm = jax.vmap(lambda W_, w_: tension_margin_smooth(W_, w_, prob.tmin, prob.tmax))(Wm, w)
    tn = (tm - prob.tension_margin_target) / 5.0
    return ws, sp, tn


def _penalised(z, prob: ExcitationProblem, t):
    states = prob.family.states(z, t)
    W_ID = stacked_regressor(states, prob.robot.gravity, prob.model)
    f = _objective_value(prob, W_ID)
    ws, sp, tn = _constraint_margins(prob, states)
    pen = sum(jnp.sum(jax.nn.relu(-c) ** 2) for c in (ws, sp, tn))
    return f + prob.penalty * pen, (f, pen)


# =============================================================================== evaluation


@dataclasses.dataclass(frozen=True)
class DesignReport:
    """Metrics of one design on the 100 Hz grid (the identification's own code path).

    ``cond``/``cond_scaled`` by numpy SVD of W_ID (:func:`cdprid.identification.condition_number`),
    ``sigma`` the predicted standard deviations at ``sigma_rho`` (N per row) and ``rel_sigma``
    relative to the nominal parameters; ``min_tension_margin_N`` from the CasADi certificate.
    """

    params: dict
    z: np.ndarray
    cond: float
    cond_scaled: float
    dopt: float
    objective: float
    sigma: dict
    rel_sigma: dict
    min_tension_margin_N: float
    workspace_ok: bool
    max_cable_speed: float
    cable_speed_ok: bool
    certified: bool

    def as_json(self) -> dict:
        return {
            "cond": self.cond, "cond_scaled": self.cond_scaled, "dopt": self.dopt,
            "objective": self.objective,
            "params": {k: np.asarray(v).tolist() for k, v in self.params.items()},
            "sigma": self.sigma, "rel_sigma": self.rel_sigma,
            "min_tension_margin_N": self.min_tension_margin_N,
            "max_cable_speed_m_s": self.max_cable_speed,
            "workspace_ok": self.workspace_ok, "cable_speed_ok": self.cable_speed_ok,
            "certified": self.certified,
        }


@eqx.filter_jit
def _eval_arrays(z, prob_arrays, t):
    prob = prob_arrays
    states = prob.family.states(z, t)
    W_ID = stacked_regressor(states, prob.robot.gravity, prob.model)
    Wm, w = _required_wrench(prob.robot, prob.nominal, states, prob.pulleys)
    speeds = _cable_speeds(Wm, states)
    return states.p, W_ID, Wm, w, speeds, _objective_value(prob, W_ID)


class _ProbModule(eqx.Module):
    """Hashable/pytree view of an ExcitationProblem for filter_jit."""

    robot: CableRobot
    family: object
    nominal: InertialParameters
    model: str = eqx.field(static=True)
    objective: str = eqx.field(static=True)
    tmin: float = eqx.field(static=True)
    tmax: float = eqx.field(static=True)
    speed_max: float = eqx.field(static=True)
    sigma_rho: float = eqx.field(static=True)
    tension_margin_target: float = eqx.field(static=True)
    workspace_margin: float = eqx.field(static=True)
    speed_fraction: float = eqx.field(static=True)
    penalty: float = eqx.field(static=True)
    pulleys: bool = eqx.field(static=True, default=True)


def _as_module(prob: ExcitationProblem) -> _ProbModule:
    return _ProbModule(prob.robot, prob.family, prob.nominal, prob.model, prob.objective,
                       prob.tmin, prob.tmax, prob.speed_max, prob.sigma_rho,
                       prob.tension_margin_target, prob.workspace_margin, prob.speed_fraction,
                       prob.penalty, prob.robot.has_pulleys)


def evaluate_design(prob: ExcitationProblem, z, rate_hz: float = 100.0,
                    certify: bool = True) -> DesignReport:
    """Metrics of coordinates z on a ``rate_hz`` grid, with the CasADi certificate."""
    from .identification import condition_number

    z = jnp.asarray(z, float)
    t = jnp.asarray(prob.grid(rate_hz))
    p, W_ID, Wm, w, speeds, obj = _eval_arrays(z, _as_module(prob), t)
    W_ID = np.asarray(W_ID)
    p = np.asarray(p)
    lo, hi = np.asarray(prob.family.box_lo), np.asarray(prob.family.box_hi)
    ws_ok = bool(np.all((p >= lo - 1e-9) & (p <= hi + 1e-9)))
    vmax_used = float(np.max(np.abs(np.asarray(speeds))))
    sp_ok = bool(vmax_used <= prob.speed_max + 1e-9)
    if certify:
        margin = float(np.min(certify_tensions(Wm, w, prob.tmin, prob.tmax)))
    else:
        margin = float("nan")
    sig = np.asarray(predicted_sigma(jnp.asarray(W_ID), prob.sigma_rho))
    x = np.asarray(prob.nominal.vector(prob.model))
    with np.errstate(divide="ignore"):
        rel = sig / np.abs(x)
    params = {k: np.asarray(v) for k, v in prob.family.to_params(z).items()}
    return DesignReport(
        params=params, z=np.asarray(z),
        cond=condition_number(W_ID), cond_scaled=condition_number(W_ID, scaled=True),
        dopt=float(d_optimality(jnp.asarray(W_ID))), objective=float(obj),
        sigma={n: float(s) for n, s in zip(prob.names, sig, strict=True)},
        rel_sigma={n: float(r) for n, r in zip(prob.names, rel, strict=True)},
        min_tension_margin_N=margin, workspace_ok=ws_ok, max_cable_speed=vmax_used,
        cable_speed_ok=sp_ok,
        certified=bool(certify and ws_ok and sp_ok and margin >= 0.0),
    )


# =============================================================================== optimiser


@dataclasses.dataclass(frozen=True)
class ExcitationResult:
    """Outcome of :func:`optimise_excitation`.

    ``optimised`` is always certified (or equal to ``initial`` with ``note`` saying why);
    ``starts`` lists each start's penalised objective, steps and certification.
    """

    problem: ExcitationProblem
    initial: DesignReport
    optimised: DesignReport
    trajectory: object
    starts: list
    wall_time_s: float
    optimiser_time_s: float
    note: str

    def as_json(self) -> dict:
        return {
            "initial": self.initial.as_json(),
            "optimised": self.optimised.as_json(),
            "wall_time_s": self.wall_time_s,
            "optimiser_time_s": self.optimiser_time_s,
            "family": self.problem.family.name,
            "model": self.problem.model,
            "objective": self.problem.objective,
            "starts": self.starts,
            "note": self.note,
        }


@eqx.filter_jit
def _solve(z0, probm: _ProbModule, t, max_steps: int):
    import optimistix as optx

    fn = lambda z, _: _penalised(z, probm, t)  # noqa: E731
    sol = optx.minimise(fn, optx.BFGS(rtol=1e-6, atol=1e-6), z0, has_aux=True,
                        max_steps=max_steps, throw=False)
    f, pen = sol.aux  # the objective's parts at sol.value (no second copy of the objective)
    return sol.value, f + probm.penalty * pen, f, pen, sol.stats["num_steps"]


def _log(msg: str, progress: Callable | bool | None):
    if progress is True:
        print(msg, file=sys.stderr, flush=True)
    elif callable(progress):
        progress(msg)


def start_points(prob: ExcitationProblem, n_starts: int = 4, seed: int = 0,
                 initial_params: dict | None = None, spread: float = 0.7) -> list:
    """Start coordinates: the initial design, then N(0, spread^2) perturbations of it
    drawn from ``jax.random.PRNGKey(seed)``."""
    fam = prob.family
    p0 = fam.initial_params(prob.robot) if initial_params is None else initial_params
    z_init = jnp.asarray(fam.from_params(p0))
    keys = jax.random.split(jax.random.PRNGKey(seed), max(n_starts - 1, 1))
    return [z_init] + [z_init + spread * jax.random.normal(k, z_init.shape) for k in keys[: n_starts - 1]]


def optimise_excitation(prob: ExcitationProblem, n_starts: int = 4, seed: int = 0,
                        initial_params: dict | None = None, max_steps: int = 1000,
                        spread: float = 0.7, progress: Callable | bool | None = True) -> ExcitationResult:
    """Minimise the penalised objective with optimistix BFGS from several starts.

    Start 0 is the initial design (the paper-like orbit unless ``initial_params``); the others
    perturb its coordinates with N(0, spread^2) draws from ``jax.random.PRNGKey(seed)``.
    One compiled solve is reused for every start. The answer is the certified design with the
    best objective (exact value on the 100 Hz grid); uncertified designs are never returned.
    """
    t_wall = time.perf_counter()
    fam = prob.family
    starts = start_points(prob, n_starts, seed, initial_params, spread)
    z_init = starts[0]
    t = jnp.asarray(prob.grid(prob.rate_opt_hz))
    probm = _as_module(prob)
    _log(f"excite: {fam.name} family, {fam.n_params} parameters, {prob.model} model, objective "
         f"{prob.objective}, {len(starts)} starts", progress)
    t_opt = time.perf_counter()
    sols = []
    for i, z0 in enumerate(starts):
        t1 = time.perf_counter()
        z, val, f, pen, steps = _solve(z0, probm, t, max_steps)
        z = jax.block_until_ready(z)
        sols.append((float(val), np.asarray(z), float(f), float(pen), int(steps)))
        _log(f"excite: start {i + 1}/{len(starts)}: penalised objective {float(val):.4f} "
             f"(objective {float(f):.4f}, penalty {float(pen):.2e}) in {int(steps)} steps, "
             f"{time.perf_counter() - t1:.1f} s", progress)
    optimiser_time = time.perf_counter() - t_opt
    initial = evaluate_design(prob, z_init)
    _log(f"excite: initial design: cond {initial.cond:.3f}, certified {initial.certified}", progress)
    reports = []
    for i in np.argsort([s[0] for s in sols]):
        rep = evaluate_design(prob, sols[i][1])
        reports.append((i, rep))
        _log(f"excite: start {i + 1}: cond {rep.cond:.3f}, cond_scaled {rep.cond_scaled:.3f}, "
             f"min tension margin {rep.min_tension_margin_N:.2f} N, certified {rep.certified}", progress)
        if rep.certified:
            break
    start_info = [{"start": i + 1, "penalised": s[0], "objective": s[2], "penalty": s[3],
                   "steps": s[4]} for i, s in enumerate(sols)]
    for i, rep in reports:
        start_info[i]["certified"] = rep.certified
        start_info[i]["cond"] = rep.cond
    cert = [(i, r) for i, r in reports if r.certified]
    note = ""
    if cert:
        i, best = cert[0]
        if i != int(np.argsort([s[0] for s in sols])[0]):
            note = f"best start was not certified; returned start {i + 1}, the best certified one."
    elif initial.certified:
        best = initial
        note = "no optimised start was certified; returned the (certified) initial design."
    else:
        raise ValueError("neither the optimised starts nor the initial design are certified "
                         "(tension, workspace or cable-speed limits); relax the limits or give "
                         "a feasible initial design.")
    if best.objective > initial.objective and initial.certified:
        best, note = initial, "the optimiser did not improve on the initial design; returned it."
    if note:
        _log(f"excite: {note}", progress)
    traj = fam.trajectory(jnp.asarray(best.z))
    return ExcitationResult(prob, initial, best, traj, start_info,
                            time.perf_counter() - t_wall, optimiser_time, note)


# =============================================================================== baseline


def slsqp_baseline(prob: ExcitationProblem, z0=None, maxiter: int = 200,
                   softness: float = 0.02) -> dict:
    """scipy SLSQP with finite-difference gradients on the same objective and constraints.

    The objective is the same jit-compiled smooth objective (no penalty); the constraints are
    soft minima (temperature ``softness``, normalised units) of the same per-sample margins:
    workspace, cable speed and tension. Returns ``{"z", "objective", "time_s", "nfev", "success"}``.
    """
    from scipy.optimize import minimize

    fam = prob.family
    if z0 is None:
        z0 = fam.from_params(fam.initial_params(prob.robot))
    t = jnp.asarray(prob.grid(prob.rate_opt_hz))
    probm = _as_module(prob)

    @jax.jit
    def both(z):
        states = probm.family.states(z, t)
        W_ID = stacked_regressor(states, probm.robot.gravity, probm.model)
        ws, sp, tn = _constraint_margins(probm, states)
        cons = jnp.array([_softmin(c.ravel(), softness) for c in (ws, sp, tn)])
        return _objective_value(probm, W_ID), cons

    both(jnp.asarray(z0))  # compile outside the timing, to time the optimiser only
    last = {}

    def at(z):
        # SLSQP asks for the objective and the constraints at the same points: one compiled
        # evaluation serves both (memoised on the last point)
        key = np.asarray(z, float).tobytes()
        if last.get("key") != key:
            f, c = both(jnp.asarray(z))
            last.update(key=key, f=float(f), c=np.asarray(c))
        return last

    t0 = time.perf_counter()
    res = minimize(lambda z: at(z)["f"], np.asarray(z0, float), method="SLSQP", jac=None,
                   constraints=[{"type": "ineq", "fun": lambda z: at(z)["c"]}],
                   options={"maxiter": maxiter, "ftol": 1e-9})
    dt = time.perf_counter() - t0
    return {"z": res.x, "objective": float(res.fun), "time_s": dt, "nfev": int(res.nfev),
            "success": bool(res.success), "message": str(res.message)}
