"""The excitation problem: fractions of the limits, its definition and construction,
the objective value and the penalised objective."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError, UserError
from cdprid.core import regressors, wrench_matrices
from cdprid.excitation._constraints import _constraint_margins, robust_tension_margin_smooth
from cdprid.excitation._currents import currents_regressor
from cdprid.excitation._families import (
    FAMILIES,
    HomedTrajectory,
    make_family,
    move_duration,
)
from cdprid.excitation._objective import (
    OBJECTIVES,
    _scale_columns,
    d_optimality,
    predicted_sigma,
    soft_log_cond,
    stacked_regressor,
)
from cdprid.excitation._safety import (
    SafetyLimits,
    UncertaintyBox,
    safety_limits,
    uncertainty_from_prior,
    uncertainty_from_robot,
)
from cdprid.model import PARAMETER_NAMES, CableRobot, InertialParameters, cable_pairs

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
    #: what the identification will measure: ``tensions`` (load cells) or ``currents`` (the
    #: joint platform and drive regressor, :mod:`cdprid.excitation._currents`)
    source: str = "tensions"
    #: ``currents``: the drives' nominal current-to-force constants (N/A)
    drive_k: tuple = ()
    #: ``currents``: the drive whose constant is the scale reference (0-based)
    reference: int = 0

    @property
    def nominal(self) -> InertialParameters:
        """The nominal platform of the uncertainty box."""
        return self.box.nominal

    @property
    def tmin(self) -> float:
        """Lowest tension, N."""
        return self.limits.tension_min

    @property
    def tmax(self) -> float:
        """Highest tension, N."""
        return self.limits.tension_max

    @property
    def speed_max(self) -> float:
        """Highest cable speed, m/s."""
        return self.limits.cable_speed_max

    @property
    def names(self) -> tuple:
        """Parameter names of the model."""
        return PARAMETER_NAMES[self.model]

    @property
    def pulleys(self) -> bool:
        """Whether any cable has a swivel pulley."""
        return self.robot.has_pulleys

    @property
    def pairs(self) -> tuple:
        """Cable pairs whose clearance is checked (:func:`cdprid.model.cable_pairs`)."""
        return tuple(tuple(int(v) for v in p) for p in cable_pairs(self.robot))

    def grid(self, rate_hz: float) -> np.ndarray:
        """Uniform time grid over the family's exciting part.

        Parameters
        ----------
        rate_hz : float
            Sampling rate, Hz.

        Returns
        -------
        ndarray (n,)
            Times from 0 to the family's duration, s.
        """
        d = self.family.duration
        n = int(np.floor(d * rate_hz + 1e-9)) + 1
        return np.arange(n) / rate_hz

    def homed(self, z) -> HomedTrajectory:
        """The trajectory of coordinates z with the moves from and back to home.

        Parameters
        ----------
        z : array (n_params,)
            The family's unconstrained coordinates.

        Returns
        -------
        HomedTrajectory
            Move durations from :func:`move_duration` at the problem's limits.
        """
        fam = self.family
        start = np.asarray(fam.to_params(jnp.asarray(z))["centre"])
        lim = self.limits
        T = move_duration(np.linalg.norm(start - self.home), lim.cable_speed_max,
                          lim.acceleration_max, lim.jerk_max)
        return HomedTrajectory(fam, jnp.asarray(z, float), jnp.asarray(self.home, float), T)


def parse_home(text: str | None, limits: SafetyLimits) -> np.ndarray:
    """``--home x,y,z`` (m, base frame; default the workspace centre), inside the workspace.

    Parameters
    ----------
    text : str or None
        ``"x,y,z"`` in m, or None for the workspace centre.
    limits : SafetyLimits

    Returns
    -------
    ndarray (3,)
        Home position, base frame, m.

    Raises
    ------
    UserError
        Not three finite numbers, or outside the workspace box.
    """
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
                 prior: str | None = None, home: str | None = None, source: str = "tensions",
                 drives=None, **kw) -> ExcitationProblem:
    """An :class:`ExcitationProblem` for a robot.

    Limits from robot.toml with stated defaults (:func:`cdprid.excitation.safety_limits`);
    the uncertainty box from ``prior`` (``cdprid identify --json``) or robot.toml ``[platform]``.

    Parameters
    ----------
    robot : CableRobot
    family : {"orbit", "orbits", "fourier"}
    objective : {"cond", "cond_scaled", "dopt", "sigma"}
    model : {"translation", "full"}, optional
        Default ``translation`` for the orbit families and ``full`` for ``fourier``.
    duration : float, optional
        Duration of the exciting part, s (:func:`make_family`'s default).
    prior : path-like, optional
        A ``cdprid identify --json`` output giving the uncertainty box.
    home : str, optional
        ``"x,y,z"`` in m (default: the workspace centre).
    source : {"tensions", "currents"}
        What the identification will measure; ``currents`` designs for the joint regressor of
        the platform and every drive (its column-scaled conditioning: ``cond`` and
        ``cond_scaled`` are the same objective there; ``dopt`` and ``sigma`` are refused).
    drives : cdprid.io.DriveData, optional
        The drives' nominal data (robot.toml's ``[[cable]]`` drive fields), needed by
        ``currents``; the reference is the drive marked ``drive_reference``, else drive 1.
    **kw
        Fields of :class:`ExcitationProblem` (``tension_target``, ``rate_opt_hz``, ...).

    Returns
    -------
    ExcitationProblem

    Raises
    ------
    InputError
        Unknown objective, family or model, or the full model with a non-rotating family.
    UserError
        Neither ``prior`` nor robot.toml gives the platform; bad limits or ``home``.
    """
    if objective not in OBJECTIVES:
        raise InputError(f"unknown objective {objective!r}; use one of {', '.join(OBJECTIVES)}.")
    if source not in ("tensions", "currents"):
        raise InputError(f"--source: unknown source {source!r}; use tensions or currents.")
    if source == "currents":
        if objective not in ("cond", "cond_scaled"):
            raise InputError(f"--objective {objective}: with --source currents the objective is "
                             "the joint regressor's column-scaled conditioning (cond).")
        if drives is None or drives.n != robot.n_cables:
            raise InputError("--source currents needs the drive fields drum_radius, gear_ratio "
                             "and torque_constant on every [[cable]] of robot.toml.")
        ref = int(np.flatnonzero(drives.reference)[0]) if drives.reference.any() else 0
        kw.update(source="currents", reference=ref,
                  drive_k=tuple(float(v) for v in drives.k_nominal))
    if family not in FAMILIES:
        raise InputError(f"unknown excitation family {family!r}; use one of {', '.join(FAMILIES)}.")
    model = model or ("full" if family == "fourier" else "translation")
    if model not in PARAMETER_NAMES:
        raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")
    rotates = family == "fourier"
    if model == "full" and not rotates:
        raise InputError(f"the 10-parameter model needs rotations; the {family!r} family does not "
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


def design_matrix(prob, states):
    """The regressor the objective conditions: the platform's stacked W_ID (eq. 11) for
    tensions, the joint platform and drive regressor for currents
    (:func:`cdprid.excitation._currents.currents_regressor`).

    Parameters
    ----------
    prob : ExcitationProblem
    states : TrajectoryState

    Returns
    -------
    array (6 n, columns)
    """
    if prob.source == "currents":
        return currents_regressor(prob.robot, states, prob.model,
                                  prob.nominal.vector(prob.model), jnp.asarray(prob.drive_k),
                                  prob.reference, prob.limits.tension_min,
                                  prob.limits.tension_max)
    return stacked_regressor(states, prob.robot.gravity, prob.model)


def _objective_value(prob, W_ID):
    M = W_ID.T @ W_ID
    if prob.source == "currents":  # columns in N/A, kg, N s/m and N: scaled
        return soft_log_cond(_scale_columns(M))
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


def _penalised(z, prob, t, t_fine=None):
    fine = None if t_fine is None else prob.family.states(z, t_fine)
    k = 0 if fine is None or t.shape[0] < 2 else (t_fine.shape[0] - 1) // (t.shape[0] - 1)
    if k >= 1 and -(-t_fine.shape[0] // k) == t.shape[0]:
        # the optimisation grid is every k-th point of the fine grid: one evaluation serves both
        states = jax.tree_util.tree_map(lambda x: x[::k], fine)
    else:
        states = prob.family.states(z, t)
    W_ID = design_matrix(prob, states)
    f = _objective_value(prob, W_ID)
    pen = sum(jnp.sum(jax.nn.relu(-c) ** 2) for c in _constraint_margins(prob, states, fine))
    return f + prob.penalty * pen, (f, pen)
