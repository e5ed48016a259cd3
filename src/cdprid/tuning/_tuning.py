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
"""

from __future__ import annotations

import dataclasses
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base._errors import InputError
from cdprid.tuning._response import (
    PENALTY_WEIGHT,
    FrequencyResponse,
    ResponseBounds,
    _noise_gain,
    acceleration_response,
    response_penalty,
    sihd_linear_response,
)
from cdprid.tuning._sihd_params import (
    PAPER_PARAMS,
    SIHD_METHODS,
    _acc_channel,
    _order,
    _theta_to_gains,
    default_params,
    params_from_theta,
    theta_from_params,
)
from cdprid.tuning._training import (
    TrainingSignal,
    content_bandwidth,
    evaluate,
    noise_realisations,
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


class ParamProblem:
    """4-parameter least squares (m, m s_G) on simulated tensions, differentiable in the
    estimated accelerations.

    The CRAFT-like robot follows the training signal (rotation-free); the cable
    wrench ``W(p) tau`` is computed at the true poses from the simulated
    tensions plus tension noise ``tension_std`` (one draw per seed).
    """

    def __init__(self, signal: TrainingSignal, seeds, tension_std: float = 0.5):
        from cdprid.model._dynamics import regressor_translation
        from cdprid.model._geometry import wrench_matrix
        from cdprid.model._robots import craft_like_robot, craft_like_truth
        from cdprid.model._sampled import SampledTrajectory
        from cdprid.simulation._simulate import SensorNoise, simulate

        robot = craft_like_robot()
        truth = craft_like_truth()
        vel = np.gradient(signal.position, signal.dt, axis=0)
        traj = SampledTrajectory(jnp.asarray(signal.t), jnp.asarray(signal.position),
                                 jnp.asarray(vel), jnp.asarray(signal.acceleration))
        sim = simulate(robot, traj, params=truth, noise=SensorNoise.off(),
                       rate_pose=1.0 / signal.dt, rate_tension=1.0 / signal.dt,
                       check_workspace_box=False)
        tau = np.asarray(sim.tension_true)
        n = min(tau.shape[0], signal.t.size)
        I3 = jnp.eye(3)
        W = np.asarray(jax.vmap(lambda p: wrench_matrix(robot, p, I3))(
            jnp.asarray(signal.position[:n])))
        rng_y = []
        for s in seeds:
            noise = np.random.default_rng(10_000 + int(s)).standard_normal(tau[:n].shape)
            rng_y.append(np.einsum("nij,nj->ni", W, tau[:n] + tension_std * noise))
        self.Y = np.stack(rng_y)  # (S, n, 6)
        self.n = n
        self.g = np.asarray(robot.gravity, float)
        self.theta_true = np.r_[truth.mass, truth.mass * np.asarray(truth.com, float)]
        self.scale = np.r_[truth.mass, np.full(3, np.linalg.norm(self.theta_true[1:]))]
        self._reg = jax.vmap(lambda a: regressor_translation(I3, a, jnp.asarray(self.g)))

    def rel_error(self, A_hat, mask):
        """RMS over seeds of the scaled parameter error; ``A_hat`` (n, S, 3)."""
        A_hat = A_hat[: self.n]
        m = jnp.asarray(mask[: self.n], A_hat.dtype)

        def one(a, y):
            R = self._reg(a) * m[:, None, None]
            R = R.reshape(-1, 4)
            th = jnp.linalg.lstsq(R, (y * m[:, None]).reshape(-1))[0]
            return jnp.sum(((th - self.theta_true) / self.scale) ** 2) / 4

        errs = jax.vmap(one, in_axes=(1, 0))(A_hat, jnp.asarray(self.Y))
        return errs


@dataclasses.dataclass
class TuneResult:
    """Outcome of :func:`tune`/:func:`tune_baseline`; ``as_json()`` is the CLI's JSON."""

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

    def as_json(self) -> dict:
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


def _stack_train(signal, noise_std, seeds):
    S = len(seeds)
    nz = noise_realisations(signal.t.size, seeds)
    y = signal.position[None] + noise_std * nz
    Y = np.transpose(y, (1, 0, 2)).reshape(signal.t.size, 3 * S)
    acc = np.tile(signal.acceleration, (1, S))
    return Y, acc


def _init_candidates(method, noise_std):
    """A few starting points: the method's defaults and pole-placement patterns."""
    cands = [default_params(method)]
    if method == "sihd2-cascade":
        for l2, l4 in ((500.0, 800.0), (2000.0, 2000.0)):
            cands.append({**PAPER_PARAMS, "lambda2": l2, "lambda4": l4, "alpha": 0.99})
        return cands
    n = _order(method)
    # Butterworth patterns of a few bandwidths (Kalman-like pole sets), alpha near 1
    for om in (5.0, 8.0, 12.0, 18.0, 30.0):
        roots = [om * complex(math.cos(math.pi * (2 * k + n + 1) / (2 * n)),
                              math.sin(math.pi * (2 * k + n + 1) / (2 * n))) for k in range(n)]
        lam = np.real(np.poly(roots))[1:]
        p = {f"lambda{q + 1}": float(lam[q]) for q in range(n)}
        p.update(alpha=0.995, mu=1.0)
        cands.append(p)
    return cands


def _as_signals(signal, signals, dt: float = 0.01) -> list:
    if signals is not None:
        sigs = list(signals)
        if not sigs:
            raise InputError("give at least one training signal.")
        if len({float(s.dt) for s in sigs}) != 1:
            raise InputError("all training signals must share one sampling period.")
        return sigs
    return [signal] if signal is not None else trajectory_family("train", dt)


def resolve_bounds(bounds, signals) -> ResponseBounds:
    """``"auto"``/None: :class:`ResponseBounds` at :func:`content_bandwidth` of ``signals``;
    a number: that bandwidth (Hz) with the default tolerances; a ResponseBounds: itself."""
    if isinstance(bounds, ResponseBounds):
        return bounds
    if bounds is None or bounds == "auto":
        return ResponseBounds(content_bandwidth(signals))
    return ResponseBounds(float(bounds))


def penalty_freqs(dt: float, bandwidth_hz: float) -> np.ndarray:
    """Frequency grid of the response penalty (coarser than :func:`dense_freqs`)."""
    return np.union1d(np.geomspace(0.02, 0.49 / dt, 120), np.linspace(0.02, bandwidth_hz, 25))


def _groups(sigs, noise_std, seeds, noisy: bool):
    """Training arrays grouped by length: (Y (n, 3 k S), acc (n, 3 k S), mask (n,), k)."""
    by_len: dict = {}
    for s in sigs:
        by_len.setdefault((s.t.size, float(s.t0)), []).append(s)
    out = []
    for group in by_len.values():
        Ys, As = [], []
        for s in group:
            if noisy:
                Y, A = _stack_train(s, noise_std, seeds)
            else:
                Y, A = s.position, s.acceleration
            Ys.append(Y)
            As.append(A)
        out.append((jnp.asarray(np.concatenate(Ys, 1)), jnp.asarray(np.concatenate(As, 1)),
                    jnp.asarray(group[0].mask.astype(float)), len(group)))
    return out


def _accel_loss(method, sigs, noise_std, seeds, zeta_min, bounds, constrain, dt):
    """``f(theta, None)``: mean over members of the log mean-square 3-D acceleration error,
    plus :data:`PENALTY_WEIGHT` x :func:`response_penalty` when ``constrain``.

    Constrained (alpha = 1, a linear observer), the noise term is exact: ``3 sigma^2`` times
    :func:`_noise_gain`, added to the noise-free tracking error of each member; otherwise the
    noise is simulated with ``seeds``.
    """
    groups = _groups(sigs, noise_std, seeds, noisy=not constrain)
    S = 1 if constrain else len(seeds)
    fa = 1.0 if constrain else None
    pf = penalty_freqs(dt, bounds.bandwidth_hz)

    def f(th, args):
        """``args``: multiplier of :data:`PENALTY_WEIGHT` (continuation stages)."""
        lams, alpha = _theta_to_gains(method, th, zeta_min, fa)
        nv = 3 * noise_std**2 * _noise_gain(method, lams, dt) if constrain else 0.0
        logs = []
        for Y, acc, mask, k in groups:
            A = jax.vmap(lambda c: _acc_channel(method, c, dt, lams, alpha), 1, 1)(Y)
            se = jnp.sum(((A - acc) ** 2) * mask[:, None], axis=0).reshape(k, S, 3)
            logs.append(jnp.log(jnp.sum(se, axis=(1, 2)) / (S * jnp.sum(mask)) + nv))
        L = jnp.mean(jnp.concatenate(logs))
        if constrain:
            H = sihd_linear_response(method, lams, dt, pf)
            L = L + args * PENALTY_WEIGHT * response_penalty(H, pf, bounds)
        return L

    return f


def _param_loss(method, signal, noise_std, seeds, objective, weight, zeta_min, bounds,
                constrain):
    """``f(theta, None)`` for the ``params``/``mix`` objectives (first training signal)."""
    pp = ParamProblem(signal, seeds)
    Y, acc = _stack_train(signal, noise_std, seeds)
    Y, acc = jnp.asarray(Y), jnp.asarray(acc)
    mask = signal.mask.astype(float)
    maskj = jnp.asarray(mask)
    h = float(signal.dt)
    a_ms = float(np.mean(np.sum(signal.acceleration[signal.mask] ** 2, axis=1)))
    fa = 1.0 if constrain else None
    pf = penalty_freqs(h, bounds.bandwidth_hz)

    def f(th, args):
        lams, alpha = _theta_to_gains(method, th, zeta_min, fa)
        A = jax.vmap(lambda c: _acc_channel(method, c, h, lams, alpha), 1, 1)(Y)
        pe = jnp.mean(pp.rel_error(A.reshape(A.shape[0], -1, 3), mask))
        if objective == "params":
            L = jnp.log(pe)
        else:
            se = jnp.sum(((A - acc) ** 2) * maskj[:, None]) / (jnp.sum(maskj) * len(seeds))
            L = jnp.log((1 - weight) * se / a_ms + weight * pe)
        if constrain:
            L = L + args * PENALTY_WEIGHT * response_penalty(
                sihd_linear_response(method, lams, h, pf), pf, bounds)
        return L

    return f


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
    max_steps : int
        BFGS iterations (unconstrained); constrained, 6 solves of ``max_steps // 2``: the
        full penalty from the start (2) and continuation stages (:data:`CONTINUATION`, 4).
    init : dict, optional
        Start here instead of the best of a few standard starts.
    zeta_min : float, optional
        Damping floor of the root pairs (SIHD-N, N >= 3; default :data:`ZETA_MIN`).
    progress : callable(str), optional
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

    if method not in SIHD_METHODS:
        raise InputError(f"gradient tuning supports {', '.join(SIHD_METHODS)}; got {method!r}.")
    if objective not in ("accel", "params", "mix"):
        raise InputError(f"unknown objective {objective!r}; use accel, params or mix.")
    if not (math.isfinite(noise_std) and noise_std > 0):
        raise InputError(f"noise std must be a positive number of metres, got {noise_std!r}.")
    say = progress or (lambda s: None)
    sigs = _as_signals(signal, signals)
    bounds = resolve_bounds(bounds, sigs)
    train_seeds, test_seeds = list(train_seeds), list(test_seeds)
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    fa = 1.0 if constrain else None
    h = float(sigs[0].dt)

    with jax.enable_x64(True):
        if objective == "accel":
            loss = _accel_loss(method, sigs, noise_std, train_seeds, zeta_min, bounds,
                               constrain, h)
        else:
            loss = _param_loss(method, sigs[0], noise_std, train_seeds, objective, weight,
                               zeta_min, bounds, constrain)
        loss_j = jax.jit(loss)
        th, steps, status = _minimise(loss_j, method, init, noise_std, zeta_min, fa,
                                      max_steps, constrain, say)
    params = params_from_theta(method, th, zeta_min, fa)
    res = _finish(method, params, noise_std, sigs, train_seeds, test_seeds, objective,
                  (t_wall, t_cpu), steps, bounds, heldout, say)
    res.extra["solver_status"] = status
    res.extra["constrained"] = bool(constrain)
    return res


#: Penalty-weight multipliers of the continuation stages of the constrained BFGS: the gains
#: move from the unconstrained optimum into the bounds instead of starting far outside them.
CONTINUATION = (1e-3, 1e-2, 1e-1, 1.0)


def _minimise(loss_j, method, init, noise_std, zeta_min, fa, max_steps, constrain, say):
    """Best start (unpenalised loss), then BFGS.

    Unconstrained: one solve of ``max_steps``.  Constrained: two paths of solves of
    ``max(1, max_steps // 2)`` steps each (one compilation), (a) the full penalty weight twice
    from the start, (b) the stages of :data:`CONTINUATION`; the lower full-weight loss of
    start, (a) and (b) is kept.
    """
    import optimistix as optx

    cands = [init] if init is not None else _init_candidates(method, noise_std)
    best = None
    for c in cands:
        th0 = jnp.asarray(theta_from_params(method, c, zeta_min, fa))
        v = float(loss_j(th0, 0.0))
        if best is None or (math.isfinite(v) and v < best[0]):
            best = (v, th0)
    one = jnp.asarray(1.0, jnp.float64)
    v_start = float(loss_j(best[1], one))
    say(f"tune {method}: start loss {v_start:.4f} (best of {len(cands)} starts)")
    solver = optx.BFGS(rtol=1e-5, atol=1e-6)
    per = max(1, max_steps // 2) if constrain else max_steps
    paths = [(1.0, 1.0), CONTINUATION] if constrain else [(1.0,)]
    out, steps, status = (v_start, best[1]), 0, ""
    for path in paths:
        th = best[1]
        for w in path:
            wj = jnp.asarray(w, jnp.float64)  # an array: one compilation for every stage
            sol = optx.minimise(loss_j, solver, th, args=wj, max_steps=per, throw=False)
            if math.isfinite(float(loss_j(sol.value, wj))):
                th = sol.value
            steps += int(sol.stats.get("num_steps", 0))
            status = ("converged" if sol.result == optx.RESULTS.successful
                      else "not converged: " + optx.RESULTS[sol.result].split(".")[0])
        v = float(loss_j(th, one))
        if math.isfinite(v) and v < out[0]:
            out = (v, th)
    say(f"tune {method}: end loss {out[0]:.4f} after {steps} BFGS steps ({len(paths)} path(s); "
        f"last solve {status}; the lowest of start and ends is kept)")
    return out[1], steps, status


def response_warnings(method: str, resp: FrequencyResponse) -> list[str]:
    """One sentence when ``resp`` is not within its stated bounds (else nothing)."""
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


def _golden(f, lo, hi, iters):
    g = (math.sqrt(5) - 1) / 2
    a, b = lo, hi
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (c, fc) if fc < fd else (d, fd)


def simulated_penalty(method: str, params: dict, dt: float, bounds: ResponseBounds,
                      amplitude_m: float = 0.3) -> float:
    """:func:`response_penalty` of the simulated (describing) response on a 40-point grid."""
    f = np.union1d(np.geomspace(0.05, 0.45 / dt, 30), np.linspace(0.05, bounds.bandwidth_hz, 10))
    r = acceleration_response(method, params, dt, freqs_hz=f, amplitude_m=amplitude_m)
    H = r.gain * np.exp(1j * np.radians(r.phase_deg))
    return float(response_penalty(jnp.asarray(H), f, bounds))


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
    """Tune one baseline's hyperparameter (see :data:`BASELINE_GRIDS`) on a log grid,
    refined by golden section, minimising the mean over the training signals of the log
    train acceleration RMSE, plus :data:`PENALTY_WEIGHT` x :func:`simulated_penalty` when
    ``constrain`` (the response is measured by simulation: the describing response at 0.3 m
    for Levant).  Other arguments as :func:`tune`.

    ``kalman``/``rts`` use the measurement variance ``r = noise_std^2``.
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
    res.extra["constrained"] = bool(constrain)
    say(f"tune {method}: {name} = {params[name]:.4g}")
    return res


def tune_method(method: str, noise_std: float, **kw) -> TuneResult:
    """:func:`tune` for the SIHD family, :func:`tune_baseline` otherwise."""
    if method in SIHD_METHODS:
        return tune(method, noise_std, **kw)
    keep = ("signal", "train_seeds", "test_seeds", "progress", "signals", "bounds", "constrain",
            "heldout")
    return tune_baseline(method, noise_std, **{k: v for k, v in kw.items() if k in keep})


"""Default gain tolerance: ``|gain - 1| <= RESPONSE_TOL`` up to the stated bandwidth."""


"""Default bound on ``|phase|`` of the acceleration estimate up to the stated bandwidth, deg."""


"""Bound on the acceleration gain below the bandwidth (no resonance)."""


"""Bound on the acceleration gain above the bandwidth: no peak above 1 beyond the tolerance
(no resonance; the noise is not amplified)."""


"""Weight of the response penalty in the (log) tuning loss."""


"""Acceleration amplitude (m/s^2) of the test sinusoids of a nonlinear method's describing
response (position amplitude ``min(amplitude_m, a / (2 pi f)^2)``)."""
