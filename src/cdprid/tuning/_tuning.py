"""Tuning of differentiator parameters for a given position-noise level.

The SIHD family (``sihd2-cascade``, ``sihd3`` and the higher-order ``sihd4``,
``sihd5`` of :mod:`cdprid.signal._sihd_high`) is tuned by gradient-based optimisation
(optimistix BFGS) *through* the ``lax.scan`` of the differentiator, against
``N`` noise realisations of a training signal evaluated in one vmapped call.
Parametrisation (unconstrained vector ``theta``):

* ``sihd2-cascade``: ``log lambda1..lambda4`` (every positive pair gives a
  Hurwitz stage polynomial ``s^2 + lambda1 s + lambda2``);
* ``sihdN`` (N >= 3): the linear part's error polynomial
  ``s^N + lambda1 s^(N-1) + ... + lambdaN`` is built from its roots, one real
  root ``-omega0`` (N odd) and pairs ``s^2 + 2 zeta omega s + omega^2``, with
  ``log omega`` and ``log zeta`` free: always Hurwitz;
* ``alpha = a_min + (1 - a_min) sigmoid(s)`` with ``a_min = 0.5`` for the cascade
  and ``(N-1)/N`` for SIHD-N; ``mu`` is fixed at 1 because it only enters as
  ``lambda_q mu^q`` (also in the projector threshold ``lambda_q (mu h)^q``): it is
  redundant with the gains.

Objectives: ``"accel"`` the mean over the training signals of the log mean-square causal
3-D acceleration error over ``t >= t0`` (default 2 s), ``"params"`` relative error of the
4-parameter least squares (m, m s_G) on simulated tensions, or ``"mix"``.  The baselines
(``euler-filtfilt``, ``euler-butter-causal``, ``savgol``, ``kalman``, ``rts``, ``levant``)
are tuned on the same signals by a log-grid search refined by golden section
(:func:`tune_baseline`).

Training signals: by default the family of ramped orbits :data:`TRAIN_FAMILY` (0.1-0.8 Hz,
radii 0.05-0.3 m, horizontal/vertical/tilted planes, a long-ramp member; built with
:mod:`cdprid.model._trajectories`), or one signal (:func:`circle_signal`, :func:`dataset_signal`).
:data:`HELDOUT_FAMILY` (plus a two-orbit sequence and a Lissajous) is never used for tuning.

Acceleration-response bounds (:class:`ResponseBounds`): up to a stated bandwidth B (default
:func:`content_bandwidth`, 99 % of the training accelerations' energy) ``|gain - 1| <=
gain_tol`` (0.05) and ``|phase| <= phase_max_deg`` (30), ``gain <= 1.1``; above B ``gain <=
gain_max_above`` (1.05: no resonance).  They are enforced inside the optimisation by a smooth
squared-hinge penalty (:func:`response_penalty`) on a frequency grid: for the SIHD family the
gains are tuned with alpha = 1, a linear observer whose response is computed exactly
(:func:`sihd_linear_response`) and whose noise variance is exact (Parseval), so that the
response does not depend on the amplitude; for the baselines the response is simulated
(:func:`simulated_penalty`; Levant's is its describing response).  Every tuned result is then
verified on a dense grid of sinusoids (:func:`acceleration_response`, :func:`dense_freqs`);
``within_bounds`` is that verification, never the penalty.

A causal estimate without lag at low frequency (sihd4, sihd5, the Kalman filters: estimators
exact on cubics or quartics) has zero group delay, and by Bode's gain-phase relation a
minimum-phase filter with zero group delay and a roll-off must have a gain above 1 somewhere:
under the default no-resonance bound these structures can comply only with a very wide
bandwidth (much noise); sihd3, sihd2-cascade and euler-butter-causal comply with some lag.

The noise level can be estimated from a dataset (:func:`noise_from_dataset`,
which uses :func:`cdprid.core.estimate_noise`), and the training signal
can be the dataset's own smoothed trajectory (:func:`dataset_signal`).

The losses are in :mod:`cdprid.tuning._losses`, the searches (starts, BFGS with continuation,
golden section) in :mod:`cdprid.tuning._search`; this module re-exports their names.
"""

from __future__ import annotations

import dataclasses
import math
import time

import jax
import numpy as np

from cdprid.base import InputError, Status
from cdprid.tuning._losses import ParamProblem as ParamProblem
from cdprid.tuning._losses import _accel_loss as _accel_loss
from cdprid.tuning._losses import _groups as _groups
from cdprid.tuning._losses import _param_loss as _param_loss
from cdprid.tuning._losses import _stack_train as _stack_train
from cdprid.tuning._losses import penalty_freqs as penalty_freqs
from cdprid.tuning._response import (
    PENALTY_WEIGHT,
    FrequencyResponse,
    ResponseBounds,
    acceleration_response,
)
from cdprid.tuning._search import CONTINUATION as CONTINUATION
from cdprid.tuning._search import _golden as _golden
from cdprid.tuning._search import _init_candidates as _init_candidates
from cdprid.tuning._search import _minimise as _minimise
from cdprid.tuning._search import simulated_penalty as simulated_penalty
from cdprid.tuning._sihd_params import (
    PAPER_PARAMS,
    SIHD_METHODS,
    default_params,
    params_from_theta,
)
from cdprid.tuning._training import (
    TrainingSignal,
    content_bandwidth,
    evaluate,
    trajectory_family,
)

#: Searched parameter, log-grid bounds and fixed extras of each tuned baseline.
BASELINE_GRIDS = {
    "euler-filtfilt": ("cutoff_hz", 0.3, 20.0, {}),
    "euler-butter-causal": ("cutoff_hz", 0.3, 20.0, {}),
    "savgol": ("window_s", 0.1, 8.0, {}),
    "kalman": ("q", 1e-4, 1e4, {}),
    "rts": ("q", 1e-5, 1e3, {}),
    "levant": ("L", 0.05, 200.0, {}),
}


@dataclasses.dataclass(frozen=True)
class TuneResult:
    """Outcome of :func:`tune`/:func:`tune_baseline` (immutable); ``as_json()`` is the CLI's
    JSON. ``status`` is the solver's :class:`cdprid.base.Status`."""

    method: str
    params: dict
    noise_std: float
    train_rmse: float
    test_rmse: float
    paper_rmse: float
    default_rmse: float
    objective: str
    train_seeds: list
    test_seeds: list
    signal: str
    wall_s: float
    cpu_s: float
    steps: int = 0
    history: list = dataclasses.field(default_factory=list)
    extra: dict = dataclasses.field(default_factory=dict)
    response: FrequencyResponse | None = None
    warnings: list = dataclasses.field(default_factory=list)
    status: Status = Status.CONVERGED

    def as_json(self) -> dict:
        """JSON of ``cdprid tune``.

        Returns
        -------
        dict
            Method, parameters, noise std (m), RMSEs (m/s^2), seeds, timings (s), status, the
            frequency response and its check, and ``warnings``.
        """
        d = {
            "method": self.method,
            "params": self.params,
            "noise_std": self.noise_std,
            "train_rmse": self.train_rmse,
            "test_rmse": self.test_rmse,
            "paper_rmse": self.paper_rmse,
            "default_rmse": self.default_rmse,
            "objective": self.objective,
            "train_seeds": self.train_seeds,
            "test_seeds": self.test_seeds,
            "signal": self.signal,
            "wall_s": round(self.wall_s, 3),
            "cpu_s": round(self.cpu_s, 3),
            "steps": self.steps,
            "status": self.status.value,
        }
        d.update(self.extra)
        if self.response is not None:
            d["frequency_response"] = self.response.as_json()
            if self.response.bounds is not None:
                d["bandwidth_hz"] = self.response.bounds.bandwidth_hz
                d["response_bounds"] = self.response.bounds.as_json()
                d.update(self.response.check_json())
        d["warnings"] = list(self.warnings)
        return d


def _as_signals(signal, signals, dt: float = 0.01) -> list:
    """The training signals: ``signals`` (checked), else ``[signal]``, else the training
    family of :func:`trajectory_family`."""
    if signals is not None:
        sigs = list(signals)
        if not sigs:
            raise InputError("give at least one training signal.")
        if len({float(s.dt) for s in sigs}) != 1:
            raise InputError("all training signals must share one sampling period.")
        return sigs
    return [signal] if signal is not None else trajectory_family("train", dt)


def resolve_bounds(bounds, signals) -> ResponseBounds:
    """The response bounds of a ``bounds`` argument.

    Parameters
    ----------
    bounds : "auto", None, float or ResponseBounds
        ``"auto"``/None: at :func:`content_bandwidth` of ``signals``; a number: that bandwidth
        (Hz) with the default tolerances; a ResponseBounds: itself.
    signals : sequence of TrainingSignal

    Returns
    -------
    ResponseBounds
    """
    if isinstance(bounds, ResponseBounds):
        return bounds
    if bounds is None or bounds == "auto":
        return ResponseBounds(content_bandwidth(signals))
    return ResponseBounds(float(bounds))


def _check_tune_args(method: str, objective: str, noise_std: float) -> None:
    """Raise :class:`InputError` for a method, objective or noise level :func:`tune` rejects."""
    if method not in SIHD_METHODS:
        raise InputError(f"gradient tuning supports {', '.join(SIHD_METHODS)}; got {method!r}.")
    if objective not in ("accel", "params", "mix"):
        raise InputError(f"unknown objective {objective!r}; use accel, params or mix.")
    if not (math.isfinite(noise_std) and noise_std > 0):
        raise InputError(f"noise std must be a positive number of metres, got {noise_std!r}.")


def _optimise_theta(method, objective, sigs, noise_std, train_seeds, weight, zeta_min, bounds,
                    constrain, h, init, fa, max_steps, say):
    """Build the ``objective``'s loss (in 64-bit), jit it and minimise it (:func:`_minimise`):
    ``(theta, BFGS steps, solver status sentence, Status)``."""
    with jax.enable_x64(True):
        if objective == "accel":
            loss = _accel_loss(method, sigs, noise_std, train_seeds, zeta_min, bounds,
                               constrain, h)
        else:
            loss = _param_loss(method, sigs[0], noise_std, train_seeds, objective, weight,
                               zeta_min, bounds, constrain)
        loss_j = jax.jit(loss)
        return _minimise(loss_j, method, init, noise_std, zeta_min, fa, max_steps, constrain,
                         say)


def tune(
    method: str = "sihd2-cascade",
    noise_std: float = 5e-4,
    signal: TrainingSignal | None = None,
    train_seeds=range(4),
    test_seeds=range(100, 108),
    objective: str = "accel",
    weight: float = 0.5,
    max_steps: int = 60,
    init: dict | None = None,
    zeta_min: float | None = None,
    progress=None,
    signals=None,
    bounds="auto",
    constrain: bool = True,
    heldout=None,
) -> TuneResult:
    """Tune an SIHD method by BFGS through the scan, under acceleration-response bounds.

    Parameters
    ----------
    method : {"sihd2-cascade", "sihd3", "sihd4", "sihd5"}
    noise_std : float
        Position-noise std (m) of the training realisations.
    signal : TrainingSignal, optional
        One training signal (kept for compatibility; see ``signals``).
    train_seeds, test_seeds : iterables of int
        Noise seeds used for tuning (simulated noise) and for the held-out evaluation.
    objective : {"accel", "params", "mix"}
        ``accel``: mean over the training signals of the log mean-square acceleration error;
        ``params``: scaled LS parameter error (:class:`ParamProblem`, first signal);
        ``mix``: ``(1-weight) accel_mse / a_rms^2 + weight params`` (first signal).
    weight : float
        The ``params`` share of ``mix``.
    max_steps : int
        BFGS iterations (unconstrained); constrained, 6 solves of ``max_steps // 2``: the
        full penalty from the start (2) and continuation stages (:data:`CONTINUATION`, 4).
    init : dict, optional
        Start here instead of the best of a few standard starts.
    zeta_min : float, optional
        Damping floor of the root pairs (SIHD-N, N >= 3; default :data:`ZETA_MIN`).
    progress : callable(str), optional
        Receives progress lines.
    signals : sequence of TrainingSignal, optional
        Training signals (default: ``[signal]``, or :func:`trajectory_family` ``"train"``).
    bounds : "auto", float or ResponseBounds
        Acceleration-response bounds (``"auto"``: :func:`content_bandwidth` of the signals).
    constrain : bool
        Enforce ``bounds`` in the optimisation (alpha fixed at 1: a linear observer whose
        response is amplitude-independent; :func:`response_penalty` on
        :func:`sihd_linear_response`).  False: alpha free, no penalty (the response is still
        verified and reported).
    heldout : sequence of TrainingSignal, optional
        Signals never used for tuning, evaluated on ``test_seeds``.

    Returns
    -------
    TuneResult
        With ``response`` verified on :func:`dense_freqs` against the bounds and ``warnings``.
    """
    _check_tune_args(method, objective, noise_std)
    say = progress or (lambda s: None)
    sigs = _as_signals(signal, signals)
    bounds = resolve_bounds(bounds, sigs)
    train_seeds, test_seeds = list(train_seeds), list(test_seeds)
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    fa = 1.0 if constrain else None
    h = float(sigs[0].dt)

    th, steps, status, code = _optimise_theta(method, objective, sigs, noise_std, train_seeds,
                                              weight, zeta_min, bounds, constrain, h, init, fa,
                                              max_steps, say)
    params = params_from_theta(method, th, zeta_min, fa)
    res = _finish(method, params, noise_std, sigs, train_seeds, test_seeds, objective,
                  (t_wall, t_cpu), steps, bounds, heldout, say)
    return dataclasses.replace(res, status=code,
                               extra={**res.extra, "solver_status": status,
                                      "constrained": bool(constrain)})


def response_warnings(method: str, resp: FrequencyResponse) -> list[str]:
    """One sentence when ``resp`` is not within its stated bounds (else nothing).

    Parameters
    ----------
    method : str
    resp : FrequencyResponse

    Returns
    -------
    list of str
    """
    if resp.ok:
        return []
    why = ""
    if method in ("sihd4", "sihd5", "kalman"):
        why = (" (this structure estimates the acceleration without lag at low frequency, "
               "which forces a gain above 1 somewhere above the band; sihd3 or sihd2-cascade "
               "can meet such bounds)")
    if not resp.linear:
        why += f" (describing response at {resp.accel_amplitude:g} m/s^2)"
    return [f"the tuned {method} is not within the acceleration-response bounds: "
            + "; ".join(resp.violations) + why
            + ", so its estimate distorts motions at those frequencies whatever its RMSE on "
            "the training signals."]


def _family_name(sigs) -> str:
    """The name of the training signals in the result: one name, or the family's."""
    if len(sigs) == 1:
        return sigs[0].name
    return f"family of {len(sigs)} trajectories: " + "; ".join(s.name for s in sigs)


def _finish(method, params, noise_std, sigs, train_seeds, test_seeds, objective, t0, steps,
            bounds, heldout, say) -> TuneResult:
    """Evaluate, verify the response on the dense grid and build the TuneResult."""
    wall, cpu = time.perf_counter() - t0[0], time.process_time() - t0[1]
    per = []
    for s in sigs:
        per.append({"name": s.name,
                    "train_rmse": float(np.mean(evaluate(method, params, s, noise_std,
                                                         train_seeds))),
                    "test_rmse": float(np.mean(evaluate(method, params, s, noise_std,
                                                        test_seeds)))})
    train = float(np.mean([p["train_rmse"] for p in per]))
    test = float(np.mean([p["test_rmse"] for p in per]))
    paper = float(np.mean([np.mean(evaluate("sihd2-cascade", PAPER_PARAMS, s, noise_std,
                                            test_seeds)) for s in sigs]))
    dflt = float(np.mean([np.mean(evaluate(method, default_params(method), s, noise_std,
                                           test_seeds)) for s in sigs]))
    extra = {"signals": per}
    if heldout:
        ho = [{"name": s.name, "rmse": float(np.mean(evaluate(method, params, s, noise_std,
                                                               test_seeds)))} for s in heldout]
        extra["heldout"] = ho
        extra["heldout_rmse"] = float(np.mean([r["rmse"] for r in ho]))
    resp = acceleration_response(method, params, dt=float(sigs[0].dt), bounds=bounds)
    warns = response_warnings(method, resp)
    if resp.ok and test > paper:
        warns.append(f"within the response bounds the tuned {method} has an acceleration RMSE "
                     f"of {test:.3g} m/s^2, worse than the paper cascade's {paper:.3g}: this "
                     "structure meets the bounds only by amplifying the noise (try sihd3, or "
                     "relax --gain-max-above / --phase-max / --bandwidth).")
    say(f"tune {method}: train {train:.4g}, test {test:.4g}, paper {paper:.4g} m/s^2 "
        f"({wall:.1f} s wall, {cpu:.1f} s CPU)")
    return TuneResult(method, params, float(noise_std), train, test, paper, dflt, objective,
                      train_seeds, test_seeds, _family_name(sigs), wall, cpu, steps,
                      extra=extra, response=resp, warnings=warns)


def tune_baseline(
    method: str,
    noise_std: float = 5e-4,
    signal: TrainingSignal | None = None,
    train_seeds=range(4),
    test_seeds=range(100, 108),
    n_grid: int = 17,
    refine: int = 10,
    progress=None,
    signals=None,
    bounds="auto",
    constrain: bool = True,
    heldout=None,
) -> TuneResult:
    """Tune one baseline's hyperparameter (:data:`BASELINE_GRIDS`) on a log grid and golden section.

    Minimises the mean over the training signals of the log train acceleration RMSE, plus
    :data:`PENALTY_WEIGHT` x :func:`simulated_penalty` when ``constrain`` (the describing
    response at 0.3 m for Levant). ``kalman``/``rts`` use ``r = noise_std^2``.

    Parameters
    ----------
    method : str
        A key of :data:`BASELINE_GRIDS`.
    noise_std, signal, train_seeds, test_seeds, progress, signals, bounds, constrain, heldout
        As :func:`tune`.
    n_grid, refine : int
        Grid points and golden-section steps.

    Returns
    -------
    TuneResult

    Raises
    ------
    InputError
        A method without a grid, or bad signals.
    """
    if method not in BASELINE_GRIDS:
        raise InputError(f"grid tuning supports {', '.join(BASELINE_GRIDS)}; got {method!r}.")
    say = progress or (lambda s: None)
    sigs = _as_signals(signal, signals)
    bounds = resolve_bounds(bounds, sigs)
    dt = float(sigs[0].dt)
    train_seeds, test_seeds = list(train_seeds), list(test_seeds)
    name, lo, hi, fixed = BASELINE_GRIDS[method]
    fixed = dict(fixed)
    if method in ("kalman", "rts"):
        fixed["r"] = float(noise_std) ** 2
    if method in ("euler-filtfilt", "euler-butter-causal"):
        hi = min(hi, 0.45 / dt)
    t_wall, t_cpu = time.perf_counter(), time.process_time()

    def cost(logv):
        p = {**fixed, name: math.exp(logv)}
        try:
            v = float(np.mean([math.log(np.mean(evaluate(method, p, s, noise_std, train_seeds)))
                               for s in sigs]))
            if constrain:
                v += PENALTY_WEIGHT * simulated_penalty(method, p, dt, bounds)
            return v if math.isfinite(v) else float("inf")
        except ValueError:
            return float("inf")

    grid = np.linspace(math.log(lo), math.log(hi), n_grid)
    vals = [cost(g) for g in grid]
    k = int(np.nanargmin(vals))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, n_grid - 1)]
    lv, _ = _golden(cost, a, b, refine)
    params = {**fixed, name: float(math.exp(lv))}
    if method == "savgol":  # report the window actually used (odd number of samples)
        w = int(round(params["window_s"] / dt)) | 1
        params["window_s"] = w * dt
    res = _finish(method, params, noise_std, sigs, train_seeds, test_seeds, "accel",
                  (t_wall, t_cpu), n_grid + refine + 2, bounds, heldout, say)
    say(f"tune {method}: {name} = {params[name]:.4g}")
    return dataclasses.replace(res, extra={**res.extra, "constrained": bool(constrain)})


def tune_method(method: str, noise_std: float, **kw) -> TuneResult:
    """:func:`tune` for the SIHD family, :func:`tune_baseline` otherwise.

    Parameters
    ----------
    method : str
    noise_std : float
        Position-noise std, m.
    **kw
        Options of :func:`tune` (those :func:`tune_baseline` knows are passed to it).

    Returns
    -------
    TuneResult
    """
    if method in SIHD_METHODS:
        return tune(method, noise_std, **kw)
    keep = ("signal", "train_seeds", "test_seeds", "progress", "signals", "bounds", "constrain",
            "heldout")
    return tune_baseline(method, noise_std, **{k: v for k, v in kw.items() if k in keep})
