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

from cdprid.signal._differentiators import METHODS, differentiate
from cdprid.signal._sihd_high import METHOD_INFO as HIGH_INFO
from cdprid.signal._sihd_high import differentiate_high, sihdn_channel

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
    "ResponseBounds",
    "FrequencyResponse",
    "TRAIN_FAMILY",
    "HELDOUT_FAMILY",
    "trajectory_signal",
    "trajectory_family",
    "content_bandwidth",
    "resolve_bounds",
    "dense_freqs",
    "penalty_freqs",
    "sihd_linear_response",
    "response_penalty",
    "simulated_penalty",
    "response_warnings",
    "acceleration_response",
    "is_linear",
    "RESPONSE_TOL",
    "PHASE_MAX_DEG",
    "GAIN_MAX_BELOW",
    "GAIN_MAX_ABOVE",
    "PENALTY_WEIGHT",
    "CONTINUATION",
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
    from cdprid.core._noise import estimate_noise
    from cdprid.io import align

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

    from cdprid.io import align

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
    """:func:`cdprid.differentiate`, or :func:`cdprid.signal.differentiate_high` for
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


def _theta_to_gains(method, th, zeta_min=None, fixed_alpha=None):
    """(lambdas tuple, alpha) from theta (JAX-traceable); with ``fixed_alpha`` theta has no
    alpha entry."""
    n = _order(method)
    if fixed_alpha is None:
        amin = _alpha_min(method)
        alpha = amin + (1.0 - amin) * _sigmoid(th[-1])
        g = th[:-1]
    else:
        alpha, g = jnp.asarray(fixed_alpha, th.dtype), th
    if method == "sihd2-cascade":
        return tuple(jnp.exp(g[q]) for q in range(4)), alpha
    lam = _poly_from_theta(g, n, zeta_min)
    return tuple(lam[q] for q in range(n)), alpha


def params_from_theta(method, th, zeta_min=None, fixed_alpha=None) -> dict:
    """Method parameters (names of ``METHODS``/``METHOD_INFO``) from theta."""
    lams, alpha = _theta_to_gains(method, jnp.asarray(th, jnp.float64), zeta_min, fixed_alpha)
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


def theta_from_params(method, params, zeta_min=None, fixed_alpha=None) -> np.ndarray:
    """Inverse of :func:`params_from_theta` (alpha clipped into the open interval; no alpha
    entry with ``fixed_alpha``)."""
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
    if fixed_alpha is not None:
        return np.asarray(th, float)
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
        from cdprid.model._dynamics import regressor_translation
        from cdprid.model._geometry import wrench_matrix
        from cdprid.model._robots import craft_like_robot, craft_like_truth
        from cdprid.model._trajectories import SampledTrajectory
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



# ----------------------------------------------------------------------------- trajectory families

#: Training family of :func:`trajectory_family`: (frequency Hz, radius m, azimuth rad, tilt rad,
#: ramp s) of one ramped orbit each (spiral in from rest, orbit, spiral out).  Orbits at
#: 0.1-0.8 Hz, radii 0.05-0.3 m, horizontal, vertical and tilted planes, and one long-ramp member.
TRAIN_FAMILY = (
    (0.10, 0.30, 0.0, 0.0, 3.0),
    (0.25, 0.20, 0.0, math.pi / 2, 3.0),
    (0.40, 0.15, 0.5, 0.6, 3.0),
    (0.55, 0.10, math.pi / 2, math.pi / 2, 3.0),
    (0.70, 0.08, 0.0, 0.0, 3.0),
    (0.80, 0.05, 1.0, 1.0, 3.0),
    (0.30, 0.25, 0.0, 0.0, 8.0),
)

#: Held-out family (never used for tuning): other frequencies, radii, planes and ramps.  The
#: held-out set of :func:`trajectory_family` adds a 3-D Lissajous and a two-orbit sequence.
HELDOUT_FAMILY = (
    (0.15, 0.25, math.pi / 2, math.pi / 2, 3.0),
    (0.33, 0.30, 0.0, 0.0, 3.0),
    (0.45, 0.12, 0.0, math.pi / 2, 3.0),
    (0.60, 0.10, 0.8, 0.5, 3.0),
    (0.75, 0.06, 0.3, math.pi / 2, 3.0),
    (0.50, 0.15, 2.0, 0.3, 8.0),
)


def trajectory_signal(traj, dt: float, name: str | None = None, t0: float = 2.0
                      ) -> TrainingSignal:
    """Sample a :class:`cdprid.model.Trajectory` (exact derivatives) as a training signal.

    Parameters
    ----------
    traj : cdprid.model._trajectories.Trajectory
    dt : float
        Sampling period, s.
    name : str, optional
    t0 : float
        Errors are measured over ``t >= t0``.

    Returns
    -------
    TrainingSignal
    """
    t = np.arange(int(round(traj.t_end / dt)) + 1) * dt
    s = traj.evaluate(t)
    return TrainingSignal(t, float(dt), np.asarray(s.p, float), np.asarray(s.a, float),
                          name or traj.name, t0)


def _orbit_member(f, r, az, tilt, ramp, dt, duration):
    from cdprid.model._trajectories import Orbit, orbit_sequence

    ramp = min(ramp, duration / 3)
    plane = {0.0: "horizontal"}.get(tilt, "vertical" if abs(tilt - math.pi / 2) < 1e-9 else
                                    "tilted")
    traj = orbit_sequence([Orbit(r, f, duration - 1.0, az, tilt, 0.0, ramp)], (0.0, 0.0, 1.2))
    return trajectory_signal(traj, dt, f"orbit {f:g} Hz R {r:g} m {plane}, ramp {ramp:g} s")


def trajectory_family(which: str = "train", dt: float = 0.01, duration: float = 25.0
                      ) -> list[TrainingSignal]:
    """The training or held-out family of trajectories (ramped orbits of
    :mod:`cdprid.model._trajectories`; see :data:`TRAIN_FAMILY`, :data:`HELDOUT_FAMILY`).

    Parameters
    ----------
    which : {"train", "heldout"}
    dt : float
        Sampling period, s.
    duration : float
        Length of each member, s (>= 5).

    Returns
    -------
    list of TrainingSignal
    """
    if which not in ("train", "heldout"):
        raise ValueError(f"unknown family {which!r}; use train or heldout.")
    if not duration >= 5.0:
        raise ValueError(f"family members must last at least 5 s, got {duration!r}.")
    rows = TRAIN_FAMILY if which == "train" else HELDOUT_FAMILY
    out = [_orbit_member(*row, dt, duration) for row in rows]
    if which == "heldout":
        from cdprid.model._trajectories import Orbit, orbit_sequence

        d = (duration - 1.5) / 2
        seq = orbit_sequence([Orbit(0.2, 0.2, d, 0.0, 0.0, 0.0, min(3.0, d / 3)),
                              Orbit(0.07, 0.65, d, 0.0, math.pi / 2, 0.0, min(3.0, d / 3))],
                             (0.0, 0.0, 1.2))
        out.append(trajectory_signal(seq, dt, "sequence 0.2 Hz + 0.65 Hz orbits"))
        out.append(lissajous_signal(dt=dt, duration=duration))
    return out


def content_bandwidth(signals, fraction: float = 0.99, step_hz: float = 0.05) -> float:
    """Default stated bandwidth: the frequency below which ``fraction`` of the training
    accelerations' energy lies (Hann-windowed periodogram over ``t >= t0``, all axes; the
    largest over the members), rounded
    up to ``step_hz`` and clipped to ``[0.1 Hz, 0.1 / dt]``.

    Parameters
    ----------
    signals : sequence of TrainingSignal
    fraction : float
    step_hz : float

    Returns
    -------
    float
        Bandwidth, Hz.
    """
    best = 0.0
    dt = float(signals[0].dt)
    for s in signals:
        a = s.acceleration[s.mask]
        a = (a - a.mean(axis=0)) * np.hanning(a.shape[0])[:, None]  # Hann: little leakage
        p = np.sum(np.abs(np.fft.rfft(a, axis=0)) ** 2, axis=1)
        f = np.fft.rfftfreq(a.shape[0], s.dt)
        c = np.cumsum(p)
        if c[-1] <= 0:
            continue
        best = max(best, float(f[int(np.searchsorted(c, fraction * c[-1]))]))
    bw = math.ceil(best / step_hz - 1e-9) * step_hz
    return round(float(min(max(bw, 0.1), 0.1 / dt)), 6)


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
            raise ValueError("give at least one training signal.")
        if len({float(s.dt) for s in sigs}) != 1:
            raise ValueError("all training signals must share one sampling period.")
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
        raise ValueError(f"gradient tuning supports {', '.join(SIHD_METHODS)}; got {method!r}.")
    if objective not in ("accel", "params", "mix"):
        raise ValueError(f"unknown objective {objective!r}; use accel, params or mix.")
    if not (math.isfinite(noise_std) and noise_std > 0):
        raise ValueError(f"noise std must be a positive number of metres, got {noise_std!r}.")
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
        raise ValueError(f"grid tuning supports {', '.join(BASELINE_GRIDS)}; got {method!r}.")
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


# ----------------------------------------------------------------------------- frequency response

RESPONSE_TOL = 0.05
"""Default gain tolerance: ``|gain - 1| <= RESPONSE_TOL`` up to the stated bandwidth."""

PHASE_MAX_DEG = 30.0
"""Default bound on ``|phase|`` of the acceleration estimate up to the stated bandwidth, deg."""

GAIN_MAX_BELOW = 1.1
"""Bound on the acceleration gain below the bandwidth (no resonance)."""

GAIN_MAX_ABOVE = 1.0 + RESPONSE_TOL
"""Bound on the acceleration gain above the bandwidth: no peak above 1 beyond the tolerance
(no resonance; the noise is not amplified)."""

PENALTY_WEIGHT = 100.0
"""Weight of the response penalty in the (log) tuning loss."""


@dataclasses.dataclass(frozen=True)
class ResponseBounds:
    """Bounds on a differentiator's acceleration frequency response.

    Attributes
    ----------
    bandwidth_hz : float
        Stated bandwidth B, Hz.
    gain_tol : float
        ``|gain - 1| <= gain_tol`` for ``f <= B``.
    phase_max_deg : float
        ``|phase| <= phase_max_deg`` for ``f <= B``.
    gain_max_below : float
        ``gain <= gain_max_below`` for ``f <= B``.
    gain_max_above : float
        ``gain <= gain_max_above`` for ``f > B`` (no resonance).
    """

    bandwidth_hz: float
    gain_tol: float = RESPONSE_TOL
    phase_max_deg: float = PHASE_MAX_DEG
    gain_max_below: float = GAIN_MAX_BELOW
    gain_max_above: float = GAIN_MAX_ABOVE

    def __post_init__(self):
        for k in ("bandwidth_hz", "gain_tol", "phase_max_deg", "gain_max_below", "gain_max_above"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"response bound {k} must be a positive number, got {v!r}.")

    def as_json(self) -> dict:
        """The bounds as JSON numbers."""
        return dataclasses.asdict(self)


def dense_freqs(dt: float, bandwidth_hz: float | None = None, n: int = 160) -> np.ndarray:
    """Verification grid: ``n`` log-spaced frequencies from 0.05 Hz to ``0.45 / dt`` (plus the
    bandwidth itself and 40 linearly spaced points up to it)."""
    f = np.geomspace(0.05, 0.45 / dt, n)
    if bandwidth_hz is not None:
        f = np.union1d(f, np.linspace(0.05, bandwidth_hz, 40))
    return f


def _pascal(n, h):
    return np.array([[h ** (j - i) / math.factorial(j - i) if j >= i else 0.0 for j in range(n)]
                     for i in range(n)])


def _stage_response(lams, h, out, zeta):
    """Transfer function ``y -> w_out`` of one linear (alpha = 1) SIHD stage at points ``zeta``.

    With alpha = 1 the SIHD correction of line q is ``e min(lambda_q, h^-q)`` (mu = 1), so the
    stage is the observer ``z+ = F (z + K e)``, ``w = z + K e``, ``e = y - z_1``,
    ``K = h min(lambda, h^-q)``, F the Taylor (Pascal) matrix.
    """
    n = len(lams)
    F = jnp.asarray(_pascal(n, h))
    lam = jnp.minimum(jnp.stack([jnp.asarray(v, jnp.float64) for v in lams]),
                      jnp.asarray([h ** -(q + 1) for q in range(n)]))
    K = h * lam
    e1 = jnp.zeros(n).at[0].set(1.0)
    A = F - jnp.outer(F @ K, e1)
    B = (F @ K).astype(jnp.complex128)
    c = jnp.zeros(n).at[out].set(1.0) - K[out] * e1
    eye = jnp.eye(n, dtype=jnp.complex128)
    return K[out] + jax.vmap(lambda z: c @ jnp.linalg.solve(z * eye - A, B))(zeta)


def sihd_linear_response(method: str, lams, dt: float, freqs_hz):
    """Acceleration response (complex, relative to the true acceleration) of a SIHD with
    alpha = 1, mu = 1 (a linear observer), JAX-traceable in the gains.

    Parameters
    ----------
    method : {"sihd2-cascade", "sihd3", "sihd4", "sihd5"}
    lams : sequence of scalars
        ``lambda1..lambdaN`` (4 for the cascade).
    dt : float
    freqs_hz : array (F,)

    Returns
    -------
    jax.Array (F,) complex
        ``H(f)``: the estimate of ``a sin(2 pi f t + p)`` is ``|H| a sin(2 pi f t + p + arg H)``.
    """
    w = 2 * np.pi * np.asarray(freqs_hz, float)
    zeta = jnp.asarray(np.exp(1j * w * dt))
    if method == "sihd2-cascade":
        hy = (_stage_response(lams[:2], dt, 1, zeta) * _stage_response(lams[2:], dt, 1, zeta))
    else:
        hy = _stage_response(lams, dt, 2, zeta)
    return hy / jnp.asarray(-(w**2))


def _noise_gain(method, lams, dt, n_grid: int = 2048):
    """Variance of the acceleration estimate per unit white position-noise variance
    (Parseval: the mean of ``|H_y|^2`` over the unit circle)."""
    om = (np.arange(n_grid) + 0.5) * np.pi / n_grid
    zeta = jnp.asarray(np.exp(1j * om))
    if method == "sihd2-cascade":
        hy = _stage_response(lams[:2], dt, 1, zeta) * _stage_response(lams[2:], dt, 1, zeta)
    else:
        hy = _stage_response(lams, dt, 2, zeta)
    return jnp.mean(jnp.abs(hy) ** 2)


def response_penalty(H, freqs_hz, bounds: ResponseBounds, margin: float = 0.9):
    """Smooth (squared-hinge) penalty of a response ``H`` outside ``bounds``.

    The gain and phase bounds are tightened by ``margin`` so that the optimum lies inside them
    (the final result is verified on a dense grid by :func:`acceleration_response`).
    """
    f = np.asarray(freqs_hz, float)
    below = jnp.asarray(f <= bounds.bandwidth_hz)
    g, ph = jnp.abs(H), jnp.angle(H)
    tol, phm = bounds.gain_tol, math.radians(bounds.phase_max_deg)
    relu = jax.nn.relu
    p_gain = relu(jnp.abs(g - 1.0) - margin * tol) / tol
    p_gmax = relu(g - (bounds.gain_max_below - (1 - margin) * tol)) / tol
    p_phase = relu(jnp.abs(ph) - margin * phm) / phm
    p_above = relu(g - (bounds.gain_max_above - (1 - margin) * tol)) / tol
    pen = jnp.where(below, p_gain**2 + p_gmax**2 + p_phase**2, p_above**2)
    return jnp.sum(pen)


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
        Measured: the highest tested frequency up to which ``|gain - 1| <= RESPONSE_TOL``
        (0 if none).
    gain_max_below, gain_max_above : float
        Largest gain at or below / above the (stated if given, else measured) bandwidth.
    phase_at_bandwidth_deg : float
        Phase at the measured bandwidth.
    ok : bool
        Within the stated bounds (``bounds``), else ``gain_max_below <= GAIN_MAX_BELOW`` and
        ``gain_max_above <= GAIN_MAX_ABOVE`` about the measured bandwidth.
    bounds : ResponseBounds or None
        The stated bounds the response was checked against.
    max_gain_error_below, max_phase_below_deg : float
        ``max |gain - 1|`` and ``max |phase|`` for ``f <= bounds.bandwidth_hz``.
    max_gain, peak_frequency_hz : float
        Largest gain over the grid and its frequency.
    phase_at_stated_bandwidth_deg : float
    violations : tuple of str
        One phrase per bound not met.
    linear : bool
        True when the method is linear (the response does not depend on the amplitude); else
        it is the describing response (fundamental of the output) at ``amplitude_m``.
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
    bounds: ResponseBounds | None = None
    max_gain_error_below: float = float("nan")
    max_phase_below_deg: float = float("nan")
    max_gain: float = float("nan")
    peak_frequency_hz: float = float("nan")
    phase_at_stated_bandwidth_deg: float = float("nan")
    violations: tuple = ()
    linear: bool = True
    accel_amplitude: float | None = None

    def as_json(self) -> dict:
        """Numbers for ``tune --json`` (key ``frequency_response``)."""
        d = {
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
            "response_kind": ("linear (amplitude-independent), measured with sinusoids"
                              if self.linear else
                              "describing response: fundamental of the output for position "
                              f"sinusoids of acceleration amplitude {self.accel_amplitude:g} "
                              f"m/s^2 (position at most {self.amplitude_m:g} m; nonlinear "
                              "method: other amplitudes respond differently)"),
        }
        if self.bounds is not None:
            d.update(self.check_json())
            d["bounds"] = self.bounds.as_json()
        return d

    def check_json(self) -> dict:
        """The verification against the stated bounds (top-level keys of ``tune --json``)."""
        b = self.bounds
        return {
            "stated_bandwidth_hz": b.bandwidth_hz if b else None,
            "max_gain_error_below_bandwidth": self.max_gain_error_below,
            "max_phase_below_bandwidth_deg": self.max_phase_below_deg,
            "max_gain": self.max_gain,
            "peak_frequency_hz": self.peak_frequency_hz,
            "phase_at_stated_bandwidth_deg": self.phase_at_stated_bandwidth_deg,
            "within_bounds": self.ok,
            "violations": list(self.violations),
            "response_linear": self.linear,
            "verification_grid": {"n": int(self.freqs_hz.size),
                                  "f_min_hz": float(self.freqs_hz[0]),
                                  "f_max_hz": float(self.freqs_hz[-1])},
        }

    def summary(self) -> str:
        """One line of numbers."""
        if self.bounds is not None:
            b = self.bounds
            return (f"acceleration response up to the stated bandwidth {b.bandwidth_hz:.3g} Hz: "
                    f"max |gain - 1| {self.max_gain_error_below:.3g} (bound {b.gain_tol:g}), "
                    f"max |phase| {self.max_phase_below_deg:.3g} deg (bound {b.phase_max_deg:g}),"
                    f" phase there {self.phase_at_stated_bandwidth_deg:.3g} deg; max gain "
                    f"{self.max_gain:.3g} at {self.peak_frequency_hz:.3g} Hz, "
                    f"{self.gain_max_above:.3g} above B (bound {b.gain_max_above:g}): "
                    + ("within bounds" if self.ok else "NOT within bounds"))
        return (f"acceleration response: gain within {100 * RESPONSE_TOL:g} % of 1 up to "
                f"{self.bandwidth_hz:.3g} Hz (phase there {self.phase_at_bandwidth_deg:.0f} deg), "
                f"max gain {self.gain_max_below:.3g} below and {self.gain_max_above:.3g} above "
                f"it (bounds {GAIN_MAX_BELOW:g}, {GAIN_MAX_ABOVE:g})")


def is_linear(method: str, params: dict) -> bool:
    """True when ``method`` with ``params`` is a linear filter (SIHD with alpha = 1 and gains
    below the dead-beat clip are linear; Levant and SIHD with alpha < 1 are not)."""
    if method == "levant":
        return False
    if method in SIHD_METHODS:
        return float(params.get("alpha", default_params(method)["alpha"])) == 1.0
    return True


def _fundamental(a, t, w, amp):
    """Complex gain of the fundamental of each column of ``a`` w.r.t. ``-A w^2 sin(w t)``."""
    out = np.empty(w.size, complex)
    for i, wi in enumerate(w):
        X = np.column_stack([np.sin(wi * t), np.cos(wi * t)])
        c, *_ = np.linalg.lstsq(X, a[:, i], rcond=None)
        out[i] = complex(c[0], c[1]) / (-amp[i] * wi**2)
    return out


NONLINEAR_ACCEL_AMPLITUDE = 1.0
"""Acceleration amplitude (m/s^2) of the test sinusoids of a nonlinear method's describing
response (position amplitude ``min(amplitude_m, a / (2 pi f)^2)``)."""


def acceleration_response(method: str, params: dict, dt: float = 0.01, freqs_hz=None,
                          amplitude_m: float = 0.3, duration_s: float = 40.0,
                          bounds: ResponseBounds | None = None,
                          accel_amplitude: float | None = None) -> FrequencyResponse:
    """Gain and phase of ``method``'s acceleration on noise-free sinusoids.

    Each frequency is one channel ``A sin(2 pi f t)`` (all in one call); the fundamental of the
    estimated acceleration over the second half of the record (steady state) is compared with
    the true ``-A (2 pi f)^2 sin(2 pi f t)``.  For a nonlinear method (Levant, SIHD with
    alpha < 1) this is the describing response at amplitude ``A``.

    Parameters
    ----------
    method : str
    params : dict
        The differentiator's parameters.
    dt : float
        Sampling period, s.
    freqs_hz : array, optional
        Default: 30 log-spaced frequencies from 0.05 Hz to 0.4 / dt, or :func:`dense_freqs`
        when ``bounds`` is given.
    amplitude_m : float
        Position amplitude (homogeneous SIHD/Levant respond differently at other amplitudes).
    duration_s : float
        Record length (default 40 s; 80 s with ``bounds``).
    bounds : ResponseBounds, optional
        Check the response against these stated bounds (``ok``, ``violations``...).
    accel_amplitude : float, optional
        Scale each sinusoid to this acceleration amplitude (position amplitude capped at
        ``amplitude_m``); default :data:`NONLINEAR_ACCEL_AMPLITUDE` for nonlinear methods
        (their describing response at a realistic acceleration), none for linear ones.
    """
    if freqs_hz is None:
        f = (np.geomspace(0.05, 0.4 / dt, 30) if bounds is None
             else dense_freqs(dt, bounds.bandwidth_hz))
        if bounds is not None:
            duration_s = max(duration_s, 80.0)
    else:
        f = np.asarray(freqs_hz, float)
    t = np.arange(0.0, duration_s, dt)
    w = 2 * np.pi * f
    lin = is_linear(method, params)
    if accel_amplitude is None and not lin:
        accel_amplitude = NONLINEAR_ACCEL_AMPLITUDE
    amp = (np.full(w.size, float(amplitude_m)) if accel_amplitude is None
           else np.minimum(float(amplitude_m), accel_amplitude / w**2))
    y = amp * np.sin(np.outer(t, w))
    _, a = any_differentiate(y, dt, method, **params)
    half = t >= duration_s / 2
    z = _fundamental(np.asarray(a)[half], t[half], w, amp)
    gain, phase = np.abs(z), np.degrees(np.angle(z))
    inside = np.abs(gain - 1.0) <= RESPONSE_TOL
    k = int(np.argmin(inside)) if not inside.all() else len(f)
    bw = float(f[k - 1]) if k > 0 else 0.0
    ph_bw = float(phase[k - 1]) if k > 0 else float("nan")
    if bounds is None:
        below = gain[:k] if k > 0 else gain[:1]
        above = gain[k:] if k < len(f) else np.array([0.0])
        gb, ga = float(below.max()), float(above.max())
        return FrequencyResponse(f, gain, phase, float(amplitude_m), bw, gb, ga, ph_bw,
                                 bool(gb <= GAIN_MAX_BELOW and ga <= GAIN_MAX_ABOVE), linear=lin,
                                 accel_amplitude=accel_amplitude)
    out = _checked(f, gain, phase, float(amplitude_m), bw, ph_bw, bounds, lin)
    return dataclasses.replace(out, accel_amplitude=accel_amplitude)


def _checked(f, gain, phase, amp, bw, ph_bw, b: ResponseBounds, lin) -> FrequencyResponse:
    """FrequencyResponse with the verification against the stated bounds ``b``."""
    below = f <= b.bandwidth_hz
    if not below.any():
        raise ValueError(f"the stated bandwidth {b.bandwidth_hz:g} Hz is below the lowest "
                         f"verified frequency {f[0]:g} Hz.")
    gerr = float(np.max(np.abs(gain[below] - 1.0)))
    phmax = float(np.max(np.abs(phase[below])))
    gb = float(np.max(gain[below]))
    ga = float(np.max(gain[~below])) if (~below).any() else 0.0
    k = int(np.argmax(gain))
    ph_b = float(np.interp(b.bandwidth_hz, f, phase))
    v = []
    if gerr > b.gain_tol:
        v.append(f"|gain - 1| reaches {gerr:.3g} below {b.bandwidth_hz:g} Hz "
                 f"(bound {b.gain_tol:g})")
    if phmax > b.phase_max_deg:
        v.append(f"|phase| reaches {phmax:.3g} deg below {b.bandwidth_hz:g} Hz "
                 f"(bound {b.phase_max_deg:g})")
    if gb > b.gain_max_below:
        v.append(f"gain {gb:.3g} below {b.bandwidth_hz:g} Hz (bound {b.gain_max_below:g})")
    if ga > b.gain_max_above:
        v.append(f"gain {ga:.3g} above {b.bandwidth_hz:g} Hz, peak at {f[k]:.3g} Hz "
                 f"(bound {b.gain_max_above:g})")
    return FrequencyResponse(f, gain, phase, amp, bw, gb, ga, ph_bw, not v, b, gerr, phmax,
                             float(gain[k]), float(f[k]), ph_b, tuple(v), lin)
