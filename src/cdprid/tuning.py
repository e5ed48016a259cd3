"""Tuning of differentiator parameters for a given position-noise level.

The SIHD family (``sihd2-cascade``, ``sihd3`` and the higher-order ``sihd4``,
``sihd5`` of :mod:`cdprid.sihd_high`) is tuned by gradient-based optimisation
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

Objectives: ``"accel"`` causal 3-D acceleration RMSE over ``t >= t0``
(default 2 s), ``"params"`` relative error of the 4-parameter least squares
(m, m s_G) on simulated tensions, or ``"mix"``.  The baselines
(``euler-filtfilt``, ``euler-butter-causal``, ``savgol``, ``kalman``, ``rts``,
``levant``) are tuned on the same realisations by a log-grid search refined
by golden section (:func:`tune_baseline`).

The noise level can be estimated from a dataset (:func:`noise_from_dataset`,
which uses :func:`cdprid.diagnose.estimate_noise`), and the training signal
can be the dataset's own smoothed trajectory (:func:`dataset_signal`).
"""

from __future__ import annotations

import dataclasses
import math
import time

import jax
import jax.numpy as jnp
import numpy as np

from .differentiators import METHODS, differentiate
from .sihd_high import METHOD_INFO as HIGH_INFO
from .sihd_high import differentiate_high, sihdn_channel

__all__ = [
    "TrainingSignal",
    "TuneResult",
    "SIHD_METHODS",
    "BASELINE_GRIDS",
    "PAPER_PARAMS",
    "circle_signal",
    "lissajous_signal",
    "dataset_signal",
    "noise_from_dataset",
    "noise_realisations",
    "any_differentiate",
    "evaluate",
    "sihd_loss_fn",
    "tune",
    "tune_baseline",
    "tune_method",
    "ParamProblem",
]

SIHD_METHODS = ("sihd2-cascade", "sihd3", "sihd4", "sihd5")
PAPER_PARAMS = dict(METHODS["sihd2-cascade"].params)

#: Searched parameter, log-grid bounds and fixed extras of each tuned baseline.
BASELINE_GRIDS = {
    "euler-filtfilt": ("cutoff_hz", 0.3, 20.0, {}),
    "euler-butter-causal": ("cutoff_hz", 0.3, 20.0, {}),
    "savgol": ("window_s", 0.1, 8.0, {}),
    "kalman": ("q", 1e-4, 1e4, {}),
    "rts": ("q", 1e-5, 1e3, {}),
    "levant": ("L", 0.05, 200.0, {}),
}


# ----------------------------------------------------------------------------- signals


@dataclasses.dataclass(frozen=True)
class TrainingSignal:
    """Noise-free positions and accelerations on a uniform grid.

    Attributes
    ----------
    t : ndarray (n,)
    dt : float
    position, acceleration : ndarray (n, 3)
    name : str
    t0 : float
        Errors are measured over ``t >= t0`` (start-up transients excluded).
    """

    t: np.ndarray
    dt: float
    position: np.ndarray
    acceleration: np.ndarray
    name: str = "signal"
    t0: float = 2.0

    @property
    def mask(self) -> np.ndarray:
        return self.t >= self.t[0] + self.t0


def circle_signal(radius=0.3, freq_hz=0.25, dt=0.01, duration=52.0, centre=(0.0, 0.0, 1.2),
                  phase=0.0) -> TrainingSignal:
    """Horizontal circle (the differentiator benchmark's default signal)."""
    t = np.arange(int(round(duration / dt))) * dt
    w = 2 * math.pi * freq_hz
    c = np.asarray(centre, float)
    ph = w * t + phase
    pos = np.c_[c[0] + radius * np.cos(ph), c[1] + radius * np.sin(ph), c[2] + 0 * t]
    acc = np.c_[-radius * w**2 * np.cos(ph), -radius * w**2 * np.sin(ph), 0 * t]
    return TrainingSignal(t, dt, pos, acc, f"circle R {radius:g} m {freq_hz:g} Hz")


def lissajous_signal(ax=0.25, ay=0.2, az=0.1, f=(0.2, 0.4, 0.3), dt=0.01, duration=52.0,
                     centre=(0.0, 0.0, 1.2)) -> TrainingSignal:
    """3-D Lissajous curve (a test trajectory with several frequencies on every axis)."""
    t = np.arange(int(round(duration / dt))) * dt
    amps = np.array([ax, ay, az])
    w = 2 * math.pi * np.asarray(f)
    pos = np.asarray(centre)[None, :] + amps * np.sin(w * t[:, None] + np.array([0.0, 0.5, 1.0]))
    acc = -amps * w**2 * np.sin(w * t[:, None] + np.array([0.0, 0.5, 1.0]))
    return TrainingSignal(t, dt, pos, acc, "lissajous 0.2/0.4/0.3 Hz")


def noise_from_dataset(ds) -> float:
    """Position-noise std (m) of a dataset, from robust 4th differences, averaged over axes."""
    from .diagnosis import estimate_noise
    from .io import align

    sig = align(ds)
    s = np.asarray(estimate_noise(sig.position), float)
    v = float(np.sqrt(np.mean(s**2)))
    if not (math.isfinite(v) and v > 0):
        raise ValueError("could not estimate a positive position noise from the dataset.")
    return v


def dataset_signal(ds, window_s: float = 1.5) -> TrainingSignal:
    """Training signal with the shape of a dataset's trajectory.

    The positions are smoothed by a Savitzky-Golay filter (``window_s``,
    polynomial order 5, zero phase) whose 0th and 2nd derivatives serve as
    the noise-free position and acceleration.
    """
    from scipy.signal import savgol_filter

    from .io import align

    sig = align(ds)
    dt = float(sig.dt)
    w = int(round(window_s / dt)) | 1
    n = sig.position.shape[0]
    if n < max(w, 5 * int(round(2.0 / dt))):
        raise ValueError(f"the dataset is too short to tune on ({n} pose samples).")
    kw = dict(window_length=w, polyorder=5, axis=0, mode="interp", delta=dt)
    pos = savgol_filter(sig.position, deriv=0, **kw)
    acc = savgol_filter(sig.position, deriv=2, **kw)
    return TrainingSignal(sig.t - sig.t[0], dt, pos, acc, "dataset (smoothed)")


def noise_realisations(n_samples: int, seeds, dims: int = 3) -> np.ndarray:
    """Standard normal noise (len(seeds), n, dims); seed ``s`` always gives the same draw."""
    return np.stack([np.random.default_rng(int(s)).standard_normal((n_samples, dims))
                     for s in seeds])


# ----------------------------------------------------------------------------- evaluation


def any_differentiate(y, dt, method, **params):
    """:func:`cdprid.differentiate`, or :func:`cdprid.sihd_high.differentiate_high` for
    ``sihd4``/``sihd5`` while they are not registered in ``METHODS``."""
    if method in METHODS:
        return differentiate(y, dt, method, **params)
    if method in HIGH_INFO:
        return differentiate_high(y, dt, method, **params)
    raise ValueError(
        f"unknown method {method!r}; use one of {', '.join([*METHODS, *HIGH_INFO])}."
    )


def evaluate(method, params, signal: TrainingSignal, noise_std: float, seeds) -> np.ndarray:
    """3-D acceleration RMSE over ``signal.mask`` for each seed (one batched call)."""
    seeds = list(seeds)
    nz = noise_realisations(signal.t.size, seeds)
    y = signal.position[None] + noise_std * nz  # (S, n, 3)
    Y = np.transpose(y, (1, 0, 2)).reshape(signal.t.size, -1)
    _, A = any_differentiate(Y, signal.dt, method, **params)
    A = A.reshape(signal.t.size, len(seeds), 3)
    err = (A - signal.acceleration[:, None, :])[signal.mask]
    return np.sqrt(np.mean(np.sum(err**2, axis=2), axis=0))


# ----------------------------------------------------------------------------- SIHD parametrisation


def _order(method: str) -> int:
    return 2 if method == "sihd2-cascade" else int(method[4:])


def _alpha_min(method: str) -> float:
    return 0.5 if method == "sihd2-cascade" else (_order(method) - 1) / _order(method)


def _sigmoid(x):
    return 1.0 / (1.0 + jnp.exp(-x))


def _logit(p):
    return math.log(p / (1 - p))


#: Default floor of the damping ratio of every complex root pair of SIHD-N (N >= 3).  With
#: 0 (default) the optimiser is free to place lightly damped pairs that resonate near the
#: training signal's frequency (zeta ~ 0.1-0.25 on the benchmark circle): lowest error on
#: that spectrum, worse on others (results/tuning.md); 0.5 trades some of one for the other.
ZETA_MIN = 0.0


def _poly_from_theta(th, n, zeta_min=None):
    """Monic Hurwitz polynomial coefficients [lambda1..lambdaN] from root parameters
    (pairs: ``omega = exp(th_i)``, ``zeta = zeta_min + exp(th_i+1)``)."""
    zmin = ZETA_MIN if zeta_min is None else zeta_min
    coef = jnp.ones((1,), th.dtype)
    i = 0
    if n % 2 == 1:
        coef = jnp.convolve(coef, jnp.stack([jnp.ones((), th.dtype), jnp.exp(th[0])]))
        i = 1
    while i < n:
        om, ze = jnp.exp(th[i]), zmin + jnp.exp(th[i + 1])
        coef = jnp.convolve(coef, jnp.stack([jnp.ones((), th.dtype), 2 * ze * om, om**2]))
        i += 2
    return coef[1:]


def _theta_to_gains(method, th, zeta_min=None):
    """(lambdas tuple, alpha) from theta (JAX-traceable)."""
    n = _order(method)
    amin = _alpha_min(method)
    alpha = amin + (1.0 - amin) * _sigmoid(th[-1])
    if method == "sihd2-cascade":
        return tuple(jnp.exp(th[q]) for q in range(4)), alpha
    lam = _poly_from_theta(th[:-1], n, zeta_min)
    return tuple(lam[q] for q in range(n)), alpha


def params_from_theta(method, th, zeta_min=None) -> dict:
    """Method parameters (names of ``METHODS``/``METHOD_INFO``) from theta."""
    lams, alpha = _theta_to_gains(method, jnp.asarray(th, jnp.float64), zeta_min)
    p = {f"lambda{q + 1}": float(v) for q, v in enumerate(lams)}
    p["alpha"] = float(min(alpha, 1.0))
    p["mu"] = 1.0
    return p


def _roots_theta(lams, zeta_min=None):
    """Root parameters (log omega, log zeta) of a Hurwitz polynomial, for initialisation."""
    n = len(lams)
    r = np.roots(np.r_[1.0, np.asarray(lams, float)])
    if np.any(r.real >= 0):
        raise ValueError("initial gains give an unstable linear part.")
    real = sorted([x.real for x in r if abs(x.imag) < 1e-9 * max(1, abs(x))])
    cplx = sorted([x for x in r if x.imag > 1e-9 * max(1, abs(x))], key=lambda z: abs(z))
    th = []
    if n % 2 == 1:
        th.append(math.log(-real.pop(len(real) // 2)))
    pairs = [(abs(z), -z.real / abs(z)) for z in cplx]
    while len(real) >= 2:  # two real roots a, b -> omega = sqrt(ab), zeta = (a+b)/(2 omega)
        a, b = -real.pop(0), -real.pop(-1)
        om = math.sqrt(a * b)
        pairs.append((om, (a + b) / (2 * om)))
    zmin = ZETA_MIN if zeta_min is None else zeta_min
    for om, ze in pairs:
        th += [math.log(om), math.log(max(ze - zmin, 1e-3))]
    return th


def theta_from_params(method, params, zeta_min=None) -> np.ndarray:
    """Inverse of :func:`params_from_theta` (alpha clipped into the open interval)."""
    n = _order(method)
    amin = _alpha_min(method)
    mu = float(params.get("mu", 1.0))
    if method == "sihd2-cascade":
        lams = [params["lambda1"] * mu, params["lambda2"] * mu**2,
                params["lambda3"] * mu, params["lambda4"] * mu**2]
        th = [math.log(float(v)) for v in lams]
    else:
        th = _roots_theta([float(params[f"lambda{q}"]) * mu**q for q in range(1, n + 1)],
                           zeta_min)
    a = min(max(float(params["alpha"]), amin + 1e-4 * (1 - amin)), 1 - 1e-4 * (1 - amin))
    th.append(_logit((a - amin) / (1 - amin)))
    return np.asarray(th, float)


def default_params(method) -> dict:
    """Starting parameters of a method (METHODS defaults, paper gains for the cascade)."""
    if method in METHODS:
        return dict(METHODS[method].params)
    return dict(HIGH_INFO[method]["params"])


def _acc_channel(method, y, h, lams, alpha):
    """Acceleration of one channel with the SIHD equations (NaN-free gradients)."""
    one = jnp.ones((), y.dtype)
    if method == "sihd2-cascade":
        v, _ = sihdn_channel(y, h, lams[:2], alpha, one)
        a, _ = sihdn_channel(v, h, lams[2:], alpha, one)
        return a
    return sihdn_channel(y, h, lams, alpha, one)[1]


def sihd_loss_fn(method, zeta_min=None):
    """``f(theta, (Y, acc, mask, h)) -> mean squared 3-D acceleration error``.

    ``Y`` is (n, 3 S) (S noise realisations of the 3 axes), ``acc`` (n, 3 S)
    the true accelerations, ``mask`` (n,) 0/1 weights.  All channels run in
    one ``vmap`` of the ``lax.scan``.
    """

    def f(th, args):
        Y, acc, mask, h = args
        lams, alpha = _theta_to_gains(method, th, zeta_min)
        A = jax.vmap(lambda c: _acc_channel(method, c, h, lams, alpha), in_axes=1, out_axes=1)(Y)
        se = jnp.sum(((A - acc) ** 2) * mask[:, None])
        return se / (jnp.sum(mask) * (Y.shape[1] // 3))

    return f


# ----------------------------------------------------------------------------- parameter error


class ParamProblem:
    """4-parameter least squares (m, m s_G) on simulated tensions, differentiable in the
    estimated accelerations.

    The CRAFT-like robot follows the training signal (rotation-free); the cable
    wrench ``W(p) tau`` is computed at the true poses from the simulated
    tensions plus tension noise ``tension_std`` (one draw per seed).
    """

    def __init__(self, signal: TrainingSignal, seeds, tension_std: float = 0.5):
        from .dynamics import regressor_translation
        from .geometry import wrench_matrix
        from .robots import craft_like_robot, craft_like_truth
        from .simulate import SensorNoise, simulate
        from .trajectories import SampledTrajectory

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


# ----------------------------------------------------------------------------- tuning


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
    for om in (5.0, 8.0, 12.0, 18.0):
        roots = [om * complex(math.cos(math.pi * (2 * k + n + 1) / (2 * n)),
                              math.sin(math.pi * (2 * k + n + 1) / (2 * n))) for k in range(n)]
        lam = np.real(np.poly(roots))[1:]
        p = {f"lambda{q + 1}": float(lam[q]) for q in range(n)}
        p.update(alpha=0.995, mu=1.0)
        cands.append(p)
    return cands


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
) -> TuneResult:
    """Tune an SIHD method by BFGS through the scan.

    Parameters
    ----------
    method : {"sihd2-cascade", "sihd3", "sihd4", "sihd5"}
    noise_std : float
        Position-noise std (m) of the training realisations.
    signal : TrainingSignal, optional
        Default :func:`circle_signal` (benchmark circle).
    train_seeds, test_seeds : iterables of int
        Noise seeds used for tuning and for the held-out evaluation.
    objective : {"accel", "params", "mix"}
        ``accel``: mean-square acceleration error; ``params``: scaled LS
        parameter error (:class:`ParamProblem`); ``mix``:
        ``(1-weight) accel_mse / a_rms^2 + weight params``.
    max_steps : int
        BFGS iterations.
    init : dict, optional
        Start here instead of the best of a few standard starts.
    zeta_min : float, optional
        Damping floor of the root pairs (SIHD-N, N >= 3; default :data:`ZETA_MIN`;
        0 lets the optimiser fit resonances to the training spectrum).
    progress : callable(str), optional

    Returns
    -------
    TuneResult
    """
    import optimistix as optx

    if method not in SIHD_METHODS:
        raise ValueError(f"gradient tuning supports {', '.join(SIHD_METHODS)}; got {method!r}.")
    if objective not in ("accel", "params", "mix"):
        raise ValueError(f"unknown objective {objective!r}; use accel, params or mix.")
    if not (math.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise std must be a positive number of metres, got {noise_std!r}.")
    say = progress or (lambda s: None)
    signal = signal or circle_signal()
    train_seeds, test_seeds = list(train_seeds), list(test_seeds)
    t_wall, t_cpu = time.perf_counter(), time.process_time()

    with jax.enable_x64(True):
        Y, acc = _stack_train(signal, noise_std, train_seeds)
        mask = signal.mask.astype(float)
        h = float(signal.dt)
        args = (jnp.asarray(Y), jnp.asarray(acc), jnp.asarray(mask), jnp.asarray(h))
        mse = sihd_loss_fn(method, zeta_min)
        a_ms = float(np.mean(np.sum(signal.acceleration[signal.mask] ** 2, axis=1)))
        pp = None
        if objective != "accel":
            pp = ParamProblem(signal, train_seeds)

        def loss(th, args):
            Yv, accv, maskv, hv = args
            if objective == "accel":
                return jnp.log(mse(th, args))
            lams, alpha = _theta_to_gains(method, th, zeta_min)
            A = jax.vmap(lambda c: _acc_channel(method, c, hv, lams, alpha),
                         in_axes=1, out_axes=1)(Yv)
            pe = jnp.mean(pp.rel_error(A.reshape(A.shape[0], -1, 3), np.asarray(maskv)))
            if objective == "params":
                return jnp.log(pe)
            se = jnp.sum(((A - accv) ** 2) * maskv[:, None])
            se = se / (jnp.sum(maskv) * (Yv.shape[1] // 3))
            return jnp.log((1 - weight) * se / a_ms + weight * pe)

        loss_j = jax.jit(loss)
        # pick the best start (forward passes only)
        cands = [init] if init is not None else _init_candidates(method, noise_std)
        best = None
        for c in cands:
            th0 = jnp.asarray(theta_from_params(method, c, zeta_min))
            v = float(loss_j(th0, args))
            if best is None or (math.isfinite(v) and v < best[0]):
                best = (v, th0)
        say(f"tune {method}: start loss {best[0]:.4f} (best of {len(cands)} starts)")
        solver = optx.BFGS(rtol=1e-5, atol=1e-6)
        sol = optx.minimise(loss_j, solver, best[1], args=args, max_steps=max_steps,
                            throw=False)
        th = sol.value
        v_end = float(loss_j(th, args))
        if not (math.isfinite(v_end) and v_end <= best[0]):
            th, v_end = best[1], best[0]
        steps = int(sol.stats.get("num_steps", 0))
        status = ("converged" if sol.result == optx.RESULTS.successful
                  else "not converged: " + optx.RESULTS[sol.result].split(".")[0])
        say(f"tune {method}: end loss {v_end:.4f} after {steps} BFGS steps ({status}; the best "
            "loss seen is kept)")
    params = params_from_theta(method, th, zeta_min)
    wall, cpu = time.perf_counter() - t_wall, time.process_time() - t_cpu
    train = float(np.mean(evaluate(method, params, signal, noise_std, train_seeds)))
    test = float(np.mean(evaluate(method, params, signal, noise_std, test_seeds)))
    paper = float(np.mean(evaluate("sihd2-cascade", PAPER_PARAMS, signal, noise_std, test_seeds)))
    dflt = float(np.mean(evaluate(method, default_params(method), signal, noise_std, test_seeds)))
    say(f"tune {method}: train {train:.4g}, test {test:.4g}, paper {paper:.4g} m/s^2 "
        f"({wall:.1f} s wall, {cpu:.1f} s CPU)")
    return TuneResult(method, params, float(noise_std), train, test, paper, dflt, objective,
                      train_seeds, test_seeds, signal.name, wall, cpu, steps)


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


def tune_baseline(
    method: str,
    noise_std: float = 5e-4,
    signal: TrainingSignal | None = None,
    train_seeds=range(4),
    test_seeds=range(100, 108),
    n_grid: int = 17,
    refine: int = 10,
    progress=None,
) -> TuneResult:
    """Tune one baseline's hyperparameter (see :data:`BASELINE_GRIDS`) on a log grid,
    refined by golden section, minimising the mean train acceleration RMSE.

    ``kalman``/``rts`` use the measurement variance ``r = noise_std^2``.
    """
    if method not in BASELINE_GRIDS:
        raise ValueError(f"grid tuning supports {', '.join(BASELINE_GRIDS)}; got {method!r}.")
    say = progress or (lambda s: None)
    signal = signal or circle_signal()
    train_seeds, test_seeds = list(train_seeds), list(test_seeds)
    name, lo, hi, fixed = BASELINE_GRIDS[method]
    fixed = dict(fixed)
    if method in ("kalman", "rts"):
        fixed["r"] = float(noise_std) ** 2
    if method in ("euler-filtfilt", "euler-butter-causal"):
        hi = min(hi, 0.45 / signal.dt)
    t_wall, t_cpu = time.perf_counter(), time.process_time()

    def cost(logv):
        try:
            return float(np.mean(evaluate(method, {**fixed, name: math.exp(logv)}, signal,
                                          noise_std, train_seeds)))
        except ValueError:
            return float("inf")

    grid = np.linspace(math.log(lo), math.log(hi), n_grid)
    vals = [cost(g) for g in grid]
    k = int(np.nanargmin(vals))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, n_grid - 1)]
    lv, _ = _golden(cost, a, b, refine)
    params = {**fixed, name: float(math.exp(lv))}
    if method == "savgol":  # report the window actually used (odd number of samples)
        w = int(round(params["window_s"] / signal.dt)) | 1
        params["window_s"] = w * signal.dt
    wall, cpu = time.perf_counter() - t_wall, time.process_time() - t_cpu
    train = float(np.mean(evaluate(method, params, signal, noise_std, train_seeds)))
    test = float(np.mean(evaluate(method, params, signal, noise_std, test_seeds)))
    paper = float(np.mean(evaluate("sihd2-cascade", PAPER_PARAMS, signal, noise_std, test_seeds)))
    dflt = float(np.mean(evaluate(method, default_params(method), signal, noise_std, test_seeds)))
    say(f"tune {method}: {name} = {params[name]:.4g}, train {train:.4g}, test {test:.4g} m/s^2")
    return TuneResult(method, params, float(noise_std), train, test, paper, dflt, "accel",
                      train_seeds, test_seeds, signal.name, wall, cpu, n_grid + refine + 2)


def tune_method(method: str, noise_std: float, **kw) -> TuneResult:
    """:func:`tune` for the SIHD family, :func:`tune_baseline` otherwise."""
    if method in SIHD_METHODS:
        return tune(method, noise_std, **kw)
    kw = {k: v for k, v in kw.items() if k in ("signal", "train_seeds", "test_seeds", "progress")}
    return tune_baseline(method, noise_std, **kw)


# ----------------------------------------------------------------------------- frequency response

RESPONSE_TOL = 0.05
"""Bandwidth: the highest frequency up to which the acceleration gain stays within 5 % of 1."""

GAIN_MAX_BELOW = 1.1
"""Bound on the acceleration gain below the bandwidth (no resonance)."""

GAIN_MAX_ABOVE = 1.0
"""Bound on the acceleration gain above the bandwidth (noise must not be amplified)."""


@dataclasses.dataclass(frozen=True)
class FrequencyResponse:
    """Measured acceleration response of a differentiator (sinusoids through it).

    Attributes
    ----------
    freqs_hz, gain, phase_deg : ndarray (F,)
        Frequency, gain and phase of the estimated acceleration relative to the true one.
    amplitude_m : float
        Position amplitude of the test sinusoids (homogeneous differentiators depend on it).
    bandwidth_hz : float
        Highest tested frequency up to which ``|gain - 1| <= RESPONSE_TOL`` (0 if none).
    gain_max_below, gain_max_above : float
        Largest gain at or below / above the bandwidth.
    phase_at_bandwidth_deg : float
    ok : bool
        ``gain_max_below <= GAIN_MAX_BELOW`` and ``gain_max_above <= GAIN_MAX_ABOVE``.
    """

    freqs_hz: np.ndarray
    gain: np.ndarray
    phase_deg: np.ndarray
    amplitude_m: float
    bandwidth_hz: float
    gain_max_below: float
    gain_max_above: float
    phase_at_bandwidth_deg: float
    ok: bool

    def as_json(self) -> dict:
        """Numbers for ``tune --json`` (key ``frequency_response``)."""
        return {
            "freqs_hz": [float(f) for f in self.freqs_hz],
            "gain": [float(g) for g in self.gain],
            "phase_deg": [float(p) for p in self.phase_deg],
            "amplitude_m": self.amplitude_m,
            "bandwidth_hz": self.bandwidth_hz,
            "bandwidth_rule": f"|gain - 1| <= {RESPONSE_TOL:g}",
            "gain_max_below_bandwidth": self.gain_max_below,
            "gain_max_above_bandwidth": self.gain_max_above,
            "phase_at_bandwidth_deg": self.phase_at_bandwidth_deg,
            "bounds": {"gain_max_below": GAIN_MAX_BELOW, "gain_max_above": GAIN_MAX_ABOVE},
            "within_bounds": self.ok,
        }

    def summary(self) -> str:
        """One line of numbers."""
        return (f"acceleration response: gain within {100 * RESPONSE_TOL:g} % of 1 up to "
                f"{self.bandwidth_hz:.3g} Hz (phase there {self.phase_at_bandwidth_deg:.0f} deg), "
                f"max gain {self.gain_max_below:.3g} below and {self.gain_max_above:.3g} above "
                f"it (bounds {GAIN_MAX_BELOW:g}, {GAIN_MAX_ABOVE:g})")


def acceleration_response(method: str, params: dict, dt: float = 0.01, freqs_hz=None,
                          amplitude_m: float = 0.3, duration_s: float = 40.0
                          ) -> FrequencyResponse:
    """Gain and phase of ``method``'s acceleration on noise-free sinusoids.

    Each frequency is one channel ``A sin(2 pi f t)`` (all in one call); the fundamental of the
    estimated acceleration over the second half of the record (steady state) is compared with
    the true ``-A (2 pi f)^2 sin(2 pi f t)``.

    Parameters
    ----------
    method : str
    params : dict
        The differentiator's parameters.
    dt : float
        Sampling period, s.
    freqs_hz : array, optional
        Default: 30 log-spaced frequencies from 0.05 Hz to 0.4 / dt.
    amplitude_m : float
        Position amplitude (homogeneous SIHD/Levant respond differently at other amplitudes).
    duration_s : float
    """
    f = (np.geomspace(0.05, 0.4 / dt, 30) if freqs_hz is None
         else np.asarray(freqs_hz, float))
    t = np.arange(0.0, duration_s, dt)
    w = 2 * np.pi * f
    y = amplitude_m * np.sin(np.outer(t, w))
    _, a = any_differentiate(y, dt, method, **params)
    half = t >= duration_s / 2
    gain, phase = np.empty_like(f), np.empty_like(f)
    for i, wi in enumerate(w):
        X = np.column_stack([np.sin(wi * t[half]), np.cos(wi * t[half])])
        c, *_ = np.linalg.lstsq(X, np.asarray(a)[half, i], rcond=None)
        z = complex(c[0], c[1]) / (-amplitude_m * wi**2)  # relative to the true acceleration
        gain[i], phase[i] = abs(z), math.degrees(math.atan2(z.imag, z.real))
    inside = np.abs(gain - 1.0) <= RESPONSE_TOL
    k = int(np.argmin(inside)) if not inside.all() else len(f)
    bw = float(f[k - 1]) if k > 0 else 0.0
    below = gain[:k] if k > 0 else gain[:1]
    above = gain[k:] if k < len(f) else np.array([0.0])
    gb, ga = float(below.max()), float(above.max())
    return FrequencyResponse(f, gain, phase, float(amplitude_m), bw, gb, ga,
                             float(phase[k - 1]) if k > 0 else float("nan"),
                             bool(gb <= GAIN_MAX_BELOW and ga <= GAIN_MAX_ABOVE))
