"""Training signals of the tuning: circles, Lissajous curves, trajectory families, a
dataset's own motion, noise realisations, and the evaluation of a differentiator on them."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdprid.base import InputError
from cdprid.signal import METHOD_INFO as HIGH_INFO
from cdprid.signal import METHODS, differentiate, differentiate_high


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
        """Samples whose errors count: ``t >= t[0] + t0``."""
        return self.t >= self.t[0] + self.t0


def circle_signal(radius=0.3, freq_hz=0.25, dt=0.01, duration=52.0, centre=(0.0, 0.0, 1.2),
                  phase=0.0) -> TrainingSignal:
    """Horizontal circle (the differentiator benchmark's default signal).

    Parameters
    ----------
    radius : float
        Radius, m.
    freq_hz : float
        Frequency, Hz.
    dt : float
        Sampling period, s.
    duration : float
        Length, s.
    centre : sequence of 3 floats
        Centre, m.
    phase : float
        Phase at t = 0, rad.

    Returns
    -------
    TrainingSignal
    """
    t = np.arange(int(round(duration / dt))) * dt
    w = 2 * math.pi * freq_hz
    c = np.asarray(centre, float)
    ph = w * t + phase
    pos = np.c_[c[0] + radius * np.cos(ph), c[1] + radius * np.sin(ph), c[2] + 0 * t]
    acc = np.c_[-radius * w**2 * np.cos(ph), -radius * w**2 * np.sin(ph), 0 * t]
    return TrainingSignal(t, dt, pos, acc, f"circle R {radius:g} m {freq_hz:g} Hz")


def lissajous_signal(ax=0.25, ay=0.2, az=0.1, f=(0.2, 0.4, 0.3), dt=0.01, duration=52.0,
                     centre=(0.0, 0.0, 1.2)) -> TrainingSignal:
    """3-D Lissajous curve (a test trajectory with several frequencies on every axis).

    Parameters
    ----------
    ax, ay, az : float
        Amplitudes per axis, m.
    f : sequence of 3 floats
        Frequencies per axis, Hz.
    dt : float
        Sampling period, s.
    duration : float
        Length, s.
    centre : sequence of 3 floats
        Centre, m.

    Returns
    -------
    TrainingSignal
    """
    t = np.arange(int(round(duration / dt))) * dt
    amps = np.array([ax, ay, az])
    w = 2 * math.pi * np.asarray(f)
    pos = np.asarray(centre)[None, :] + amps * np.sin(w * t[:, None] + np.array([0.0, 0.5, 1.0]))
    acc = -amps * w**2 * np.sin(w * t[:, None] + np.array([0.0, 0.5, 1.0]))
    return TrainingSignal(t, dt, pos, acc, "lissajous 0.2/0.4/0.3 Hz")


def noise_from_dataset(ds) -> float:
    """Position-noise std of a dataset, from robust 4th differences, averaged over axes.

    Parameters
    ----------
    ds : Dataset

    Returns
    -------
    float
        Noise std, m.

    Raises
    ------
    InputError
        No positive noise level could be estimated.
    """
    from cdprid.core import estimate_noise
    from cdprid.io import align

    sig = align(ds)
    s = np.asarray(estimate_noise(sig.position), float)
    v = float(np.sqrt(np.mean(s**2)))
    if not (math.isfinite(v) and v > 0):
        raise InputError("could not estimate a positive position noise from the dataset.")
    return v


def dataset_signal(ds, window_s: float = 1.5) -> TrainingSignal:
    """Training signal with the shape of a dataset's trajectory.

    The positions are smoothed by a Savitzky-Golay filter (``window_s``,
    polynomial order 5, zero phase) whose 0th and 2nd derivatives serve as
    the noise-free position and acceleration.

    Parameters
    ----------
    ds : Dataset
    window_s : float
        Filter window, s.

    Returns
    -------
    TrainingSignal
        Times from 0, s; position, m; acceleration, m/s^2.

    Raises
    ------
    InputError
        The dataset is too short to tune on.
    """
    from scipy.signal import savgol_filter

    from cdprid.io import align

    sig = align(ds)
    dt = float(sig.dt)
    w = int(round(window_s / dt)) | 1
    n = sig.position.shape[0]
    if n < max(w, 5 * int(round(2.0 / dt))):
        raise InputError(f"the dataset is too short to tune on ({n} pose samples).")
    kw = dict(window_length=w, polyorder=5, axis=0, mode="interp", delta=dt)
    pos = savgol_filter(sig.position, deriv=0, **kw)
    acc = savgol_filter(sig.position, deriv=2, **kw)
    return TrainingSignal(sig.t - sig.t[0], dt, pos, acc, "dataset (smoothed)")


def noise_realisations(n_samples: int, seeds, dims: int = 3) -> np.ndarray:
    """Standard normal noise; seed ``s`` always gives the same draw.

    Parameters
    ----------
    n_samples : int
    seeds : iterable of int
    dims : int

    Returns
    -------
    ndarray (len(seeds), n_samples, dims)
    """
    return np.stack([np.random.default_rng(int(s)).standard_normal((n_samples, dims))
                     for s in seeds])


def any_differentiate(y, dt, method, **params):
    """:func:`cdprid.differentiate`, or :func:`cdprid.signal.differentiate_high` (``sihd4``/5).

    Parameters
    ----------
    y : array (n,) or (n, k)
        Samples, e.g. positions in m.
    dt : float
        Sampling period, s.
    method : str
        A method of ``METHODS`` or ``METHOD_INFO``.
    **params
        The method's parameters.

    Returns
    -------
    velocity, acceleration : ndarray
        Shaped as ``y``, in y's unit per s and per s^2.

    Raises
    ------
    InputError
        Unknown ``method``.
    """
    if method in METHODS:
        return differentiate(y, dt, method, **params)
    if method in HIGH_INFO:
        return differentiate_high(y, dt, method, **params)
    raise InputError(
        f"unknown method {method!r}; use one of {', '.join([*METHODS, *HIGH_INFO])}."
    )


def evaluate(method, params, signal: TrainingSignal, noise_std: float, seeds) -> np.ndarray:
    """3-D acceleration RMSE over ``signal.mask`` for each seed (one batched call).

    Parameters
    ----------
    method : str
    params : dict
        The differentiator's parameters.
    signal : TrainingSignal
    noise_std : float
        Position-noise std, m.
    seeds : iterable of int
        Noise seeds (:func:`noise_realisations`).

    Returns
    -------
    ndarray (len(seeds),)
        RMSE, m/s^2.
    """
    seeds = list(seeds)
    nz = noise_realisations(signal.t.size, seeds)
    y = signal.position[None] + noise_std * nz  # (S, n, 3)
    Y = np.transpose(y, (1, 0, 2)).reshape(signal.t.size, -1)
    _, A = any_differentiate(Y, signal.dt, method, **params)
    A = A.reshape(signal.t.size, len(seeds), 3)
    err = (A - signal.acceleration[:, None, :])[signal.mask]
    return np.sqrt(np.mean(np.sum(err**2, axis=2), axis=0))


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
    from cdprid.model import Orbit, orbit_sequence

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
        raise InputError(f"unknown family {which!r}; use train or heldout.")
    if not duration >= 5.0:
        raise InputError(f"family members must last at least 5 s, got {duration!r}.")
    rows = TRAIN_FAMILY if which == "train" else HELDOUT_FAMILY
    out = [_orbit_member(*row, dt, duration) for row in rows]
    if which == "heldout":
        from cdprid.model import Orbit, orbit_sequence

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
