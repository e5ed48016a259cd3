"""Optimal excitation trajectories: a differentiable identifiability objective, safety
constraints, a jit-compiled multi-start optimiser and an exact safety certificate.

Objective (paper section 4). Along a trajectory sampled at times t_k the identification stacks
``W_ID = [A_1; ...; A_ne]`` (eq. 11) with ``A_k`` the regressor of eq. (10) or of the
10-parameter model (:func:`cdprid.core.regressors`), built here from the trajectory's
*analytic* accelerations. With the information matrix ``M = W_ID^T W_ID`` (p x p):

- ``cond(W_ID) = sqrt(lambda_max(M) / lambda_min(M))`` (raw) and the same after scaling
  every column of W_ID to unit norm (``cond_scaled``);
- D-optimality ``-log det(M / n_rows + delta I)``;
- predicted standard deviations ``sigma_x = sigma_rho sqrt(diag(M^-1))`` (eq. 20), and
  relative ones ``sigma_x / |x_nominal|`` (eq. 21), only where the nominal value is not 0.

Inside the optimiser the condition number is replaced by a smooth surrogate without any
eigen-decomposition: ``lambda_max ~ tr(M^k)^(1/k)`` and ``lambda_min ~ tr(M^-k)^(-1/k)`` with
k = 32, by repeated normalised squaring; it bounds the exact value from above by at most a
factor ``p^(1/k)`` (< 1.08 for p = 10).

Constraints (smooth penalties on the 10 Hz optimisation grid, at the fractions of
:class:`Fractions` of each limit so that the exact check on the dense output passes): the
workspace box, cable speeds, acceleration and jerk of P, tilt, angular velocity and
acceleration, cable-cable and cable-body clearance (:mod:`cdprid.model._clearance`), and a robust
tension margin over the interval hull of the platform's uncertainty box
(:func:`robust_tension_margin_smooth`). Limits and uncertainty: :mod:`cdprid.excitation._safety`
(stated defaults, never silent). Afterwards :mod:`cdprid.excitation._check` certifies the whole
trajectory (with the moves from and back to ``home``) exactly: kinematics at 500 Hz,
clearances and tensions (LP at every corner of the uncertainty box) on the 100 Hz grid of the
written CSV. An uncertified trajectory is never returned.

Families: :mod:`cdprid.excitation._families`.
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

from cdprid.base._errors import UserError
from cdprid.core._regression import regressors, wrench_matrices
from cdprid.excitation._check import SafetyCertificate, certify_trajectory, limit_ratios
from cdprid.excitation._families import (
    FAMILIES,
    FourierFamily,
    FourierTrajectory,
    HomedTrajectory,
    OrbitFamily,
    make_family,
    move_duration,
)
from cdprid.excitation._safety import (
    SafetyLimits,
    UncertaintyBox,
    safety_limits,
    uncertainty_from_prior,
    uncertainty_from_robot,
)
from cdprid.model._clearance import cable_pairs, smooth_clearances
from cdprid.model._dynamics import PARAMETER_NAMES, InertialParameters
from cdprid.model._geometry import CableRobot
from cdprid.model._rotations import quat_to_matrix
from cdprid.model._trajectories import TrajectoryState

__all__ = [
    "FAMILIES",
    "OBJECTIVES",
    "ExcitationProblem",
    "ExcitationResult",
    "DesignReport",
    "Fractions",
    "OrbitFamily",
    "FourierFamily",
    "FourierTrajectory",
    "HomedTrajectory",
    "make_family",
    "make_problem",
    "parse_home",
    "stacked_regressor",
    "information_cond",
    "soft_log_cond",
    "d_optimality",
    "predicted_sigma",
    "tension_margin_smooth",
    "robust_tension_margin_smooth",
    "certify_tensions",
    "evaluate_design",
    "optimise_excitation",
    "start_points",
    "slsqp_baseline",
    "GENTLE_FRACTION",
    "fit_to_limits",
    "initial_design",
    "gentle_run",
    "CERTIFICATE_SCOPE",
]

#: What the certificate proves, and what it does not (written to the JSON).
CERTIFICATE_SCOPE = (
    "Checked exactly on samples: acceleration, jerk, tilt, angular velocity and acceleration on "
    "a 500 Hz grid and the 100 Hz grid; workspace, cable speeds, cable-cable and cable-body "
    "clearances and tension feasibility (LP) on the 100 Hz grid of trajectory.csv, with the "
    "moves from and back to home. Tensions: at every point of a set whose convex hull holds "
    "every platform of the uncertainty box (robot.toml [platform]: mass, centre of mass per "
    "axis and principal moments, the m s s^T term of the inertia about P included; --prior: "
    "the box estimate +- 3 std in x, inertia from robot.toml when the prior has none). Not "
    "covered: values between samples (10 ms apart; the optimiser keeps margins for this), "
    "platforms outside the stated box, cable elasticity, pulley geometry errors and the "
    "tracking error of the controller.")

#: Fraction of every kinematic limit (and of the cable speed) that the default initial design,
#: the "gentle first run", stays within (see :func:`initial_design`).
GENTLE_FRACTION = 0.5

OBJECTIVES = ("cond", "cond_scaled", "dopt", "sigma")


# =============================================================================== objective


def stacked_regressor(states: TrajectoryState, gravity, model: str = "translation"):
    """W_ID (6 n, p) of eq. (11) from analytic motion states
    (:func:`cdprid.core.regressors`)."""
    R = jax.vmap(quat_to_matrix)(states.q)
    A = regressors(model, R, states.a, states.omega, states.alpha, gravity)
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


# =============================================================================== constraints


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


def robust_tension_margin_smooth(W, A_full, x_lo, x_hi, tmin: float, tmax: float,
                                 temperature: float = 0.5):
    """Smooth, conservative tension margin (N) of one sample over a box of parameters.

    The centred least-norm distribution ``tau(x) = base + G x`` with ``G = W^+ A_full`` is
    linear in ``x = [m, m s_G, I_P]``; over the box ``[x_lo, x_hi]`` its i-th tension ranges
    over ``base_i + G_i x_mid +- |G_i| x_half`` exactly. Soft minimum of the distances of those
    ranges to the bounds (never above the true worst case of that distribution).
    """
    mid = 0.5 * (tmin + tmax)
    tau0 = jnp.full(W.shape[1], mid)
    WWt = W @ W.T + 1e-10 * jnp.eye(6)
    rhs = jnp.concatenate([A_full, (W @ tau0)[:, None]], axis=1)
    sol = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(WWt), rhs)
    G = W.T @ sol[:, :-1]  # (m, 10)
    base = tau0 - W.T @ sol[:, -1]
    xm, xh = 0.5 * (x_lo + x_hi), 0.5 * (x_hi - x_lo)
    centre = base + G @ xm
    spread = jnp.abs(G) @ xh
    return _softmin(jnp.concatenate([centre - spread - tmin, tmax - centre - spread]), temperature)


def _cholesky_solve(A, b):
    """``A^-1 b`` for a small symmetric positive-definite ``A`` by an unrolled Cholesky.

    Written with scalar entries so that, vmapped over the samples of a trajectory, every
    operation is one fused vector operation across samples (cheaper than a batched LAPACK
    solve of 6 x 6 systems, gradients included). ``b`` may be a vector or a matrix (rows
    ``b[i]``). Same result as ``jnp.linalg.solve`` to rounding (tested).
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


def certify_tensions(W, w, tmin: float, tmax: float):
    """Per-sample largest tension margin (N) by a linear programme through CasADi (HiGHS).

    Parameters
    ----------
    W : array (n, 6, m)
        Wrench matrices (eq. 2).
    w : array (n, 6)
        Required wrenches.
    tmin, tmax : float
        Tension limits, N.

    Returns
    -------
    margin : ndarray (n,)
        ``max s`` such that some tau with ``W tau = w`` lies in ``[tmin + s, tmax - s]``;
        ``-inf`` where ``W tau = w`` has no solution.
    """
    from cdprid.model._tensions import feasibility_margin

    return np.atleast_1d(feasibility_margin(np.asarray(W, float), np.asarray(w, float), tmin, tmax))


# =============================================================================== problem


@dataclasses.dataclass(frozen=True)
class Fractions:
    """Safety factors of the optimiser: its constraints use these fractions of each limit so
    that the exact check on the dense output grid (not only the 10 Hz optimisation grid)
    passes. ``clearance`` multiplies the cable clearance; ``workspace_m`` is kept inside the
    box; ``tension_N`` is the robust tension margin aimed at (capped at 10 % of the range and
    at half the margin at rest: :attr:`ExcitationProblem.tension_target`)."""

    kinematic: float = 0.92
    speed: float = 0.85
    clearance: float = 1.5
    workspace_m: float = 0.02
    tension_N: float = 3.0


@dataclasses.dataclass(frozen=True)
class ExcitationProblem:
    """Everything the objective needs: robot, family, model, limits, uncertainty box, home."""

    robot: CableRobot
    family: object
    model: str
    objective: str
    limits: SafetyLimits
    box: UncertaintyBox
    home: np.ndarray
    tension_target: float = 3.0
    rate_opt_hz: float = 10.0
    fine_factor: int = 4  # kinematic constraints on a 4x finer grid (40 Hz)
    sigma_rho: float = 1.0
    fractions: Fractions = Fractions()
    penalty: float = 30.0

    @property
    def nominal(self) -> InertialParameters:
        return self.box.nominal

    @property
    def tmin(self) -> float:
        return self.limits.tension_min

    @property
    def tmax(self) -> float:
        return self.limits.tension_max

    @property
    def speed_max(self) -> float:
        return self.limits.cable_speed_max

    @property
    def names(self) -> tuple:
        return PARAMETER_NAMES[self.model]

    @property
    def pulleys(self) -> bool:
        return self.robot.has_pulleys

    @property
    def pairs(self) -> tuple:
        """Cable pairs whose clearance is checked (:func:`cdprid.model.cable_pairs`)."""
        return tuple(tuple(int(v) for v in p) for p in cable_pairs(self.robot))

    def grid(self, rate_hz: float) -> np.ndarray:
        d = self.family.duration
        n = int(np.floor(d * rate_hz + 1e-9)) + 1
        return np.arange(n) / rate_hz

    def homed(self, z) -> HomedTrajectory:
        """The trajectory of coordinates z with the moves from and back to home."""
        fam = self.family
        start = np.asarray(fam.to_params(jnp.asarray(z))["centre"])
        lim = self.limits
        T = move_duration(np.linalg.norm(start - self.home), lim.cable_speed_max,
                          lim.acceleration_max, lim.jerk_max)
        return HomedTrajectory(fam, jnp.asarray(z, float), jnp.asarray(self.home, float), T)


def parse_home(text: str | None, limits: SafetyLimits) -> np.ndarray:
    """``--home x,y,z`` (m, base frame; default the workspace centre), inside the workspace."""
    lo, hi = np.asarray(limits.workspace_min), np.asarray(limits.workspace_max)
    if text is None:
        return 0.5 * (lo + hi)
    try:
        h = np.array([float(v) for v in str(text).split(",")])
    except ValueError:
        raise UserError(f"--home: expected three numbers x,y,z in m, got {text!r}.") from None
    if h.shape != (3,) or not np.all(np.isfinite(h)):
        raise UserError(f"--home: expected three finite numbers x,y,z in m, got {text!r}.")
    if np.any(h < lo) or np.any(h > hi):
        raise UserError(f"--home: {text} is outside the workspace box {lo.tolist()} .. "
                        f"{hi.tolist()}.")
    return h


def make_problem(robot: CableRobot, family: str = "orbit", objective: str = "cond",
                 model: str | None = None, duration: float | None = None,
                 prior: str | None = None, home: str | None = None, **kw) -> ExcitationProblem:
    """An :class:`ExcitationProblem` for a robot.

    Limits from robot.toml with stated defaults (:func:`cdprid.excitation.safety_limits`);
    the uncertainty box from ``prior`` (``cdprid identify --json``) or robot.toml ``[platform]``
    (a UserError when neither gives the platform); ``home`` as ``"x,y,z"`` (default: the
    workspace centre). ``model`` defaults to ``translation`` for the orbit families and ``full``
    for ``fourier``.
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective {objective!r}; use one of {', '.join(OBJECTIVES)}.")
    if family not in FAMILIES:
        raise ValueError(f"unknown excitation family {family!r}; use one of {', '.join(FAMILIES)}.")
    model = model or ("full" if family == "fourier" else "translation")
    if model not in PARAMETER_NAMES:
        raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")
    rotates = family == "fourier"
    if model == "full" and not rotates:
        raise ValueError(f"the 10-parameter model needs rotations; the {family!r} family does not "
                         "rotate (use --family fourier).")
    box = (uncertainty_from_prior(prior, robot, rotates) if prior is not None
           else uncertainty_from_robot(robot, rotates))
    limits = safety_limits(robot, box.mass_max)
    fam = make_family(family, limits.workspace_min, limits.workspace_max, duration)
    home_p = parse_home(home, limits)
    kw.setdefault("tension_target", _tension_target(robot, limits, box, fam, kw))
    return ExcitationProblem(robot, fam, model, objective, limits, box, home_p, **kw)


def _tension_target(robot, limits, box, family, kw) -> float:
    """The robust tension margin the optimiser aims at (N): ``fractions.tension_N``, at most
    10 % of the tension range and half the (smooth, worst-corner) margin of the platform at
    rest at the initial design's start point, so that the aim is reachable."""
    fr = kw.get("fractions", Fractions())
    centre = family.initial_params(robot)["centre"]
    R = jnp.eye(3)
    W = wrench_matrices(robot, jnp.asarray(centre)[None], R[None])[0]
    A = regressors("full", R[None], jnp.zeros((1, 3)), jnp.zeros((1, 3)), jnp.zeros((1, 3)),
                   robot.gravity)[0]
    rest = float(robust_tension_margin_smooth(W, A, jnp.asarray(box.x_lo), jnp.asarray(box.x_hi),
                                              limits.tension_min, limits.tension_max))
    return float(min(fr.tension_N, 0.1 * (limits.tension_max - limits.tension_min), 0.5 * rest))


def _objective_value(prob, W_ID):
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


def _norm(x):
    return jnp.sqrt(jnp.sum(x * x, axis=-1) + 1e-12)


def _kinematic_margins(prob, states):
    """Normalised margins (n, k) of acceleration, jerk and (rotating families) tilt, angular
    velocity and acceleration, at ``fractions.kinematic`` of the limits."""
    lim, f = prob.limits, prob.fractions.kinematic
    pairs = [(_norm(states.a), lim.acceleration_max), (_norm(states.j), lim.jerk_max)]
    if prob.family.rotates:
        tilt = 2.0 * jnp.arctan2(_norm(states.q[:, 1:]), jnp.abs(states.q[:, 0]))
        pairs += [(tilt, lim.tilt_max), (_norm(states.omega), lim.angular_velocity_max),
                  (_norm(states.alpha), lim.angular_acceleration_max)]
    return jnp.stack([(f * L - v) / (0.05 * L) for v, L in pairs], axis=1)


def _constraint_margins(prob, states, states_fine=None):
    """Per-sample normalised margins (>= 0 feasible): workspace, speed, tension, kinematics
    (on ``states_fine`` when given: a finer grid, cheap), clearance."""
    fr, lim = prob.fractions, prob.limits
    lo = jnp.asarray(lim.workspace_min) + fr.workspace_m
    hi = jnp.asarray(lim.workspace_max) - fr.workspace_m
    ws = jnp.minimum(states.p - lo, hi - states.p) / 0.05  # (n, 3)
    R = jax.vmap(quat_to_matrix)(states.q)
    Wm = wrench_matrices(prob.robot, states.p, R)
    sp = (fr.speed * lim.cable_speed_max - jnp.abs(_cable_speeds(Wm, states)))
    sp = sp / (0.05 * lim.cable_speed_max)
    A = regressors("full", R, states.a, states.omega, states.alpha, prob.robot.gravity)
    x_lo, x_hi = jnp.asarray(prob.box.x_lo), jnp.asarray(prob.box.x_hi)
    tm = jax.vmap(lambda W_, A_: robust_tension_margin_smooth(W_, A_, x_lo, x_hi, lim.tension_min,
                                                              lim.tension_max))(Wm, A)
    target = prob.tension_target
    tn = (tm - target) / max(1.0, abs(target))
    clr = lim.cable_clearance
    cc, cb = smooth_clearances(prob.robot, states.p, R, np.asarray(prob.pairs, int).reshape(-1, 2),
                               pulleys=prob.pulleys)
    cl = (jnp.stack([cc, cb], axis=1) - fr.clearance * clr) / clr
    kin = _kinematic_margins(prob, states if states_fine is None else states_fine)
    return ws, sp, tn, kin, cl


def _penalised(z, prob, t, t_fine=None):
    fine = None if t_fine is None else prob.family.states(z, t_fine)
    k = 0 if fine is None or t.shape[0] < 2 else (t_fine.shape[0] - 1) // (t.shape[0] - 1)
    if k >= 1 and -(-t_fine.shape[0] // k) == t.shape[0]:
        # the optimisation grid is every k-th point of the fine grid: one evaluation serves both
        states = jax.tree_util.tree_map(lambda x: x[::k], fine)
    else:
        states = prob.family.states(z, t)
    W_ID = stacked_regressor(states, prob.robot.gravity, prob.model)
    f = _objective_value(prob, W_ID)
    pen = sum(jnp.sum(jax.nn.relu(-c) ** 2) for c in _constraint_margins(prob, states, fine))
    return f + prob.penalty * pen, (f, pen)


# =============================================================================== evaluation


@dataclasses.dataclass(frozen=True)
class DesignReport:
    """Metrics of one design (with its moves from and back to home) on the 100 Hz grid.

    ``cond``/``cond_scaled`` by numpy SVD of W_ID (:func:`cdprid.core.condition_number`),
    ``sigma`` the predicted standard deviations at ``sigma_rho`` (N per row) and ``rel_sigma``
    relative to the nominal parameters (None where the nominal value is 0: not meaningful);
    ``certificate`` the exact check of every limit (:mod:`cdprid.excitation._check`).
    """

    params: dict
    z: np.ndarray
    cond: float
    cond_scaled: float
    dopt: float
    objective: float
    sigma: dict
    rel_sigma: dict
    certificate: SafetyCertificate
    t_move: float
    duration: float

    @property
    def certified(self) -> bool:
        return self.certificate.certified

    @property
    def min_tension_margin_N(self) -> float:
        """Worst tension margin over the samples and the uncertainty box (N)."""
        return self.certificate.robust_margin_N

    def as_json(self) -> dict:
        c = self.certificate
        return {
            "cond": self.cond, "cond_scaled": self.cond_scaled, "dopt": self.dopt,
            "objective": self.objective,
            "params": {k: np.asarray(v).tolist() for k, v in self.params.items()},
            "sigma": self.sigma, "rel_sigma": self.rel_sigma,
            "min_tension_margin_N": c.robust_margin_N,
            "robust_tension_margin_N": c.robust_margin_N,
            "nominal_tension_margin_N": c.nominal_margin_N,
            "max_cable_speed_m_s": c.peaks["cable_speed_m_s"],
            "workspace_ok": c.peaks["workspace_distance_m"] >= 0.0,
            "cable_speed_ok": not any(f.startswith("cable_speed") for f in c.failed),
            "peaks": c.peaks, "failed_checks": list(c.failed),
            "worst_corner_parameters": dict(zip(PARAMETER_NAMES["full"], c.worst_corner,
                                                strict=True)),
            "n_lp_solved": c.n_lp,
            "move_duration_s": self.t_move, "duration_s": self.duration,
            "certified": self.certified,
        }


class _ProbModule(eqx.Module):
    """Pytree view of an ExcitationProblem for filter_jit (everything but arrays static)."""

    robot: CableRobot
    family: object
    nominal: InertialParameters
    model: str = eqx.field(static=True)
    objective: str = eqx.field(static=True)
    limits: SafetyLimits = eqx.field(static=True)
    box: UncertaintyBox = eqx.field(static=True)
    sigma_rho: float = eqx.field(static=True)
    fractions: Fractions = eqx.field(static=True)
    penalty: float = eqx.field(static=True)
    pairs: tuple = eqx.field(static=True)
    pulleys: bool = eqx.field(static=True)
    tension_target: float = eqx.field(static=True)


def _as_module(prob: ExcitationProblem) -> _ProbModule:
    return _ProbModule(prob.robot, prob.family, prob.nominal, prob.model, prob.objective,
                       prob.limits, _HashableBox(prob.box), prob.sigma_rho, prob.fractions,
                       prob.penalty, prob.pairs, prob.pulleys, prob.tension_target)


class _HashableBox:
    """The uncertainty box as a static (hashable) field: only its interval hull is used."""

    def __init__(self, box: UncertaintyBox):
        self.x_lo = tuple(float(v) for v in box.x_lo)
        self.x_hi = tuple(float(v) for v in box.x_hi)

    def __hash__(self):
        return hash((self.x_lo, self.x_hi))

    def __eq__(self, other):
        return (isinstance(other, _HashableBox)
                and (self.x_lo, self.x_hi) == (other.x_lo, other.x_hi))


@eqx.filter_jit
def _homed_W_ID(traj, t, gravity, model: str):
    states = traj.states(t)
    return states, stacked_regressor(states, gravity, model)


def _meaningful_rel(sig, x):
    """Relative sigmas, None where the nominal value is 0 (a percentage of 0 means nothing)."""
    scale = max(abs(float(x[0])), 1e-12)
    return [float(s / abs(v)) if abs(v) > 1e-9 * scale else None
            for s, v in zip(sig, x, strict=True)]


def evaluate_design(prob: ExcitationProblem, z, rate_hz: float = 100.0,
                    certify: bool = True, dense_hz: float = 500.0) -> DesignReport:
    """Metrics of coordinates z (with the home moves) on a ``rate_hz`` grid and the exact
    certificate (kinematics also on a ``dense_hz`` grid)."""
    from cdprid.core._identification import condition_number

    z = jnp.asarray(z, float)
    traj = prob.homed(z)
    t = np.arange(int(np.floor(traj.t_end * rate_hz + 1e-9)) + 1) / rate_hz
    states, W_ID = _homed_W_ID(traj, jnp.asarray(t), prob.robot.gravity, prob.model)
    W_ID = np.asarray(W_ID)
    obj = float(_objective_value(prob, jnp.asarray(W_ID)))
    td = np.arange(int(np.floor(traj.t_end * dense_hz + 1e-9)) + 1) / dense_hz
    dense = traj.evaluate(td)
    cert = certify_trajectory(prob.robot, states, dense, prob.limits, prob.box)
    sig = np.asarray(predicted_sigma(jnp.asarray(W_ID), prob.sigma_rho))
    x = np.asarray(prob.nominal.vector(prob.model))
    params = {k: np.asarray(v) for k, v in prob.family.to_params(z).items()}
    return DesignReport(
        params=params, z=np.asarray(z),
        cond=condition_number(W_ID), cond_scaled=condition_number(W_ID, scaled=True),
        dopt=float(d_optimality(jnp.asarray(W_ID))), objective=obj,
        sigma={n: float(s) for n, s in zip(prob.names, sig, strict=True)},
        rel_sigma=dict(zip(prob.names, _meaningful_rel(sig, x), strict=True)),
        certificate=cert, t_move=traj.t_move, duration=traj.t_end,
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
    initial_rule: str = ""

    def as_json(self) -> dict:
        prob = self.problem
        return {
            "initial": self.initial.as_json(),
            "optimised": self.optimised.as_json(),
            "wall_time_s": self.wall_time_s,
            "optimiser_time_s": self.optimiser_time_s,
            "family": prob.family.name,
            "model": prob.model,
            "objective": prob.objective,
            "limits": prob.limits.as_json(),
            "defaults_used": list(prob.limits.defaults_used) + list(
                prob.box.description.get("defaults_used", [])),
            "uncertainty": {"source": prob.box.source, **prob.box.description,
                            "corners": prob.box.corners.tolist(),
                            "parameter_order": list(PARAMETER_NAMES["full"])},
            "home": [float(v) for v in prob.home],
            "safety_fractions": dataclasses.asdict(prob.fractions),
            "tension_margin_target_N": prob.tension_target,
            "starts": self.starts,
            "note": self.note,
            "initial_design": self.initial_rule,
            "certificate_scope": CERTIFICATE_SCOPE,
        }


def _solve_impl(z0, probm: _ProbModule, t, t_fine, max_steps: int):
    import optimistix as optx

    fn = lambda z, _: _penalised(z, probm, t, t_fine)  # noqa: E731
    sol = optx.minimise(fn, optx.BFGS(rtol=1e-6, atol=1e-6), z0, has_aux=True,
                        max_steps=max_steps, throw=False)
    f, pen = sol.aux  # the objective's parts at sol.value (no second copy of the objective)
    return sol.value, f + probm.penalty * pen, f, pen, sol.stats["num_steps"], sol.result


#: XLA options of the optimiser's compilation: without the CPU fusion emitters XLA compiles the
#: BFGS loop about 30 % faster (measured 26 -> 18 s for the penalised objective and its
#: gradient on a loaded 2-core machine) for the same run time per step.
COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}
_COMPILED: dict = {}


def _solve(z0, probm: _ProbModule, t, t_fine, max_steps: int, compiler_options=None):
    """The jit-compiled BFGS solve; compiled once per problem structure and shapes (and kept
    for the next starts), with :data:`COMPILER_OPTIONS`."""
    opts = COMPILER_OPTIONS if compiler_options is None else compiler_options
    dyn, static = eqx.partition(probm, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(static)
    key = (treedef, tuple(leaves), tuple(sorted(opts.items())), max_steps,
           tuple(x.shape for x in (z0, t, t_fine)))
    if key not in _COMPILED:
        fn = jax.jit(lambda z, d, t_, tf_: _solve_impl(z, eqx.combine(d, static), t_, tf_,
                                                       max_steps))
        lowered = fn.lower(z0, dyn, t, t_fine)
        _COMPILED.clear()  # keep one compiled problem (they hold the robot's constants)
        _COMPILED[key] = lowered.compile(compiler_options=dict(opts)) if opts else \
            lowered.compile()
    return _COMPILED[key](z0, dyn, t, t_fine)


def _log(msg: str, progress: Callable | bool | None):
    if progress is True:
        print(msg, file=sys.stderr, flush=True)
    elif callable(progress):
        progress(msg)


def fit_to_limits(prob: ExcitationProblem, params: dict, fraction: float,
                  rate_hz: float = 200.0, iterations: int = 8) -> tuple[dict, float]:
    """The design ``params`` with its amplitude scaled down (never up) until the peaks of the
    whole trajectory (with the home moves) are within ``fraction`` of every kinematic limit
    and of the cable speed limit.

    Parameters
    ----------
    prob : ExcitationProblem
    params : dict
        Physical parameters of the family.
    fraction : float
        In (0, 1].
    rate_hz : float
        Grid on which the peaks are measured.
    iterations : int
        Peaks are about linear in the amplitude factor; a few rescalings suffice.

    Returns
    -------
    params : dict
        The scaled design.
    k : float
        The amplitude factor applied (1.0: unchanged).
    """
    fam = prob.family
    k, out = 1.0, params
    for _ in range(iterations):
        out = fam.scale_amplitude(params, k)
        traj = prob.homed(jnp.asarray(fam.from_params(out)))
        t = np.arange(int(np.floor(traj.t_end * rate_hz + 1e-9)) + 1) / rate_hz
        worst = max(limit_ratios(prob.robot, traj.evaluate(t), prob.limits).values())
        if worst <= fraction:
            return out, k
        k *= 0.995 * fraction / worst
    return out, k


def initial_design(prob: ExcitationProblem) -> tuple[dict, str]:
    """The default initial design, the "gentle first run", and a sentence describing it.

    The paper's design (a horizontal orbit of radius 0.4 m at 0.25 Hz about the workspace
    centre, radius fitted to the workspace; for ``fourier`` with a small rotation), its
    amplitude scaled down if needed so that every peak of the whole trajectory (acceleration,
    jerk, tilt, angular velocity and acceleration, cable speed, with the home moves) is at most
    :data:`GENTLE_FRACTION` of its limit: what we recommend for a first run with a platform
    that is not yet identified (its mass is uncertain; half of each limit leaves room).
    """
    fam = prob.family
    params, k = fit_to_limits(prob, fam.initial_params(prob.robot), GENTLE_FRACTION)
    rule = (f"gentle first run: the paper's orbit (0.4 m, 0.25 Hz, horizontal, about the "
            f"workspace centre; radius fitted to the workspace) with its amplitude scaled by "
            f"{k:.3g} so that every peak is at most {100 * GENTLE_FRACTION:g} % of its limit")
    return params, rule


def gentle_run(prob: ExcitationProblem) -> ExcitationResult:
    """The certified gentle first run (:func:`initial_design`) as a result, not optimised
    (``cdprid excite --gentle``); a UserError naming the failed checks when it is not safe."""
    t0 = time.perf_counter()
    params, rule = initial_design(prob)
    rep = evaluate_design(prob, prob.family.from_params(params))
    if not rep.certified:
        raise UserError("--gentle: the gentle first run does not pass every safety check ("
                        + "; ".join(rep.certificate.failed) + "); relax the limits, move "
                        "--home, or give an --initial design.")
    return ExcitationResult(prob, rep, rep, prob.homed(jnp.asarray(rep.z)), [],
                            time.perf_counter() - t0, 0.0,
                            "gentle first run (--gentle): the initial design, not optimised.",
                            rule)


def start_points(prob: ExcitationProblem, n_starts: int = 4, seed: int = 0,
                 initial_params: dict | None = None, spread: float = 0.7) -> list:
    """Start coordinates: the initial design (:func:`initial_design` unless
    ``initial_params``), then N(0, spread^2) perturbations of it drawn from
    ``jax.random.PRNGKey(seed)``."""
    fam = prob.family
    p0 = initial_design(prob)[0] if initial_params is None else initial_params
    z_init = jnp.asarray(fam.from_params(p0))
    keys = jax.random.split(jax.random.PRNGKey(seed), max(n_starts - 1, 1))
    return [z_init] + [z_init + spread * jax.random.normal(k, z_init.shape)
                       for k in keys[: n_starts - 1]]


def _run_starts(prob, starts, max_steps, progress):
    """One compiled BFGS solve per start; [(penalised, z, objective, penalty, steps, status,
    seconds)] (the first start's seconds include the compilation)."""
    import optimistix as optx

    t = jnp.asarray(prob.grid(prob.rate_opt_hz))
    t_fine = jnp.asarray(prob.grid(prob.rate_opt_hz * prob.fine_factor))
    probm = _as_module(prob)
    sols = []
    for i, z0 in enumerate(starts):
        t1 = time.perf_counter()
        z, val, f, pen, steps, result = _solve(z0, probm, t, t_fine, max_steps)
        z = jax.block_until_ready(z)
        status = "converged" if result == optx.RESULTS.successful else "stopped early"
        dt = time.perf_counter() - t1
        sols.append((float(val), np.asarray(z), float(f), float(pen), int(steps), status, dt))
        _log(f"excite: start {i + 1}/{len(starts)}: penalised objective {float(val):.4f} "
             f"(objective {float(f):.4f}, penalty {float(pen):.2e}) in {int(steps)} steps, "
             f"{status}, {dt:.1f} s" + (" (with the compilation)" if i == 0 else ""), progress)
    return sols


def _pick(prob, sols, initial, progress):
    """The certified design with the best penalised objective (exact certificate); note."""
    order = np.argsort([s[0] for s in sols])
    reports = []
    for i in order:
        rep = evaluate_design(prob, sols[i][1])
        reports.append((int(i), rep))
        _log(f"excite: start {i + 1}: cond {rep.cond:.3f}, cond_scaled {rep.cond_scaled:.3f}, "
             f"robust tension margin {rep.min_tension_margin_N:.2f} N, certified {rep.certified}"
             + ("" if rep.certified else f" ({'; '.join(rep.certificate.failed)})"), progress)
        if rep.certified:
            break
    cert = [(i, r) for i, r in reports if r.certified]
    note = ""
    if cert:
        i, best = cert[0]
        if i != int(order[0]):
            note = f"best start was not certified; returned start {i + 1}, the best certified one."
    elif initial.certified:
        best = initial
        note = "no optimised start was certified; returned the (certified) initial design."
    else:
        raise UserError("neither the optimised starts nor the initial design pass every safety "
                        f"check (initial: {'; '.join(initial.certificate.failed)}); relax the "
                        "limits, move --home, or give a feasible --initial design.")
    if best.objective > initial.objective and initial.certified:
        best, note = initial, "the optimiser did not improve on the initial design; returned it."
    return best, reports, note


def optimise_excitation(prob: ExcitationProblem, n_starts: int = 4, seed: int = 0,
                        initial_params: dict | None = None, max_steps: int = 1000,
                        spread: float = 0.7,
                        progress: Callable | bool | None = True) -> ExcitationResult:
    """Minimise the penalised objective with optimistix BFGS from several starts.

    Start 0 is the initial design (:func:`initial_design`, the gentle first run, unless
    ``initial_params``); the others
    perturb its coordinates with N(0, spread^2) draws from ``jax.random.PRNGKey(seed)``.
    One compiled solve is reused for every start. The answer is the certified design with the
    best objective; uncertified designs are never returned (every limit, clearance and the
    tensions at every corner of the uncertainty box are checked exactly, with the home moves).
    A start that stops before convergence is reported as such in ``starts`` and the log.
    """
    t_wall = time.perf_counter()
    fam = prob.family
    if initial_params is None:
        initial_params, rule = initial_design(prob)
    else:
        rule = "given by the caller (--initial)"
    starts = start_points(prob, n_starts, seed, initial_params, spread)
    _log(f"excite: {fam.name} family, {fam.n_params} parameters, {prob.model} model, objective "
         f"{prob.objective}, {len(starts)} starts", progress)
    t_opt = time.perf_counter()
    sols = _run_starts(prob, starts, max_steps, progress)
    optimiser_time = time.perf_counter() - t_opt
    initial = evaluate_design(prob, starts[0])
    _log(f"excite: initial design: cond {initial.cond:.3f}, certified {initial.certified}"
         + ("" if initial.certified else f" ({'; '.join(initial.certificate.failed)})"), progress)
    best, reports, note = _pick(prob, sols, initial, progress)
    start_info = [{"start": i + 1, "penalised": s[0], "objective": s[2], "penalty": s[3],
                   "steps": s[4], "status": s[5], "time_s": s[6]} for i, s in enumerate(sols)]
    for i, rep in reports:
        start_info[i]["certified"] = rep.certified
        start_info[i]["cond"] = rep.cond
    if note:
        _log(f"excite: {note}", progress)
    traj = prob.homed(best.z)
    return ExcitationResult(prob, initial, best, traj, start_info,
                            time.perf_counter() - t_wall, optimiser_time, note, rule)


# =============================================================================== baseline


def slsqp_baseline(prob: ExcitationProblem, z0=None, maxiter: int = 200,
                   softness: float = 0.02) -> dict:
    """scipy SLSQP with finite-difference gradients on the same objective and constraints.

    The objective is the same jit-compiled smooth objective (no penalty); the constraints are
    soft minima (temperature ``softness``, normalised units) of the same per-sample margins:
    workspace, cable speed, tension, kinematics and clearance. Returns
    ``{"z", "objective", "time_s", "nfev", "success"}``.
    """
    from scipy.optimize import minimize

    fam = prob.family
    if z0 is None:
        z0 = fam.from_params(initial_design(prob)[0])
    t = jnp.asarray(prob.grid(prob.rate_opt_hz))
    probm = _as_module(prob)

    @jax.jit
    def both(z):
        states = probm.family.states(z, t)
        W_ID = stacked_regressor(states, probm.robot.gravity, probm.model)
        cons = jnp.array([_softmin(c.ravel(), softness)
                          for c in _constraint_margins(probm, states)])
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
