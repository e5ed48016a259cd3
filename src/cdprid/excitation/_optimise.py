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

from cdprid.base import Status, UserError
from cdprid.excitation._check import limit_ratios, rest_margins
from cdprid.excitation._evaluation import ExcitationResult, evaluate_design
from cdprid.excitation._problem import GENTLE_FRACTION, ExcitationProblem, Fractions, _penalised
from cdprid.excitation._safety import (
    SafetyLimits,
    UncertaintyBox,
)
from cdprid.model import CableRobot, InertialParameters


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
    source: str = eqx.field(static=True)
    drive_k: tuple = eqx.field(static=True)
    reference: int = eqx.field(static=True)


def _as_module(prob: ExcitationProblem) -> _ProbModule:
    return _ProbModule(prob.robot, prob.family, prob.nominal, prob.model, prob.objective,
                       prob.limits, _HashableBox(prob.box), prob.sigma_rho, prob.fractions,
                       prob.penalty, prob.pairs, prob.pulleys, prob.tension_target,
                       prob.source, prob.drive_k, prob.reference)


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

    Parameters
    ----------
    prob : ExcitationProblem

    Returns
    -------
    params : dict
        The family's physical parameters.
    rule : str
        One sentence describing the design.
    """
    fam = prob.family
    params, k = fit_to_limits(prob, fam.initial_params(prob.robot), GENTLE_FRACTION)
    rule = (f"gentle first run: the paper's orbit (0.4 m, 0.25 Hz, horizontal, about the "
            f"workspace centre; radius fitted to the workspace) with its amplitude scaled by "
            f"{k:.3g} so that every peak is at most {100 * GENTLE_FRACTION:g} % of its limit")
    return params, rule


def gentle_run(prob: ExcitationProblem, move_home: bool = False,
               progress: Callable | bool | None = None) -> ExcitationResult:
    """The certified gentle first run (:func:`initial_design`) as a result, not optimised.

    ``cdprid excite --gentle``. With ``move_home`` (the user gave no ``--home``), a gentle run
    that fails at the workspace centre is tried again about the rest points of the workspace
    with the largest robust static tension margin (:func:`robust_homes`): home and orbit centre
    there, the amplitude fitted to the box and the limits; the first certified one is returned,
    with a note saying where home moved and why.

    Parameters
    ----------
    prob : ExcitationProblem
    move_home : bool
        Try other homes when the run fails about the given one.
    progress : callable, bool or None
        True prints progress lines on stderr, a callable receives them, None/False is silent.

    Returns
    -------
    ExcitationResult
        ``initial`` and ``optimised`` are the same certified design.

    Raises
    ------
    UserError
        No gentle run tried passes every safety check (the sentence names the failed checks).
    """
    t0 = time.perf_counter()
    params, rule = initial_design(prob)
    rep = evaluate_design(prob, prob.family.from_params(params))
    note = "gentle first run (--gentle): the initial design, not optimised."
    if not rep.certified and move_home:
        failed = "; ".join(rep.certificate.failed)
        for home in robust_homes(prob):
            _log(f"excite --gentle: not certified about {np.round(prob.home, 3).tolist()} "
                 f"({failed}); trying home {np.round(home, 3).tolist()}", progress)
            p2 = dataclasses.replace(prob, home=np.asarray(home, float))
            par2, rule2 = _gentle_about(p2, home)
            rep2 = evaluate_design(p2, p2.family.from_params(par2))
            if rep2.certified:
                prob, rep, rule = p2, rep2, rule2
                note += (f" Home moved to {np.round(home, 3).tolist()} m (no --home given): "
                         f"about the workspace centre the gentle run failed ({failed}).")
                break
    if not rep.certified:
        raise UserError("--gentle: the gentle first run does not pass every safety check ("
                        + "; ".join(rep.certificate.failed) + ")"
                        + (" about the workspace centre or any robust rest point tried"
                           if move_home else "") + "; relax the limits, move "
                        "--home, or give an --initial design.")
    return ExcitationResult(prob, rep, rep, prob.homed(jnp.asarray(rep.z)), [],
                            time.perf_counter() - t0, 0.0, note, rule)


def robust_homes(prob: ExcitationProblem, n_grid: int = 5, n_best: int = 6) -> list:
    """Rest points with a positive robust static tension margin, largest margin first.

    Parameters
    ----------
    prob : ExcitationProblem
    n_grid : int
        Grid points per axis over the workspace box inset by 10 %.
    n_best : int
        At most this many points.

    Returns
    -------
    list of ndarray (3,)
        Positions, base frame, m.
    """
    lo, hi = np.asarray(prob.limits.workspace_min), np.asarray(prob.limits.workspace_max)
    inset = 0.1 * (hi - lo)
    axes = [np.linspace(a + d, b - d, n_grid) for a, b, d in zip(lo, hi, inset, strict=True)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    marg = rest_margins(prob.robot, pts, prob.limits, prob.box)
    order = [i for i in np.argsort(-marg) if marg[i] > 0][:n_best]
    return [pts[i] for i in order]


def _gentle_about(prob: ExcitationProblem, centre) -> tuple[dict, str]:
    """The gentle design centred at ``centre`` (its amplitude fitted to the workspace box
    about that point, then to the limits)."""
    fam = prob.family
    params = dict(fam.initial_params(prob.robot), centre=np.asarray(centre, float))
    lo, hi = np.asarray(prob.limits.workspace_min), np.asarray(prob.limits.workspace_max)
    c = np.asarray(centre, float)
    room = float(min(np.min(c - lo), np.min(hi - c)))  # 1 at the box centre, less off it
    params = fam.scale_amplitude(params, min(1.0, room / max(float(np.min(0.5 * (hi - lo))),
                                                             1e-9)))
    params, k = fit_to_limits(prob, params, GENTLE_FRACTION)
    return params, (f"gentle first run about {np.round(centre, 3).tolist()} m: the paper's "
                    f"orbit with its amplitude scaled by {k:.3g} so that every peak is at most "
                    f"{100 * GENTLE_FRACTION:g} % of its limit")


def start_points(prob: ExcitationProblem, n_starts: int = 4, seed: int = 0,
                 initial_params: dict | None = None, spread: float = 0.7) -> list:
    """Start coordinates of the optimiser.

    The initial design (:func:`initial_design` unless ``initial_params``), then
    N(0, spread^2) perturbations of it drawn from ``jax.random.PRNGKey(seed)``.

    Parameters
    ----------
    prob : ExcitationProblem
    n_starts : int
    seed : int
    initial_params : dict, optional
        The family's physical parameters of the first start.
    spread : float
        Standard deviation of the perturbations, in coordinate units.

    Returns
    -------
    list of array (n_params,)
    """
    fam = prob.family
    p0 = initial_design(prob)[0] if initial_params is None else initial_params
    z_init = jnp.asarray(fam.from_params(p0))
    keys = jax.random.split(jax.random.PRNGKey(seed), max(n_starts - 1, 1))
    return [z_init] + [z_init + spread * jax.random.normal(k, z_init.shape)
                       for k in keys[: n_starts - 1]]


def _run_starts(prob, starts, max_steps, progress):
    """One compiled BFGS solve per start; [(penalised, z, objective, penalty, steps, status,
    seconds)] (the first start's seconds include the compilation)."""

    t = jnp.asarray(prob.grid(prob.rate_opt_hz))
    t_fine = jnp.asarray(prob.grid(prob.rate_opt_hz * prob.fine_factor))
    probm = _as_module(prob)
    sols = []
    for i, z0 in enumerate(starts):
        t1 = time.perf_counter()
        z, val, f, pen, steps, result = _solve(z0, probm, t, t_fine, max_steps)
        z = jax.block_until_ready(z)
        status = "converged" if Status.of_optimistix(result).ok else "stopped early"
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
    ``initial_params``); the others perturb its coordinates with N(0, spread^2) draws from
    ``jax.random.PRNGKey(seed)``. One compiled solve is reused for every start. The answer is
    the certified design with the best objective; uncertified designs are never returned
    (every limit, clearance and the tensions at every corner of the uncertainty box are
    checked exactly, with the home moves). A start that stops before convergence is reported
    as such in ``starts`` and the log.

    Parameters
    ----------
    prob : ExcitationProblem
    n_starts : int
    seed : int
    initial_params : dict, optional
        The family's physical parameters of start 0.
    max_steps : int
        BFGS steps per start.
    spread : float
        Standard deviation of the start perturbations, in coordinate units.
    progress : callable, bool or None
        True prints progress lines on stderr, a callable receives them, None/False is silent.

    Returns
    -------
    ExcitationResult

    Raises
    ------
    UserError
        Neither an optimised start nor the initial design is certified.
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
