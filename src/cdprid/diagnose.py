"""Model-discrepancy diagnosis: what the paper's model gets wrong, why, and what fixing it gains.

Pipeline (see ``docs/diagnosis.md`` for the derivations):

1. **Base fit** — the paper's translation model (x = [m, m s_G], measured orientation in W
   and in the regressor), accelerations by Euler differences after the zero-phase 4 Hz
   Butterworth, and the *same* filter applied to the cable wrench (matched filtering).
   Force and moment rows are weighted by the inverse of their residual RMS.
2. **One forward model for every effect** — :func:`_measured_side` and :func:`_model_side`
   take the whole effect-parameter vector theta (delay, per-cable offsets and gains, per-cable
   exit and anchor displacements, drag, pulley radius, cable density, frame tilt) and give the
   matched-filtered residual ``r(x, theta)`` in JAX. theta = 0 is the base model. The
   linearised column of every candidate is one column of ``d r / d theta`` (jacfwd),
   so ranking and the final nonlinear refit (optimistix Levenberg-Marquardt) share one model.
3. **Testing with honest false-positive control** — for each candidate (effect x cable):
   a Wald statistic with HAC (Newey-West, Bartlett) covariance, since filtered residuals are
   strongly autocorrelated; a Bonferroni correction over all candidates; a threshold calibrated
   on null residuals simulated from the fitted base model with the noise levels estimated from
   the data; and blocked held-out validation (contiguous time blocks, with a guard gap):
   an effect is accepted only when the held-out residual improves.
4. **Aliases** — candidates whose columns (after projecting out the base model) are nearly
   collinear with the winner's and explain nearly as much are listed as aliases.
5. **Greedy forward selection** — refit with the accepted effects, re-linearise, repeat.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from scipy import stats

from .differentiators import differentiate, zero_phase_filter
from .dynamics import PARAMETER_NAMES, regressor_full, regressor_translation
from .geometry import CableRobot, _one_cable, cable_vectors, wrench_matrix
from .identification import least_squares
from .io.dataset import Dataset, align
from .regression import wrench_matrices
from .rotations import quat_to_matrix

__all__ = ["DiagnosisResult", "diagnose", "CANDIDATE_EFFECTS", "estimate_noise"]

#: effects the diagnosis tests (the simulator's vocabulary minus ``none``)
CANDIDATE_EFFECTS = (
    "time_delay",
    "tension_offset",
    "tension_gain",
    "exit_point_error",
    "anchor_point_error",
    "viscous_drag",
    "pulley",
    "cable_mass",
    "frame_tilt",
    "rotational_dynamics",
    "pulley_friction",
)

# ----------------------------------------------------------------------------- theta layout


class ThetaLayout:
    """Index layout of the unified effect-parameter vector theta for m cables."""

    def __init__(self, m: int):
        self.m = m
        sl = {}
        i = 0
        for name, size in (("delay", 1), ("offset", m), ("gain", m), ("exit", 3 * m),
                           ("anchor", 3 * m), ("drag", 1), ("pulley", 1), ("rho", 1), ("tilt", 2),
                           ("coulomb", m), ("pvisc", m)):
            sl[name] = slice(i, i + size)
            i += size
        self.slices = sl
        self.size = i

    def unpack(self, theta):
        s = self.slices
        m = self.m
        return {
            "delay": theta[s["delay"]][0],
            "offset": theta[s["offset"]],
            "gain": theta[s["gain"]],
            "exit": theta[s["exit"]].reshape(m, 3),
            "anchor": theta[s["anchor"]].reshape(m, 3),
            "drag": theta[s["drag"]][0],
            "pulley": theta[s["pulley"]][0],
            "rho": theta[s["rho"]][0],
            "tilt": theta[s["tilt"]],
            "coulomb": theta[s["coulomb"]],
            "pvisc": theta[s["pvisc"]],
        }

    def candidate_indices(self, effect: str, cable: int | None = None) -> list[int]:
        """Indices of theta that an effect (and cable, 1-based) uses."""
        s = self.slices
        if effect == "time_delay":
            return [s["delay"].start]
        if effect == "tension_offset":
            return [s["offset"].start + cable - 1]
        if effect == "tension_gain":
            return [s["gain"].start + cable - 1]
        if effect == "exit_point_error":
            return list(range(s["exit"].start + 3 * (cable - 1), s["exit"].start + 3 * cable))
        if effect == "anchor_point_error":
            return list(range(s["anchor"].start + 3 * (cable - 1), s["anchor"].start + 3 * cable))
        if effect == "viscous_drag":
            return [s["drag"].start]
        if effect == "pulley":
            return [s["pulley"].start]
        if effect == "cable_mass":
            return [s["rho"].start]
        if effect == "frame_tilt":
            return list(range(s["tilt"].start, s["tilt"].stop))
        if effect == "pulley_friction":
            return [s["coulomb"].start + cable - 1, s["pvisc"].start + cable - 1]
        raise KeyError(effect)


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One testable extension: an effect, optionally on one cable."""

    effect: str
    cable: int | None = None

    @property
    def label(self) -> str:
        return self.effect if self.cable is None else f"{self.effect}[cable {self.cable}]"


def alias_label(c: Candidate) -> str:
    """The JSON form of a candidate in ``aliases`` (``effect`` or ``effect:cable=i``)."""
    return c.effect if c.cable is None else f"{c.effect}:cable={c.cable}"


def _candidates(m: int, has_rotation: bool) -> list[Candidate]:
    out = [Candidate("time_delay")]
    for eff in ("tension_offset", "tension_gain", "exit_point_error", "anchor_point_error",
                "pulley_friction"):
        out += [Candidate(eff, i) for i in range(1, m + 1)]
    out += [Candidate("viscous_drag"), Candidate("pulley"), Candidate("cable_mass"),
            Candidate("frame_tilt")]
    if has_rotation:
        out.append(Candidate("rotational_dynamics"))
    return out


# ----------------------------------------------------------------------------- data


class DiagData(eqx.Module):
    """Arrays the forward model needs (an immutable pytree)."""

    robot: CableRobot
    t: jnp.ndarray
    p: jnp.ndarray
    R: jnp.ndarray
    v: jnp.ndarray
    a: jnp.ndarray
    om: jnp.ndarray
    al: jnp.ndarray
    tau_grid: jnp.ndarray  # raw tension stream (uniform grid), (k, m)
    ldot: jnp.ndarray  # cable length rates dl/dt of the nominal geometry, (n, m)
    tau_t0: float = eqx.field(static=True)
    tau_dt: float = eqx.field(static=True)


def _tension_at(d: DiagData, s):
    """Tensions at times s (n,) by cubic Hermite (Catmull-Rom) on the uniform tension grid."""
    k = d.tau_grid.shape[0]
    u = (s - d.tau_t0) / d.tau_dt
    i = jnp.clip(jnp.floor(u).astype(int), 1, k - 3)
    f = (u - i)[:, None]
    y0, y1, y2, y3 = d.tau_grid[i - 1], d.tau_grid[i], d.tau_grid[i + 1], d.tau_grid[i + 2]
    m1 = 0.5 * (y2 - y0)
    m2 = 0.5 * (y3 - y1)
    f2, f3 = f * f, f * f * f
    return ((2 * f3 - 3 * f2 + 1) * y1 + (f3 - 2 * f2 + f) * m1 + (-2 * f3 + 3 * f2) * y2
            + (f3 - f2) * m2)


def _tilt_gravity(g, tilt):
    rx, ry = tilt[0], tilt[1]
    cx, sx, cy, sy = jnp.cos(rx), jnp.sin(rx), jnp.cos(ry), jnp.sin(ry)
    Rx = jnp.array([[1.0, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = jnp.array([[cy, 0, sy], [0, 1.0, 0], [-sy, 0, cy]])
    return (Ry @ Rx).T @ g  # g_pose = R_tilt^T g, R_tilt = Ry(ry) Rx(rx)


def _true_robot(robot: CableRobot, th):
    return eqx.tree_at(
        lambda r: (r.B_A, r.P_b, r.pulley_radius),
        robot,
        (robot.B_A + th["exit"], robot.P_b + th["anchor"], robot.pulley_radius + th["pulley"]),
    )


def _measured_side(d: DiagData, th):
    """Unfiltered cable-side wrench (n, 6): W_true tau_true + cable-weight load."""
    tau = _tension_at(d, d.t + th["delay"])
    tau = (tau - th["offset"]) / (1.0 + th["gain"])
    tau = tau + th["coulomb"] * jnp.sign(d.ldot) + th["pvisc"] * d.ldot
    rob = _true_robot(d.robot, th)
    g = _tilt_gravity(d.robot.gravity, th["tilt"])

    def one(p, R, ta):
        W = wrench_matrix(rob, p, R)
        L = cable_vectors(rob, p, R)
        Lc = jnp.linalg.norm(L, axis=1)
        b = (R @ rob.P_b.T).T
        half = 0.5 * th["rho"] * Lc  # kg: half of each cable's mass at its attachment
        f = jnp.sum(half) * g
        n = jnp.sum(half[:, None] * jnp.cross(b, jnp.broadcast_to(g, b.shape)), axis=0)
        return W @ ta + jnp.concatenate([f, n])

    return jax.vmap(one)(d.p, d.R, tau)


def _model_side(d: DiagData, th, x, rotational: bool):
    """Model wrench (n, 6): regressor(x) with tilted gravity, plus drag c v on the force rows."""
    g = _tilt_gravity(d.robot.gravity, th["tilt"])
    if rotational:
        A = jax.vmap(lambda R, a, w, al: regressor_full(R, a, w, al, g))(d.R, d.a, d.om, d.al)
    else:
        A = jax.vmap(lambda R, a: regressor_translation(R, a, g))(d.R, d.a)
    y = jnp.einsum("nij,j->ni", A, x)
    drag = jnp.concatenate([d.v * th["drag"], jnp.zeros_like(d.v)], axis=1)
    return y + drag


def _tension_rate_at(d: DiagData, s):
    """Time derivative of the Catmull-Rom interpolant of :func:`_tension_at`."""
    return jax.jacfwd(lambda h: _tension_at(d, s + h))(0.0)


def _cable_contribution(local, A, b, r, k, ref, p, R, tau_c, taud_c, g0, local_c, ldot_c):
    """Wrench (6,) of one cable on the platform, with its own effect parameters.

    ``local = [dA (3), db (3), offset, gain, delay, pulley, rho, tilt (2), coulomb, viscous]``
    (the last two: load-cell friction of ``pulley_friction`` with the cable rate ``ldot_c``);
    the delay enters
    through the first-order expansion of the tension about the current delay ``local_c[8]``,
    exact in value and first derivative at the linearisation point.
    """
    dA, db = local[0:3], local[3:6]
    off, gain, delay, pul, rho = local[6], local[7], local[8], local[9], local[10]
    tau = tau_c + (delay - local_c[8]) * taud_c
    tau = (tau - off) / (1.0 + gain) + local[13] * jnp.sign(ldot_c) + local[14] * ldot_c
    bb = R @ (b + db)
    T, _, _ = _one_cable(A + dA, bb, p, r + pul, k, ref)
    L = T - (p + bb)
    Ln = jnp.linalg.norm(L)
    u = L / Ln
    g = _tilt_gravity(g0, local[11:13])
    load = 0.5 * rho * Ln * g
    return jnp.concatenate([u * tau + load, jnp.cross(bb, u * tau + load)])


def _locals(d: DiagData, th):
    """Per-cable local parameter vectors (m, 15) at theta."""
    m = d.robot.n_cables
    glob = jnp.stack([th["delay"], th["pulley"], th["rho"]])
    return jnp.concatenate([
        th["exit"], th["anchor"], th["offset"][:, None], th["gain"][:, None],
        jnp.broadcast_to(glob, (m, 3))[:, :1], jnp.broadcast_to(glob, (m, 3))[:, 1:],
        jnp.broadcast_to(th["tilt"], (m, 2)), th["coulomb"][:, None], th["pvisc"][:, None]],
        axis=1)


@functools.partial(jax.jit, static_argnums=(2,))
def _meas_and_jac(d, theta, layout):
    """Unfiltered measured side (n, 6) and its Jacobian (n, 6, ntheta) at theta.

    Computed cable by cable (13 local parameters each) instead of through all theta at once.
    """
    th = layout.unpack(theta)
    m = layout.m
    loc = _locals(d, th)  # (m, 15)
    tau_c = _tension_at(d, d.t + th["delay"])  # (n, m)
    taud_c = _tension_rate_at(d, d.t + th["delay"])
    rob = d.robot

    def per_sample(p, R, tc, tdc, ld):
        def per_cable(lc, A, b, r, k, ref, ti, tdi, li):
            f = functools.partial(_cable_contribution, A=A, b=b, r=r, k=k, ref=ref, p=p, R=R,
                                  tau_c=ti, taud_c=tdi, g0=rob.gravity, local_c=lc, ldot_c=li)
            return f(lc), jax.jacfwd(f)(lc)

        w, J = jax.vmap(per_cable)(loc, rob.B_A, rob.P_b, rob.pulley_radius, rob.pulley_axis,
                                   rob.pulley_reference, tc, tdc, ld)
        return w.sum(0), J  # (6,), (m, 6, 15)

    y, Jl = jax.vmap(per_sample)(d.p, d.R, tau_c, taud_c, d.ldot)
    n = y.shape[0]
    s = layout.slices
    J = jnp.zeros((n, 6, layout.size))
    Jl = jnp.moveaxis(Jl, 1, 3)  # (n, 6, 15, m)
    J = J.at[:, :, s["exit"]].set(jnp.moveaxis(Jl[:, :, 0:3, :], 3, 2).reshape(n, 6, 3 * m))
    J = J.at[:, :, s["anchor"]].set(jnp.moveaxis(Jl[:, :, 3:6, :], 3, 2).reshape(n, 6, 3 * m))
    J = J.at[:, :, s["offset"]].set(Jl[:, :, 6, :])
    J = J.at[:, :, s["gain"]].set(Jl[:, :, 7, :])
    J = J.at[:, :, s["delay"]].set(Jl[:, :, 8, :].sum(-1, keepdims=True))
    J = J.at[:, :, s["pulley"]].set(Jl[:, :, 9, :].sum(-1, keepdims=True))
    J = J.at[:, :, s["rho"]].set(Jl[:, :, 10, :].sum(-1, keepdims=True))
    J = J.at[:, :, s["tilt"]].set(Jl[:, :, 11:13, :].sum(-1))
    J = J.at[:, :, s["coulomb"]].set(Jl[:, :, 13, :])
    J = J.at[:, :, s["pvisc"]].set(Jl[:, :, 14, :])
    return y, J


@functools.partial(jax.jit, static_argnums=(3, 4))
def _model_jit(d, theta, x, layout, rotational):
    return _model_side(d, layout.unpack(theta), x, rotational)


@functools.partial(jax.jit, static_argnums=(3, 4))
def _model_jac_jit(d, theta, x, layout, rotational):
    return jax.jacfwd(lambda th: _model_side(d, layout.unpack(th), x, rotational))(theta)


@functools.partial(jax.jit, static_argnums=(2, 3))
def _regs_jit(d, theta, layout, rotational):
    g = _tilt_gravity(d.robot.gravity, layout.unpack(theta)["tilt"])
    if rotational:
        return jax.vmap(lambda R, a, w, al: regressor_full(R, a, w, al, g))(d.R, d.a, d.om, d.al)
    return jax.vmap(lambda R, a: regressor_translation(R, a, g))(d.R, d.a)




# ----------------------------------------------------------------------------- statistics


def _hac_cov(Z, e, lags: int):
    """Sandwich covariance of LS coefficients, Newey-West (Bartlett) HAC over time samples.

    Z : (n, 6, p) design rows grouped by sample; e : (n, 6) residuals. The Bartlett-weighted
    sum of score autocovariances up to ``lags`` equals the mean outer product of moving sums
    of ``lags + 1`` consecutive scores (computed by cumulative sums, O(n p^2)).
    """
    n, _, p = Z.shape
    Zf = Z.reshape(-1, p)
    bread = np.linalg.pinv(Zf.T @ Zf)
    S = np.einsum("nip,ni->np", Z, e)  # per-sample scores
    L = int(lags) + 1
    c = np.concatenate([np.zeros((1, p)), np.cumsum(S, axis=0)])
    # windows [k - L + 1, k] for k = 0 .. n + L - 2 (partial windows at both ends)
    hi = np.minimum(np.arange(n + L - 1) + 1, n)
    lo = np.maximum(np.arange(n + L - 1) - L + 1, 0)
    M = c[hi] - c[lo]
    meat = (M.T @ M) / L
    return bread @ meat @ bread


def _wald(Z, y, idx_extra, lags):
    """LS of y on Z, Wald statistic of the coefficients idx_extra with HAC covariance."""
    n, _, p = Z.shape
    Zf = Z.reshape(-1, p)
    beta, *_ = np.linalg.lstsq(Zf, y.reshape(-1), rcond=None)
    e = y - np.einsum("nip,p->ni", Z, beta)
    V = _hac_cov(Z, e, lags)
    b = beta[idx_extra]
    Vb = V[np.ix_(idx_extra, idx_extra)]
    try:
        stat = float(b @ np.linalg.solve(Vb, b))
    except np.linalg.LinAlgError:
        stat = 0.0
    return stat, beta, V, e


def _blocks(n: int, k: int):
    edges = np.linspace(0, n, k + 1).astype(int)
    return [(edges[i], edges[i + 1]) for i in range(k)]


def _cv_sse(Z, y, folds, guard):
    """Blocked held-out sum of squared residuals of the LS of y on Z."""
    n = Z.shape[0]
    sse = 0.0
    count = 0
    p = Z.shape[2]
    for lo, hi in folds:
        train = np.ones(n, bool)
        train[max(0, lo - guard):min(n, hi + guard)] = False
        Zt = Z[train].reshape(-1, p)
        beta, *_ = np.linalg.lstsq(Zt, y[train].reshape(-1), rcond=None)
        r = y[lo:hi] - np.einsum("nip,p->ni", Z[lo:hi], beta)
        sse += float(np.sum(r * r))
        count += r.size
    return sse, count


def estimate_noise(x, order: int = 4) -> np.ndarray:
    """White-noise standard deviation of each column of a smooth signal plus noise.

    The ``order``-th difference of white noise of variance s^2 has variance
    ``C(2 order, order) s^2`` while a smooth signal's is negligible at 100 Hz; a median
    absolute deviation keeps it robust.
    """
    x = np.asarray(x, float)
    d = np.diff(x, n=order, axis=0)
    c = math.comb(2 * order, order)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) * 1.4826
    return mad / math.sqrt(c)


# ----------------------------------------------------------------------------- results


@dataclasses.dataclass(frozen=True)
class Finding:
    """One accepted effect."""

    effect: str
    parameters: dict
    interval: dict
    aliases: list
    heldout_rms_before: float
    heldout_rms_after: float
    p_value: float
    statistic: float
    threshold: float
    #: alias label -> what trajectory or measurement would tell the two apart
    separated_by: dict = dataclasses.field(default_factory=dict)

    def as_json(self) -> dict:
        return {
            "effect": self.effect,
            "parameters": self.parameters,
            "interval": self.interval,
            "aliases": self.aliases,
            "heldout_rms_before": self.heldout_rms_before,
            "heldout_rms_after": self.heldout_rms_after,
            "p_value": self.p_value,
            "statistic": self.statistic,
            "threshold": self.threshold,
            "separated_by": self.separated_by,
        }


@dataclasses.dataclass(frozen=True)
class DiagnosisResult:
    """Everything :func:`diagnose` found; ``as_json()`` is the CLI's JSON contract."""

    base_parameters: dict
    base_residual_rms: list
    base_heldout_rms: float
    findings: list
    extended_parameters: dict
    extended_heldout_rms: float
    ranking: list
    info: dict
    arrays: dict = dataclasses.field(default_factory=dict, repr=False)
    #: residual structure the extended model leaves, and hints (vocabulary effects removed
    #: by backward elimination): ``where``, ``size`` (N), ``correlates_with``, ``p_value``
    unexplained: list = dataclasses.field(default_factory=list)

    def as_json(self) -> dict:
        return {
            "base": {
                "parameters": self.base_parameters,
                "residual_rms": self.base_residual_rms,
                "heldout_residual_rms": self.base_heldout_rms,
            },
            "findings": [f.as_json() for f in self.findings],
            "extended": {
                "parameters": self.extended_parameters,
                "heldout_residual_rms": self.extended_heldout_rms,
                "effects": [f.effect for f in self.findings],
                "information_criterion": self.info.get("information_criterion", {}),
            },
            "unexplained": [{k: v for k, v in u.items() if k != "significant"}
                            for u in self.unexplained],
            "ranking": self.ranking,
            "info": {k: v for k, v in self.info.items() if k != "information_criterion"},
        }


# ----------------------------------------------------------------------------- main routine


def _rotvec_from_quat(q):
    q = np.asarray(q, float)
    q = q * np.sign(q[:, :1] + (q[:, :1] == 0))
    v = q[:, 1:]
    s = np.linalg.norm(v, axis=1)
    ang = 2 * np.arctan2(s, q[:, 0])
    scale = np.where(s > 1e-12, ang / np.where(s > 1e-12, s, 1.0), 2.0)
    return v * scale[:, None]


def _well_determined(v, cov, ratio: float = 0.4):
    """Shrink the poorly determined directions of a 3-D displacement estimate to zero.

    A displacement of an exit or attachment point along its cable barely changes the cable
    direction, so that component is weakly identifiable (its standard deviation is large).
    Components along covariance eigen-directions whose standard deviation exceeds ``ratio``
    times the estimate's norm are set to zero (the prior of no displacement); the interval
    keeps the full uncertainty.
    """
    w, E = np.linalg.eigh(cov)
    c = E.T @ v
    s = np.sqrt(np.clip(w, 0, None))
    keep = s <= ratio * max(np.linalg.norm(v), 1e-12)
    return E @ (c * keep)


def _vocab_params(c: Candidate, th_values: np.ndarray, layout: ThetaLayout, extra: dict,
                  th_cov=None) -> dict:
    idx = layout.candidate_indices(c.effect, c.cable) if c.effect != "rotational_dynamics" else []
    v = th_values[idx] if idx else None
    if c.effect in ("exit_point_error", "anchor_point_error") and th_cov is not None:
        v = _well_determined(v, th_cov[np.ix_(idx, idx)])
    if c.effect == "time_delay":
        return {"delay_s": float(v[0])}
    if c.effect == "tension_offset":
        return {"cable": c.cable, "offset_N": float(v[0])}
    if c.effect == "tension_gain":
        return {"cable": c.cable, "gain": float(1.0 + v[0])}
    if c.effect in ("exit_point_error", "anchor_point_error"):
        return {"cable": c.cable, "displacement_m": [float(z) for z in v]}
    if c.effect == "viscous_drag":
        return {"coefficient_Ns_per_m": float(v[0])}
    if c.effect == "pulley":
        return {"radius_m": float(v[0])}
    if c.effect == "cable_mass":
        return {"linear_density_kg_per_m": float(v[0])}
    if c.effect == "frame_tilt":
        return {"tilt_rad": [float(v[0]), float(v[1])]}
    if c.effect == "rotational_dynamics":
        return {"amplitude_rad": float(extra["rotation_amplitude"])}
    if c.effect == "pulley_friction":
        return {"cable": c.cable, "coulomb_N": float(v[0]), "viscous_Ns_per_m": float(v[1])}
    raise KeyError(c.effect)


#: plausibility bounds of a refitted effect (a larger value means a degenerate linearisation)
_BOUNDS = {"coulomb_N": 100.0, "viscous_Ns_per_m": 1e3, "delay_s": 0.5, "offset_N": 1e3,
           "displacement_m": 0.25, "coefficient_Ns_per_m": 1e3, "radius_m": 0.25,
           "linear_density_kg_per_m": 5.0, "tilt_rad": 0.05}


def _implausible(effect: str, params: dict) -> str:
    """A reason string when a refitted effect is physically implausible, else ''."""
    for k, v in params.items():
        if k == "cable":
            continue
        if k == "gain":
            if not 0.5 < v < 2.0:
                return f"gain {v:.3g}"
            continue
        if k == "amplitude_rad":
            continue
        mag = float(np.linalg.norm(np.atleast_1d(v)))
        if not np.isfinite(mag) or mag > _BOUNDS.get(k, np.inf):
            return f"{k} = {v}"
        if k in ("radius_m", "linear_density_kg_per_m", "coefficient_Ns_per_m") and v < 0:
            return f"{k} = {v:.3g} < 0"
        if k in ("coulomb_N", "viscous_Ns_per_m") and v < 0:
            return f"{k} = {v:.3g} < 0"
    return ""


def _vocab_interval(c: Candidate, th_values, th_std, layout, extra) -> dict:
    z = 1.959963984540054
    if c.effect == "rotational_dynamics":
        a = extra["rotation_amplitude"]
        s = extra.get("rotation_amplitude_std", 0.0)
        return {"amplitude_rad": [a - z * s, a + z * s]}
    idx = layout.candidate_indices(c.effect, c.cable)
    v, s = th_values[idx], th_std[idx]
    lo, hi = v - z * s, v + z * s
    if c.effect == "tension_gain":
        return {"gain": [float(1 + lo[0]), float(1 + hi[0])]}
    if c.effect == "pulley_friction":
        return {"coulomb_N": [float(lo[0]), float(hi[0])],
                "viscous_Ns_per_m": [float(lo[1]), float(hi[1])]}
    name = {"time_delay": "delay_s", "tension_offset": "offset_N", "viscous_drag":
            "coefficient_Ns_per_m", "pulley": "radius_m", "cable_mass": "linear_density_kg_per_m"}
    if c.effect in name:
        return {name[c.effect]: [float(lo[0]), float(hi[0])]}
    key = "tilt_rad" if c.effect == "frame_tilt" else "displacement_m"
    return {key: [[float(a), float(b)] for a, b in zip(lo, hi, strict=True)]}


def diagnose(
    ds: Dataset,
    train_until: float | None = None,
    cutoff_hz: float = 4.0,
    trim: float = 1.0,
    n_folds: int = 5,
    alpha: float = 1e-3,
    n_null: int = 30,
    max_effects: int = 3,
    min_gain: float = 0.01,
    seed: int = 0,
    taut_N: float = 5.0,
    progress=None,
) -> DiagnosisResult:
    """Diagnose what the paper's model misses in a dataset.

    Parameters
    ----------
    ds : Dataset
    train_until : float, optional
        Fit everything on t < train_until and measure the held-out gain on t >= train_until.
        Without it, held-out figures are blocked cross-validation over ``n_folds`` time blocks.
    cutoff_hz : float
        Zero-phase filter cutoff (differentiator and matched filter).
    trim : float
        Seconds dropped at both ends (filter transients).
    n_folds : int
        Number of contiguous time blocks for held-out validation.
    alpha : float
        Family-wise false-positive rate (Bonferroni over all candidates).
    n_null : int
        Null residual replicates simulated from the fitted base model to calibrate thresholds.
    max_effects : int
        Greedy forward selection stops after this many effects.
    min_gain : float
        Smallest relative held-out RMS reduction for an effect to be accepted.
    seed : int
        Seed of the null simulation.
    taut_N : float
        Samples where any cable is below this tension (N) within +-0.1 s are excluded
        (slack phases are outside every model here).
    progress : callable, optional
        Called with progress strings.

    Returns
    -------
    DiagnosisResult
    """
    t0 = time.perf_counter()

    def say(msg):
        if progress is not None:
            progress(f"[{time.perf_counter() - t0:6.1f} s] {msg}")

    sig = align(ds)
    dt = sig.dt
    robot = ds.robot
    m = robot.n_cables
    v, a = differentiate(sig.position, dt, method="euler-filtfilt", cutoff_hz=cutoff_hz)
    R = np.asarray(jax.vmap(quat_to_matrix)(sig.quaternion))
    if sig.has_rotation:
        qd, qdd = differentiate(sig.quaternion, dt, method="euler-filtfilt", cutoff_hz=cutoff_hz)
        from .rotations import angular_rates_from_quat

        om, al = (np.asarray(z) for z in jax.vmap(angular_rates_from_quat)(sig.quaternion, qd, qdd))
    else:
        om = np.zeros_like(v)
        al = np.zeros_like(v)
    # raw tension grid (uniform) for the fractional delay
    tt = ds.tension_t
    tdt = float(np.median(np.diff(tt)))
    if np.max(np.abs(np.diff(tt) - tdt)) > 0.01 * tdt:
        grid_t = np.arange(tt[0], tt[-1], tdt)
        tau_grid = np.column_stack([np.interp(grid_t, tt, ds.tension[:, i]) for i in range(m)])
    else:
        grid_t, tau_grid = tt, ds.tension
    W_all = np.asarray(jax.jit(wrench_matrices)(robot, jnp.asarray(sig.position),
                                                 jnp.asarray(R)))
    ldot = -np.einsum("nim,ni->nm", W_all, np.concatenate([v, om], axis=1))
    d = DiagData(robot, jnp.asarray(sig.t), jnp.asarray(sig.position), jnp.asarray(R),
                 jnp.asarray(v), jnp.asarray(a), jnp.asarray(om), jnp.asarray(al),
                 jnp.asarray(tau_grid), jnp.asarray(ldot), float(grid_t[0]), tdt)
    layout = ThetaLayout(m)
    n = len(sig.t)
    # usable samples: trimmed ends, and delay margin inside the tension stream
    margin = max(trim, 0.1)
    use = ((sig.t >= max(sig.t[0], grid_t[0]) + margin)
           & (sig.t <= min(sig.t[-1], grid_t[-1]) - margin))
    # taut phases only: every cable above taut_N within +-0.1 s (slack cables are not modelled)
    from scipy.ndimage import minimum_filter1d

    win = 2 * int(round(0.1 / dt)) + 1
    taut = minimum_filter1d(sig.tension.min(axis=1), size=win, mode="nearest") > taut_N
    n_slack = int((use & ~taut).sum())
    use = use & taut
    if train_until is not None:
        train = use & (sig.t < train_until)
        test = use & (sig.t >= train_until)
        if train.sum() < 200 or test.sum() < 50:
            raise ValueError(
                f"--train-until {train_until:g} leaves {int(train.sum())} training and "
                f"{int(test.sum())} held-out samples; choose a time inside the recording."
            )
    else:
        train = use
        test = None
    say(f"aligned {n} samples at {1 / dt:.4g} Hz; {int(train.sum())} used for fitting"
        + (f" ({n_slack} samples with a cable below {taut_N:g} N excluded)" if n_slack else ""))

    # ---------------------------------------------------------------- model pieces
    # cable side (unfiltered) and its theta-Jacobian are jitted once, with the data as an
    # argument; the matched filter is then applied by scipy along time (linear, so filtering
    # the Jacobian equals the Jacobian of the filtered side).
    zf = functools.partial(zero_phase_filter, dt=dt, cutoff_hz=cutoff_hz, order=2)
    theta0 = jnp.zeros(layout.size)

    def design(theta, x_cur, rotational):
        """Filtered measured wrench y, model regressor A and theta columns C at theta.

        Linearisation: ``y(theta') - model(theta') ~ y - A x - C (theta' - theta)``.
        """
        th = jnp.asarray(theta)
        xin = jnp.asarray(x_cur if rotational else x_cur[:4])
        ym, Jm = _meas_and_jac(d, th, layout)
        ym = zf(np.asarray(ym))
        Jm = np.asarray(Jm)  # (n, 6, ntheta)
        Jm = zf(Jm.reshape(n, -1)).reshape(Jm.shape)
        Jmod = np.asarray(_model_jac_jit(d, th, xin, layout, rotational))
        # model side at theta minus its x-part: drag (tilt acts through the regressor)
        Am = np.asarray(_regs_jit(d, th, layout, rotational))
        mod = np.asarray(_model_jit(d, th, xin, layout, rotational))
        y_now = ym - (mod - np.einsum("nij,j->ni", Am, np.asarray(xin)))
        # columns: d(model)/d theta - d(meas)/d theta  (so that y_now ~ A x + C theta)
        C = Jmod - Jm
        return y_now, Am, C

    A4 = np.asarray(_regs_jit(d, theta0, layout, False))
    A10 = np.asarray(_regs_jit(d, theta0, layout, True)) if sig.has_rotation else None
    y_meas0 = zf(np.asarray(_meas_and_jac(d, theta0, layout)[0]))

    # ---------------------------------------------------------------- base fit
    def weighted_fit(Z, y, rows):
        """Two-step weighted LS (force / moment rows) on samples `rows`."""
        p = Z.shape[2]
        beta, *_ = np.linalg.lstsq(Z[rows].reshape(-1, p), y[rows].reshape(-1), rcond=None)
        e = y[rows] - np.einsum("nip,p->ni", Z[rows], beta)
        sf = np.sqrt(np.mean(e[:, :3] ** 2))
        sm = np.sqrt(np.mean(e[:, 3:] ** 2))
        return np.array([1 / sf] * 3 + [1 / sm] * 3)

    wrow = weighted_fit(A4, y_meas0, train)
    base_ls = least_squares((A4[train] * wrow[None, :, None]).reshape(-1, 4),
                            (y_meas0[train] * wrow).reshape(-1), PARAMETER_NAMES["translation"])
    # report std in unweighted units via the weighted fit (weights only rescale rows)
    x_base = base_ls.x
    e_base = y_meas0 - np.einsum("nij,j->ni", A4, x_base)
    base_rms = [float(np.sqrt(np.mean(e_base[train][:, i] ** 2))) for i in range(6)]
    lags = int(math.ceil(3.0 / (cutoff_hz * dt)))  # correlation length of the filtered residual
    Zb = A4 * wrow[None, :, None]
    yb = y_meas0 * wrow
    _, _, Vb, _ = _wald(Zb[train], yb[train], [0], lags)
    base_params = {
        nm: {"value": float(v_), "std": float(np.sqrt(Vb[i, i])),
             "rel_std_percent": float(100 * np.sqrt(Vb[i, i]) / abs(v_))}
        for i, (nm, v_) in enumerate(zip(PARAMETER_NAMES["translation"], x_base, strict=True))
    }
    say(f"base fit: m = {x_base[0]:.4f} kg, force residual rms "
        f"{np.sqrt(np.mean(np.square(base_rms[:3]))):.3f} N")

    # ---------------------------------------------------------------- noise and null model
    sig_p = float(np.median(estimate_noise(sig.position)))
    sig_tau = estimate_noise(tau_grid)
    rot_amp = 0.0
    rot_std = 0.0
    if sig.has_rotation:
        rv = _rotvec_from_quat(sig.quaternion[use])
        rot_amp = float(np.max(np.percentile(np.abs(rv), 99.5, axis=0)))
        rot_std = float(np.median(estimate_noise(rv)))
    say(f"noise estimated from the data: position {1e3 * sig_p:.3f} mm, tensions "
        f"{np.mean(sig_tau):.3f} N (rms over cables)")
    rng = np.random.default_rng(seed)

    def null_residuals(x):
        """Residual replicates of the base model under sensor noise alone (n, 6) each."""
        for _ in range(n_null):
            eta_t = rng.normal(size=(n, m)) * sig_tau[None, :] * math.sqrt(tdt / dt)
            eta_p = rng.normal(size=(n, 3)) * sig_p
            _, acc = differentiate(eta_p, dt, method="euler-filtfilt", cutoff_hz=cutoff_hz)
            yw = zf(np.einsum("nij,nj->ni", W_all, eta_t))
            ms = np.einsum("nij,j->ni", R, x[1:4])  # first moment, base frame
            force = x[0] * acc
            moment = np.cross(ms, acc)
            yield yw - np.concatenate([force, moment], axis=1)

    guard = lags

    def heldout_rms(Z, y):
        """Held-out RMS (weighted units): blocked CV, or train/test split."""
        if test is None:
            Zu, yu = Z[use], y[use]
            sse, cnt = _cv_sse(Zu, yu, _blocks(int(use.sum()), n_folds), guard)
            return math.sqrt(sse / cnt)
        p = Z.shape[2]
        beta, *_ = np.linalg.lstsq(Z[train].reshape(-1, p), y[train].reshape(-1), rcond=None)
        r = y[test] - np.einsum("nip,p->ni", Z[test], beta)
        return float(np.sqrt(np.mean(r * r)))

    def force_heldout_rms(Z, y):
        """Held-out RMS of the force rows in newtons (unweighted)."""
        zz, yy = Z / wrow[None, :, None], y / wrow[None, :]
        del zz
        p = Z.shape[2]
        if test is None:
            tot, cnt = 0.0, 0
            idx = np.nonzero(use)[0]
            for lo, hi in _blocks(len(idx), n_folds):
                tr = np.ones(len(idx), bool)
                tr[max(0, lo - guard):hi + guard] = False
                beta, *_ = np.linalg.lstsq(Z[idx[tr]].reshape(-1, p), y[idx[tr]].reshape(-1),
                                           rcond=None)
                r = yy[idx[lo:hi]] - np.einsum("nip,p->ni", Z[idx[lo:hi]], beta) / wrow[None, :]
                tot += float(np.sum(r[:, :3] ** 2))
                cnt += r[:, :3].size
            return math.sqrt(tot / cnt)
        beta, *_ = np.linalg.lstsq(Z[train].reshape(-1, p), y[train].reshape(-1), rcond=None)
        r = yy[test] - np.einsum("nip,p->ni", Z[test], beta) / wrow[None, :]
        return float(np.sqrt(np.mean(r[:, :3] ** 2)))

    # ---------------------------------------------------------------- greedy selection
    candidates = _candidates(m, sig.has_rotation)
    n_tests = len(candidates)
    theta = np.zeros(layout.size)
    x_cur = np.concatenate([x_base, np.zeros(6)])
    rotational = False
    accepted: list[Candidate] = []
    excluded: set = set()
    findings: list[Finding] = []
    ranking_json = []
    active_idx: list[int] = []
    extra = {"rotation_amplitude": rot_amp, "rotation_amplitude_std": rot_std}
    th_cov = np.zeros((layout.size, layout.size))
    thr_first = alpha / n_tests

    for step in range(max_effects):
        y_now, Am, C = design(theta, x_cur, rotational)
        # current model columns: base regressor + already active theta columns (linearised)
        base_cols = [Am] + ([C[:, :, active_idx]] if active_idx else [])
        Zbase = np.concatenate(base_cols, axis=2) * wrow[None, :, None]
        # the already-active effects are at their fitted values: regress on the current target
        y_target = (y_now + np.einsum("nij,j->ni", C[:, :, active_idx], theta[active_idx])
                    if active_idx else y_now) * wrow
        pb = Zbase.shape[2]
        rms_before = heldout_rms(Zbase, y_target)
        # candidate columns
        cand_cols = {}
        for c in candidates:
            if c in accepted:
                continue
            if c.effect == "rotational_dynamics":
                if rotational:
                    continue
                K = np.einsum("nij,j->ni", A10[:, :, :4] - A4, x_cur[:4])[:, :, None]
                cols = np.concatenate([K, A10[:, :, 4:]], axis=2)
            else:
                cols = C[:, :, layout.candidate_indices(c.effect, c.cable)]
            cand_cols[c] = cols * wrow[None, :, None]
        # statistics on the data (Frisch-Waugh: partial the base model out once)
        Q = np.linalg.qr(Zbase[train].reshape(-1, pb))[0]
        ntr = int(train.sum())

        def partial(M, Q=Q, ntr=ntr):
            M2 = M.reshape(-1, M.shape[-1]) if M.ndim == 3 else M.reshape(-1, 1)
            return (M2 - Q @ (Q.T @ M2)).reshape(ntr, 6, -1)

        yt = partial(y_target[train])[:, :, 0]
        pcols = {c: partial(cols[train]) for c, cols in cand_cols.items()}
        scored = []
        for c, Ct in pcols.items():
            stat, beta, V = _partial_wald(Ct, yt, lags)
            q = Ct.shape[2]
            scored.append((float(stats.chi2.sf(stat, q)), c, stat, q, beta, V))
        scored.sort(key=lambda r: (r[0], -r[2]))
        say(f"step {step + 1}: tested {len(scored)} candidates; calibrating on {n_null} null "
            "replicates simulated from the fitted base model")
        Yn = np.stack([partial((e_null * wrow)[train])[:, :, 0]
                       for e_null in null_residuals(x_cur[:4])], axis=-1)  # (ntr, 6, R)
        null_p = np.ones(Yn.shape[-1])
        for Ct in pcols.values():
            st = _partial_wald_many(Ct, Yn, lags)
            null_p = np.minimum(null_p, stats.chi2.sf(st, Ct.shape[2]))
        # threshold: Bonferroni, and no looser than the null's alpha-quantile of the minimum p
        thr_p = min(alpha / n_tests, float(np.quantile(null_p, alpha)) if len(null_p) else 1.0)
        step_ranking = [
            {"candidate": c.label, "statistic": float(stat), "dof": int(q), "p_value": float(p),
             "p_bonferroni": float(min(1.0, p * n_tests))}
            for p, c, stat, q, _, _ in scored[:15]
        ]
        if step == 0:
            ranking_json = step_ranking
            thr_first = thr_p
        if not scored:
            break
        chosen = False
        for p_best, c_best, stat_best, q_best, beta_best, _ in scored[:6]:
            if c_best in excluded:
                continue
            say(f"step {step + 1}: best candidate {c_best.label}: statistic {stat_best:.1f} "
                f"(dof {q_best}), p = {p_best:.2e}, threshold p < {thr_p:.2e}")
            if not p_best < thr_p:
                break
            # held-out check of the linearised extension
            Zext = np.concatenate([Zbase, cand_cols[c_best]], axis=2)
            rms_after_lin = heldout_rms(Zext, y_target)
            if rms_after_lin > rms_before * (1 - min_gain):
                say(f"step {step + 1}: {c_best.label} does not improve the held-out residual "
                    f"enough ({rms_before:.4f} -> {rms_after_lin:.4f}); stop")
                break
            # aliases: nearly as good and nearly collinear after projecting out the base
            aliases = _aliases(c_best, scored, pcols, yt)
            saved = (theta.copy(), x_cur.copy(), list(active_idx), rotational)
            if c_best.effect == "rotational_dynamics":
                rotational = True
            else:
                active_idx = sorted(set(active_idx) | set(layout.candidate_indices(
                    c_best.effect, c_best.cable)))
                theta = theta.copy()
                theta[layout.candidate_indices(c_best.effect, c_best.cable)] = beta_best[:q_best]
            # nonlinear refit of all accepted effects (Gauss-Newton, exact Jacobian)
            theta, x_cur, th_cov = _refit_gauss_newton(design, theta, x_cur, active_idx,
                                                       rotational, wrow, train, lags)
            extra = {"rotation_amplitude": rot_amp, "rotation_amplitude_std": rot_std}
            vocab = _vocab_params(c_best, theta, layout, extra, th_cov)
            why = _implausible(c_best.effect, vocab)
            if why:
                say(f"step {step + 1}: {c_best.label} refits to an implausible value ({why}); "
                    "rejected, trying the next candidate")
                theta, x_cur, active_idx, rotational = saved
                excluded.add(c_best)
                continue
            # held-out after the nonlinear refit (same split): the extension must still help
            y_new, Am_new, C_new = design(theta, x_cur, rotational)
            Zn = np.concatenate([Am_new] + ([C_new[:, :, active_idx]] if active_idx else []),
                                axis=2) * wrow[None, :, None]
            yt_new = (y_new + np.einsum("nij,j->ni", C_new[:, :, active_idx],
                                        theta[active_idx]) if active_idx else y_new) * wrow
            rms_after = heldout_rms(Zn, yt_new)
            if rms_after > rms_before * (1 - min_gain):
                say(f"step {step + 1}: after the nonlinear refit {c_best.label} improves the "
                    f"held-out residual too little ({rms_before:.4f} -> {rms_after:.4f}); "
                    "rejected, trying the next candidate")
                theta, x_cur, active_idx, rotational = saved
                excluded.add(c_best)
                continue
            accepted.append(c_best)
            chosen = True
            break
        if not chosen:
            break
        findings.append(Finding(
            effect=c_best.effect,
            parameters=vocab,
            interval=_vocab_interval(c_best, theta, np.sqrt(np.clip(np.diag(th_cov), 0, None)),
                                     layout, extra),
            aliases=aliases,
            heldout_rms_before=float(rms_before),
            heldout_rms_after=float(rms_after),
            p_value=float(min(1.0, p_best * n_tests)),
            statistic=float(stat_best),
            threshold=float(thr_p),
        ))
        say(f"step {step + 1}: accepted {c_best.label}: {findings[-1].parameters}; held-out "
            f"rms {rms_before:.4f} -> {rms_after:.4f} (weighted units)")

    # ---------------------------------------------------------------- model after selection
    feats = {k: zf(F.reshape(n, -1)).reshape(F.shape) * wrow[None, :, None] for k, F in
             structure_features(W_all, v, om, sig.tension, sig.position, sig.t, use).items()}

    def linear_model(theta, x_cur, active_idx, rotational):
        y_now, Am, C = design(theta, x_cur, rotational)
        Ca = C[:, :, active_idx]
        Z = np.concatenate([Am, Ca], axis=2) * wrow[None, :, None]
        y = (y_now + np.einsum("nij,j->ni", Ca, theta[active_idx])) * wrow
        return Z, y, Am.shape[2], C

    # ---------------------------------------------------------------- swap (take back a pick)
    ties: dict = {}
    for _ in range(len(accepted)):
        Z, y, n_model, C_now = linear_model(theta, x_cur, active_idx, rotational)
        cols_of = functools.partial(finding_columns, layout=layout, active_idx=active_idx,
                                    n_model=n_model)
        alts = {c: swap_alternatives(c, candidates, accepted) for c in accepted}

        def alt_cols(a, C_now=C_now):
            return C_now[:, :, layout.candidate_indices(a.effect, a.cable)] * wrow[None, :, None]

        k, alt, ties = best_swap(accepted, alts, Z, y, cols_of, alt_cols, heldout_rms, min_gain)
        if k is None:
            break
        saved = (theta.copy(), x_cur.copy(), list(active_idx))
        old = accepted[k]
        idx_old = layout.candidate_indices(old.effect, old.cable)
        idx_new = layout.candidate_indices(alt.effect, alt.cable)
        theta[idx_old] = 0.0
        active_idx = sorted((set(active_idx) - set(idx_old)) | set(idx_new))
        theta, x_cur, th_cov = _refit_gauss_newton(design, theta, x_cur, active_idx, rotational,
                                                   wrow, train, lags)
        vocab = _vocab_params(alt, theta, layout, extra, th_cov)
        if _implausible(alt.effect, vocab):
            theta, x_cur, active_idx = saved
            break
        say(f"swap: {old.label} -> {alt.label} predicts the held-out data better")
        accepted[k] = alt
        findings[k] = dataclasses.replace(findings[k], effect=alt.effect,
                                          aliases=sorted(set(findings[k].aliases) | {
                                              alias_label(old)}))
    th_std = np.sqrt(np.clip(np.diag(th_cov), 0, None))
    findings = [dataclasses.replace(
        fi, parameters=_vocab_params(ci, theta, layout, extra, th_cov),
        interval=_vocab_interval(ci, theta, th_std, layout, extra),
        aliases=sorted(set(fi.aliases) | {alias_label(a) for a in ties.get(ci, [])}),
        separated_by={**fi.separated_by, **{alias_label(a): separated_by(ci.effect, a.effect)
                                            for a in ties.get(ci, [])}})
        for ci, fi in zip(accepted, findings, strict=True)]

    # ---------------------------------------------------------------- backward elimination
    hints = []
    while accepted:
        Z, y, n_model, _ = linear_model(theta, x_cur, active_idx, rotational)
        struct = structure_tests({k: F[train] for k, F in feats.items()}, Z[train], y[train],
                                 wrow, lags, alpha)
        S = [feats[u["correlates_with"]] for u in struct if u["significant"]]
        Zs = np.concatenate([Z] + S, axis=2)
        cols_of = functools.partial(finding_columns, layout=layout, active_idx=active_idx,
                                    n_model=n_model)
        k, why, p_given = weakest_finding(accepted, Zs, y, cols_of, heldout_rms, train, lags,
                                          min_gain, thr_first)
        if k is None:
            break
        c = accepted.pop(k)
        f = findings.pop(k)
        cols = cols_of(c)
        beta_s, *_ = np.linalg.lstsq(Zs[train].reshape(-1, Zs.shape[2]), y[train].reshape(-1),
                                     rcond=None)
        part = np.einsum("nip,p->ni", Zs[use][:, :, cols], beta_s[cols]) / wrow[None, :]
        say(f"backward elimination: {why}; removed")
        if S:  # a vocabulary effect that only fits part of an unexplained structure: a hint
            hints.append({
                "where": c.label,
                "size": float(np.sqrt(np.mean(part[:, :3] ** 2))),
                "correlates_with": f"the vocabulary effect {c.effect} {f.parameters} fits part "
                "of the residual but is not needed given the other findings and the "
                "unexplained structure ("
                + ", ".join(u["correlates_with"] for u in struct if u["significant"]) + ")",
                "p_value": p_given,
            })
        if c.effect == "rotational_dynamics":
            rotational = False
            x_cur[4:] = 0.0
        else:
            idx = layout.candidate_indices(c.effect, c.cable)
            theta[idx] = 0.0
            active_idx = [i for i in active_idx if i not in idx]
        theta, x_cur, th_cov = _refit_gauss_newton(design, theta, x_cur, active_idx, rotational,
                                                   wrow, train, lags)
        th_std = np.sqrt(np.clip(np.diag(th_cov), 0, None))
        findings = [dataclasses.replace(
            fi, parameters=_vocab_params(ci, theta, layout, extra, th_cov),
            interval=_vocab_interval(ci, theta, th_std, layout, extra))
            for ci, fi in zip(accepted, findings, strict=True)]

    # ---------------------------------------------------------------- unexplained structure
    Z, y, _, _ = linear_model(theta, x_cur, active_idx, rotational)
    struct = structure_tests({k: F[train] for k, F in feats.items()}, Z[train], y[train], wrow,
                             lags, alpha)
    unexplained = [u for u in struct if u["significant"]] + hints
    for u in unexplained:
        say(f"unexplained: {u['where']}, {u['size']:.3g} N, like {u['correlates_with']}, "
            f"p = {u['p_value']:.2e}")

    # ---------------------------------------------------------------- extended model summary
    y_fin, Am_fin, C_fin = design(theta, x_cur, rotational)
    Zf = np.concatenate([Am_fin] + ([C_fin[:, :, active_idx]] if active_idx else []), axis=2)
    yf = (y_fin + np.einsum("nij,j->ni", C_fin[:, :, active_idx], theta[active_idx])
          if active_idx else y_fin)
    Zfw, yfw = Zf * wrow[None, :, None], yf * wrow
    names = PARAMETER_NAMES["full" if rotational else "translation"]
    pmod = len(names)
    _, beta_f, V_f, _ = _wald(Zfw[train], yfw[train], [0], lags)
    ext_params = {
        nm: {"value": float(beta_f[i]), "std": float(np.sqrt(V_f[i, i])),
             "rel_std_percent": float(100 * np.sqrt(V_f[i, i]) / max(abs(beta_f[i]), 1e-300))}
        for i, nm in enumerate(names)
    }
    base_force_ho = force_heldout_rms(Zb, yb)
    ext_force_ho = force_heldout_rms(Zfw, yfw)
    # information criterion (BIC with the effective sample size)
    n_eff = max(10.0, train.sum() / max(1.0, lags / 2.0))
    e_b = yb[train] - np.einsum("nip,p->ni", Zb[train], np.linalg.lstsq(
        Zb[train].reshape(-1, 4), yb[train].reshape(-1), rcond=None)[0])
    e_f = yfw[train] - np.einsum("nip,p->ni", Zfw[train], beta_f)
    k_b, k_f = 4, Zf.shape[2]
    bic_b = n_eff * math.log(np.mean(e_b**2)) + k_b * math.log(n_eff)
    bic_f = n_eff * math.log(np.mean(e_f**2)) + k_f * math.log(n_eff)
    info = {
        "n_samples": int(n),
        "n_train": int(train.sum()),
        "n_heldout": int(test.sum()) if test is not None else None,
        "heldout": "train/test split" if test is not None else f"blocked {n_folds}-fold CV",
        "heldout_units": "N (force rows)",
        "train_until": train_until,
        "noise_position_m": sig_p,
        "noise_tension_N": [float(s) for s in sig_tau],
        "rotation_amplitude_rad": rot_amp,
        "taut_threshold_N": taut_N,
        "n_excluded_slack": n_slack,
        "row_weights": [float(w) for w in wrow],
        "hac_lags": lags,
        "n_candidates": n_tests,
        "alpha": alpha,
        "wall_time_s": time.perf_counter() - t0,
        "weight_at_rest": _weight_at_rest(d, layout, theta, v, a, dt),
        "information_criterion": {"kind": "BIC (effective sample size)", "base": bic_b,
                                  "extended": bic_f, "n_eff": n_eff},
    }
    del pmod
    arrays = {"t": sig.t, "residual_base": e_base, "residual_extended":
              (yf - np.einsum("nip,p->ni", Zf, beta_f)), "velocity": v, "acceleration": a,
              "tension": sig.tension, "position": sig.position, "train": train, "use": use}
    say(f"done in {info['wall_time_s']:.1f} s: {len(findings)} finding(s)")
    return DiagnosisResult(base_params, base_rms, base_force_ho, findings, ext_params,
                           ext_force_ho, ranking_json, info, arrays, unexplained=unexplained)


def _weight_at_rest(d, layout, theta, v, a, dt, min_rest_s: float = 0.5):
    """Platform weight (kg) from the cable forces where the platform is at rest.

    Rest: speed < 3 cm/s over at least ``min_rest_s`` (vibrations average out). Given
    with the raw tensions and with the extended model's sensor corrections (offsets, gains,
    delay), to compare with the mass identified from the motion: a common load-cell gain is
    indistinguishable from the mass, the two must agree under the same sensor model.
    """
    from scipy.ndimage import minimum_filter1d

    still = np.linalg.norm(v, axis=1) < 0.03
    win = max(1, int(round(min_rest_s / dt)))
    rest = minimum_filter1d(still.astype(int), size=win, mode="nearest") > 0
    if rest.sum() < win:
        return None
    g = np.asarray(d.robot.gravity)
    gn = np.linalg.norm(g)
    out = {"n_samples": int(rest.sum()), "t_first": float(np.asarray(d.t)[rest][0])}
    for key, th in (("raw_kg", np.zeros(layout.size)), ("corrected_kg", theta)):
        y = np.asarray(_meas_and_jac(d, jnp.asarray(th), layout)[0])[rest]
        out[key] = float(np.mean(-(y[:, :3] @ g)) / gn**2)
    return out


def _partial_wald(Ct, yt, lags):
    """Wald statistic (HAC) of the LS of yt on Ct, both already partialled on the base model."""
    q = Ct.shape[2]
    Cf = Ct.reshape(-1, q)
    G = Cf.T @ Cf
    try:
        beta = np.linalg.solve(G, Cf.T @ yt.reshape(-1))
    except np.linalg.LinAlgError:
        return 0.0, np.zeros(q), np.eye(q)
    e = yt - np.einsum("niq,q->ni", Ct, beta)
    V = _hac_cov(Ct, e, lags)
    try:
        stat = float(beta @ np.linalg.solve(V, beta))
    except np.linalg.LinAlgError:
        stat = 0.0
    return stat, beta, V


def _partial_wald_many(Ct, Y, lags):
    """:func:`_partial_wald` statistics for many right-hand sides Y (n, 6, R) at once."""
    n, _, q = Ct.shape
    Cf = Ct.reshape(-1, q)
    G = Cf.T @ Cf
    Ginv = np.linalg.pinv(G)
    B = Ginv @ (Cf.T @ Y.reshape(-1, Y.shape[-1]))  # (q, R)
    E = Y - np.einsum("niq,qr->nir", Ct, B)
    S = np.einsum("niq,nir->nqr", Ct, E)  # (n, q, R)
    L = int(lags) + 1
    c = np.concatenate([np.zeros((1, q, S.shape[2])), np.cumsum(S, axis=0)])
    hi = np.minimum(np.arange(n + L - 1) + 1, n)
    lo = np.maximum(np.arange(n + L - 1) - L + 1, 0)
    M = c[hi] - c[lo]  # (n+L-1, q, R)
    meat = np.einsum("kqr,kpr->rqp", M, M) / L
    V = Ginv[None] @ meat @ Ginv[None]  # (R, q, q)
    out = np.empty(B.shape[1])
    for r in range(B.shape[1]):
        try:
            out[r] = B[:, r] @ np.linalg.solve(V[r], B[:, r])
        except np.linalg.LinAlgError:
            out[r] = 0.0
    return out


def _aliases(c_best, scored, pcols, yt, corr: float = 0.8) -> list[str]:
    """Candidates the data cannot tell apart from the winner.

    An alternative is an alias when its HAC Wald statistic is within
    ``max(25, 5 %)`` of the winner's (it explains the residual nearly as well, the difference
    being of the order of the noise) and the largest canonical correlation between the two
    column spaces, with the base model partialled out, is at least ``corr``.
    """
    stat_best = next(st for _, c, st, _, _, _ in scored if c == c_best)
    margin = max(25.0, 0.05 * stat_best)
    Qb, _ = np.linalg.qr(pcols[c_best].reshape(-1, pcols[c_best].shape[2]))
    out = []
    for _, c, st, _, _, _ in scored[:25]:
        if c == c_best or st < stat_best - margin:
            continue
        Qc, _ = np.linalg.qr(pcols[c].reshape(-1, pcols[c].shape[2]))
        s = np.linalg.svd(Qb.T @ Qc, compute_uv=False)
        if s.max() >= corr:
            out.append(c.effect if c.cable is None else f"{c.effect}:cable={c.cable}")
    return out


def _refit_gauss_newton(design, theta, x0, active_idx, rotational, wrow, train, lags,
                        max_iter: int = 10, tol: float = 1e-7):
    """Nonlinear least squares on (x, active theta): Gauss-Newton with the exact Jacobian.

    Every iteration re-linearises the full nonlinear model (``design``: the per-cable JAX
    Jacobian of the cable side, compiled once, filtered by the matched filter) and solves the
    weighted linear LS for (x, theta_active) in closed form (x enters linearly: variable
    projection). No recompilation per active set, which keeps the diagnosis within its time
    budget. Returns theta, x (10,) and the HAC covariance of theta.
    """
    theta = np.array(theta, float)
    px = 10 if rotational else 4
    x = np.array(x0, float)
    ai = np.asarray(active_idx, int)
    V = np.zeros((px + len(ai), px + len(ai)))
    for _ in range(max_iter):
        y, A, C = design(theta, x, rotational)
        Ca = C[:, :, ai]
        Z = np.concatenate([A, Ca], axis=2) * wrow[None, :, None]
        tgt = (y + np.einsum("nij,j->ni", Ca, theta[ai])) * wrow
        p = Z.shape[2]
        beta, *_ = np.linalg.lstsq(Z[train].reshape(-1, p), tgt[train].reshape(-1), rcond=None)
        step = beta[px:] - theta[ai]
        theta[ai] = beta[px:]
        x[:px] = beta[:px]
        e = tgt[train] - np.einsum("nip,p->ni", Z[train], beta)
        V = _hac_cov(Z[train], e, lags)
        scale = np.sqrt(np.clip(np.diag(V)[px:], 1e-30, None))
        if len(ai) == 0 or np.max(np.abs(step) / scale) < tol * 1e3:
            break
    th_cov = np.zeros((len(theta), len(theta)))
    if len(ai):
        th_cov[np.ix_(ai, ai)] = V[px:, px:]
    return theta, x, th_cov


# ----------------------------------------------------------------------------- residual structure


#: generic signals the residual of the extended model is tested against (unexplained stage)
STRUCTURE_SIGNALS = ("sign of cable velocity", "tension level", "pose", "time (slow drift)")


def structure_features(W_all, v, om, tension, position, t, use) -> dict:
    """Generic residual-structure regressors, unfiltered, ``(n, 6, q)`` each.

    These are not effects of the vocabulary: they describe what a remaining residual is
    *like*. ``sign of cable velocity`` is ``W_i sign(dl_i/dt)`` per cable (a Coulomb-like
    force along each cable, with ``dl/dt = -W^T [v; omega]``); ``tension level`` is
    ``W_i (z_i^2 - 1)`` with z_i the standardised tension (a load cell that is not linear);
    ``pose`` is a force linear in the position, per force axis; ``time (slow drift)`` is a
    force that drifts as Legendre polynomials of degree 1-3 in time, per force axis.

    Parameters
    ----------
    W_all : (n, 6, m) nominal wrench matrices
    v, om : (n, 3) platform velocity and angular rate
    tension : (n, m) tensions at the pose times
    position : (n, 3)
    t : (n,)
    use : (n,) bool, the samples that are fitted

    Returns
    -------
    dict
        Signal name (one of :data:`STRUCTURE_SIGNALS`) -> array ``(n, 6, q)``.
    """
    n = W_all.shape[0]
    twist = np.concatenate([v, om], axis=1)
    ldot = -np.einsum("nim,ni->nm", W_all, twist)
    tz = (tension - tension[use].mean(0)) / np.maximum(tension[use].std(0), 1e-9)
    pc = position - position[use].mean(0)
    tu = t[use]
    s = 2.0 * (t - tu[0]) / max(tu[-1] - tu[0], 1e-9) - 1.0
    legendre = [s, 0.5 * (3 * s**2 - 1), 0.5 * (5 * s**3 - 3 * s)]
    P = np.zeros((n, 6, 9))
    D = np.zeros((n, 6, 9))
    for j in range(3):
        for k in range(3):
            P[:, j, 3 * j + k] = pc[:, k]
            D[:, j, 3 * j + k] = legendre[k]
    return {
        "sign of cable velocity": W_all * np.sign(ldot)[:, None, :],
        "tension level": W_all * (tz**2 - 1.0)[:, None, :],
        "pose": P,
        "time (slow drift)": D,
    }


def _where(name: str, beta, V) -> str:
    """Which cables / force axes a structure sits on (coefficients with |t| > 3)."""
    tstat = np.abs(beta) / np.sqrt(np.clip(np.diag(V), 1e-300, None))
    if name in ("sign of cable velocity", "tension level"):
        idx = [i + 1 for i in np.nonzero(tstat > 3)[0]]
        return ("load cells of cables " + ", ".join(map(str, idx))) if idx else "all cables"
    axes = sorted({"xyz"[i // 3] for i in np.nonzero(tstat > 3)[0]})
    return ("force along " + ", ".join(axes)) if axes else "force rows"


def structure_tests(feats: dict, Z, y, wrow, lags: int, alpha: float) -> list:
    """Test the residual of ``y ~ Z`` for generic structure, strongest first (stepwise).

    Each signal is tested (HAC Wald, Bonferroni over the signals) given the model and the
    signals already found significant, so that one structure is not reported again under
    the name of a correlated signal.

    Parameters
    ----------
    feats : dict
        Signal name -> weighted, matched-filtered regressors ``(n, 6, q)`` (training rows).
    Z : (n, 6, p)
        The extended model's columns (weighted, training rows).
    y : (n, 6)
        Its target (weighted, training rows).
    wrow : (6,) row weights (to give sizes in newtons)
    lags : int
        HAC lag window.
    alpha : float
        Family-wise level; every signal is returned, ``significant`` marks p < alpha.

    Returns
    -------
    list of dict
        ``where``, ``size`` (RMS force in N of the fitted structure), ``correlates_with``,
        ``p_value`` (Bonferroni over the signals), ``coefficients`` and ``significant``.
    """
    out: list = []
    left = dict(feats)
    while left:
        tests = _structure_step(left, Z, y, wrow, lags, alpha, len(feats))
        if not tests:
            break
        best = min(tests, key=lambda u: u["p_value"])
        if not best["significant"]:
            return out + sorted(tests, key=lambda u: u["p_value"])
        out.append(best)
        Z = np.concatenate([Z, left.pop(best["correlates_with"])], axis=2)
    return out


def _structure_step(feats, Z, y, wrow, lags, alpha, n_signals):
    n, _, p = Z.shape
    Q = np.linalg.qr(Z.reshape(-1, p))[0]

    def partial(M):
        M2 = M.reshape(n * 6, -1)
        return (M2 - Q @ (Q.T @ M2)).reshape(n, 6, -1)

    yt = partial(y)[:, :, 0]
    out = []
    for name, F in feats.items():
        Ft = partial(F)
        keep = np.linalg.norm(Ft.reshape(-1, Ft.shape[2]), axis=0) > 1e-9 * max(
            1.0, float(np.linalg.norm(F)))
        Ft = Ft[:, :, keep]
        if Ft.shape[2] == 0:
            continue
        stat, beta, V = _partial_wald(Ft, yt, lags)
        pv = float(min(1.0, stats.chi2.sf(stat, Ft.shape[2]) * n_signals))
        fit = np.einsum("niq,q->ni", Ft, beta) / wrow[None, :]
        out.append({
            "where": _where(name, beta, V),
            "size": float(np.sqrt(np.mean(fit[:, :3] ** 2))),
            "correlates_with": name,
            "p_value": pv,
            "coefficients": [float(b) for b in beta],
            "significant": bool(pv < alpha),
        })
    return out


def finding_columns(c: Candidate, layout: ThetaLayout, active_idx: list, n_model: int) -> list:
    """Columns of the linearised extended model ``[A, C_active]`` that belong to a finding."""
    if c.effect == "rotational_dynamics":
        return list(range(4, n_model))
    idx = layout.candidate_indices(c.effect, c.cable)
    return [n_model + active_idx.index(i) for i in idx]


def weakest_finding(accepted: list, Z, y, cols_of, heldout_rms, train, lags: int,
                    min_gain: float, thr_p: float):
    """Backward step: the finding whose removal hurts held-out prediction least, if it fails.

    A finding stays when removing it (given every other column of ``Z``: the other
    findings, and the unexplained structure when there is one) worsens the held-out RMS by
    more than ``min_gain`` (relative) AND its HAC Wald test given the others passes
    ``thr_p``. Returns ``(index, reason, p)`` of the worst failing finding (p: its Wald
    p-value given the others), or ``(None, '', 1.0)``.
    """
    p = Z.shape[2]
    rms_full = heldout_rms(Z, y)
    worst, worst_gain, reason, worst_p = None, np.inf, "", 1.0
    for k, c in enumerate(accepted):
        cols = cols_of(c)
        rest = [j for j in range(p) if j not in cols]
        rms_minus = heldout_rms(Z[:, :, rest], y)
        gain = 1.0 - rms_full / rms_minus
        Zr = Z[train][:, :, rest]
        Q = np.linalg.qr(Zr.reshape(-1, len(rest)))[0]
        ntr = Zr.shape[0]
        Ct = Z[train][:, :, cols].reshape(-1, len(cols))
        Ct = (Ct - Q @ (Q.T @ Ct)).reshape(ntr, 6, -1)
        yt = y[train].reshape(-1, 1)
        yt = (yt - Q @ (Q.T @ yt)).reshape(ntr, 6)
        stat, _, _ = _partial_wald(Ct, yt, lags)
        pv = float(stats.chi2.sf(stat, len(cols)))
        fails = gain < min_gain or not pv < thr_p
        if fails and gain < worst_gain:
            worst, worst_gain, worst_p = k, gain, pv
            reason = (f"{c.label}: removing it changes the held-out rms by {100 * gain:.2f} % "
                      f"(p = {pv:.2e}) given the others")
    return worst, reason, worst_p


#: what would separate two effects the data cannot tell apart (for ``separated_by``)
_SEPARATE = {
    frozenset({"tension_offset", "tension_gain"}):
        "a trajectory with a wider range of tension on that cable (a gain scales with the "
        "tension, an offset does not)",
    frozenset({"tension_gain", "exit_point_error"}):
        "the same poses at two pretension levels (a gain scales with the tension, a "
        "direction error with the pose)",
    frozenset({"tension_gain", "anchor_point_error"}):
        "the same poses at two pretension levels (a gain scales with the tension, a "
        "direction error with the pose)",
    frozenset({"exit_point_error", "anchor_point_error"}):
        "rotations of the platform (an attachment error turns with it, an exit error does not)",
    frozenset({"time_delay", "viscous_drag"}):
        "faster motion with the same velocities (a delay follows the tension rate, drag the "
        "velocity)",
    frozenset({"viscous_drag", "pulley_friction"}):
        "motion at several speeds (Coulomb friction does not grow with the speed)",
}


def separated_by(a: str, b: str) -> str:
    """What measurement or trajectory would separate effects ``a`` and ``b``."""
    return _SEPARATE.get(frozenset({a, b}),
                         "a longer trajectory that excites different poses, speeds and tensions")


def swap_alternatives(c: Candidate, candidates: list, accepted: list) -> list:
    """Alternatives to a finding tried by the swap stage: same cable, or global effects."""
    out = []
    for a in candidates:
        if a in accepted or a.effect == "rotational_dynamics" or a == c:
            continue
        if a.cable is None or a.cable == c.cable:
            out.append(a)
    return out


def best_swap(accepted: list, alts: dict, Z, y, cols_of, alt_cols, heldout_rms,
              min_gain: float):
    """Swap step: replace one finding by an alternative when that predicts held-out better.

    Returns ``(k, alternative, ties)``: the finding index and its better replacement (or
    ``None``), and for every finding the alternatives within ``min_gain`` of it (the data
    cannot tell them apart: reported as aliases).
    """
    p = Z.shape[2]
    rms_now = heldout_rms(Z, y)
    best, best_rms = (None, None), rms_now * (1.0 - min_gain)
    ties = {}
    for k, c in enumerate(accepted):
        if c.effect == "rotational_dynamics":
            continue
        rest = [j for j in range(p) if j not in cols_of(c)]
        ties[c] = []
        for a in alts[c]:
            r = heldout_rms(np.concatenate([Z[:, :, rest], alt_cols(a)], axis=2), y)
            if r < best_rms:
                best, best_rms = (k, a), r
            elif r < rms_now * (1.0 + min_gain):
                ties[c].append(a)
    return best[0], best[1], ties


def save_report(result: DiagnosisResult, out_dir, dataset_name: str = "dataset") -> Path:
    """Write ``report.md`` and PNG figures of a diagnosis into ``out_dir``."""
    from .plots import diagnosis_figures

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    figs = diagnosis_figures(result, out)
    lines = [f"# Diagnosis of {dataset_name}", ""]
    bp = result.base_parameters
    lines += ["## Base model (paper, translation only, matched filtering)", "",
              "| parameter | estimate | std (HAC) | %std |", "|---|---|---|---|"]
    for k, v in bp.items():
        lines.append(f"| {k} | {v['value']:.6g} | {v['std']:.3g} | {v['rel_std_percent']:.3g} |")
    lines += ["", "Residual RMS per wrench axis (fx, fy, fz [N], mx, my, mz [N m]): "
              + ", ".join(f"{r:.4g}" for r in result.base_residual_rms), ""]
    lines += ["## Findings", ""]
    if not result.findings:
        lines.append("No effect passes the tests: the paper's model explains this data within "
                     "its noise (every candidate of the vocabulary was tested).")
    for f in result.findings:
        lines.append(f"- **{f.effect}** {f.parameters}; 95 % interval {f.interval}; "
                     f"held-out rms {f.heldout_rms_before:.4g} -> {f.heldout_rms_after:.4g} "
                     f"(weighted units); p (Bonferroni) = {f.p_value:.2e}"
                     + (f"; indistinguishable on this data from: {', '.join(f.aliases)}"
                        if f.aliases else ""))
    lines += ["", "## Extended model", "", "| parameter | estimate | std (HAC) | change vs base |",
              "|---|---|---|---|"]
    for k, v in result.extended_parameters.items():
        ch = v["value"] - bp[k]["value"] if k in bp else float("nan")
        lines.append(f"| {k} | {v['value']:.6g} | {v['std']:.3g} | {ch:+.4g} |")
    lines += ["", f"Held-out force residual RMS: base {result.base_heldout_rms:.4g} N -> "
              f"extended {result.extended_heldout_rms:.4g} N ({result.info['heldout']}).", ""]
    w = result.info.get("weight_at_rest")
    if w:
        lines += [f"Weight at rest ({w['n_samples']} samples from t = {w['t_first']:.3g} s): "
                  f"{w['raw_kg']:.4g} kg from the raw tensions, {w['corrected_kg']:.4g} kg with "
                  "the extended model's sensor corrections; a common load-cell gain is "
                  "indistinguishable from the mass, so compare m with the latter.", ""]
    ic = result.info["information_criterion"]
    lines += [f"Information criterion ({ic['kind']}): base {ic['base']:.1f}, extended "
              f"{ic['extended']:.1f}.", ""]
    lines += ["## Candidate ranking (first step)", "",
              "| candidate | statistic | dof | p | p Bonferroni |", "|---|---|---|---|---|"]
    for r in result.ranking:
        lines.append(f"| {r['candidate']} | {r['statistic']:.1f} | {r['dof']} | "
                     f"{r['p_value']:.2e} | {r['p_bonferroni']:.2e} |")
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out / "report.md"
