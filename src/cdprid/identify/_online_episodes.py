"""Episodes as they happen: a causal detector in the online scan's carry.

At each used sample the **innovation** ``e_k = y_k - A_k x_{k-1}`` (the wrench equation's
prediction error against the estimate before the sample, N and N m) goes through a short
exponential mean ``m_k`` (time constant ``short_s``). Its covariance ``U`` is tracked on clean
samples only (exponential, time constant ``noise_s``), so the statistic
``T_k = m_k^T U^-1 m_k`` is whitened by the recording's own noise, filter correlation
included (``U`` is the covariance of ``m`` itself, not of ``e``). ``T`` is compared with a
Hotelling threshold for 6 channels set for ``far_per_hour`` false alarms per hour of clean
data (Bonferroni over ``1 / short_s`` looks per second; ``U`` estimated from
``noise_s / max(short_s, 0.3 s)`` independent means).

- **Alarm** (``T`` above the threshold, detector armed after ``arm_s`` s of clean data): an
  episode starts at the last sample where ``T`` was below its onset level (the 90 %
  quantile of chi-squared with 6 degrees of freedom), and the least squares are rolled back
  to their state there (``freeze``): the rows of the episode, onset included, never enter.
- **During it** the update is frozen; a side least squares (memory ``side_s``) fits the
  episode's rows alone.
- **End**: ``T`` below the onset level for ``hold_s`` s; ``end_s`` is the first of those
  samples. Kind ``external_wrench``.
- **Step**: an episode lasting ``max_episode_s`` whose rows the side fit explains (its
  residual rms within ``step_ratio`` times the clean residual rms before the episode) is a
  change of the payload: the least squares restart from the side fit (its information only),
  so the new payload is tracked, and a ``payload_step`` is reported. A long discrepancy the
  parameters do not explain stays an open ``external_wrench`` (frozen).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import chi2_isf, f_isf
from cdprid.effects import EXTERNAL_WRENCH
from cdprid.episodes import FAR_PER_HOUR, Episode
from cdprid.identify._online_step import _online_step
from cdprid.identify._online_types import OnlineOutput
from cdprid.identify._rls import _rls_init, _rls_solution, _rls_update

__all__ = ["DetectorSettings", "detector_settings", "online_episodes", "_detect_scan"]


class DetectorSettings(NamedTuple):
    """Constants of the online episode detector (plain floats; see the module docstring)."""

    a_short: float    # per-sample decay of the short mean
    a_noise: float    # per-sample decay of the noise covariance
    level: float      # alarm threshold of T
    onset: float      # onset / quiet level of T
    arm: float        # clean weight needed before alarms (samples)
    hold: int         # quiet samples that end an episode
    max_len: int      # samples after which a consistent episode is a payload step
    lam_side: float   # forgetting of the side fit
    step_ratio: float
    clip: float       # Huber level of T in the noise covariance
    prior_weight: float
    freeze: bool


def detector_settings(dt: float, far_per_hour: float = FAR_PER_HOUR, short_s: float = 0.1,
                      noise_s: float = 20.0, arm_s: float = 3.0, hold_s: float = 0.3,
                      max_episode_s: float = 3.0, side_s: float = 1.0, step_ratio: float = 3.0,
                      prior_weight: float = 1e-9, freeze: bool = True) -> DetectorSettings:
    """Settings of the online detector.

    Parameters
    ----------
    dt : float
        Sampling period, s.
    far_per_hour : float
        Stated false-alarm rate per hour of clean recording.
    short_s, noise_s : float
        Time constants of the short innovation mean and of its covariance, s.
    arm_s : float
        Seconds of clean rows before the first alarm is possible, s.
    hold_s : float
        Quiet seconds that end an episode, s.
    max_episode_s : float
        Longest episode, s; beyond it, a discrepancy the parameters explain is a payload step.
    side_s : float
        Memory of the side fit of the episode's rows, s.
    step_ratio : float
        Largest side-fit residual rms, in clean residual rms, of a payload step.
    prior_weight : float
        Prior weight of the side fit (its prior mean is the estimate before the episode).
    freeze : bool
        Freeze (and roll back) the update during episodes and restart it at a step; False
        only reports them.

    Returns
    -------
    DetectorSettings
    """
    looks = 3600.0 / short_s  # looks per hour
    nu = max(noise_s / max(short_s, 0.3), 8.0)  # independent means behind U
    p = 6
    f = f_isf(far_per_hour / looks, p, nu - p + 1)
    level = float(nu * p / (nu - p + 1) * f)
    return DetectorSettings(
        math.exp(-dt / short_s), math.exp(-dt / noise_s), level, float(chi2_isf(0.1, p)),
        arm_s / dt, max(int(round(hold_s / dt)), 1), max(int(round(max_episode_s / dt)), 1),
        1.0 - dt / side_s, float(step_ratio), float(chi2_isf(0.01, p)),
        float(prior_weight), bool(freeze))


class DetectState(NamedTuple):
    """Carry of the detector (see the module docstring)."""

    m: jnp.ndarray          # (6,) short mean of the innovation
    U: jnp.ndarray          # (6, 6) its covariance on clean samples (uncorrected EWMA)
    w: jnp.ndarray          # () EWMA weight of U (bias correction)
    n_clean: jnp.ndarray    # () clean rows seen
    in_ep: jnp.ndarray      # () bool
    start: jnp.ndarray      # () int, first sample of the current episode
    quiet: jnp.ndarray      # () int, last sample with T below the onset level
    hold: jnp.ndarray       # () int, quiet samples in a row during the episode
    S_snap: jnp.ndarray     # factor at the last quiet sample
    n_snap: jnp.ndarray
    S_side: jnp.ndarray     # side fit of the episode's rows
    n_side: jnp.ndarray


class DetectOutput(NamedTuple):
    """Per-sample detector output: the innovation (6,), ``T``, whether in an episode, and an
    event code (0 none, 1 an episode ended, 2 a payload step declared) with its start/end."""

    innovation: jnp.ndarray
    stat: jnp.ndarray
    in_episode: jnp.ndarray
    event: jnp.ndarray
    event_start: jnp.ndarray
    event_end: jnp.ndarray


def _detect_init(S, dtype) -> DetectState:
    z6, z = jnp.zeros(6, dtype), jnp.zeros((), dtype)
    i0 = jnp.zeros((), jnp.int64 if jax.config.read("jax_enable_x64") else jnp.int32)
    return DetectState(z6, jnp.zeros((6, 6), dtype), z, z, jnp.zeros((), bool), i0, i0, i0,
                       S, z, S, z)


def _statistic(det: DetectState, e, use, s: DetectorSettings):
    m = jnp.where(use, s.a_short * det.m + (1.0 - s.a_short) * e, det.m)
    U = det.U / jnp.maximum(det.w, 1e-300)
    eps = 1e-12 * jnp.trace(U) / 6.0 + 1e-300
    T = m @ jnp.linalg.solve(U + eps * jnp.eye(6, dtype=U.dtype), m)
    armed = use & (det.n_clean >= s.arm)
    return m, jnp.where(armed, T, 0.0), armed


def _detect_update(det: DetectState, st_S, st_n, new_S, new_n, A, y, k, use, s):
    """One sample of the detector: the factor to keep, the new detector state, its output."""
    p = new_S.shape[0] - 1
    x_prev = _rls_solution(st_S, st_n)[0]
    e = y - A @ x_prev
    m, T, armed = _statistic(det, e, use, s)
    alarm = armed & ~det.in_ep & (T > s.level)
    quiet_now = T < s.onset
    in_ep = det.in_ep | alarm
    clean = use & ~in_ep
    a = s.a_noise
    # robust: once armed, a mean beyond the clip level enters U at that level (Huber), so
    # that a transient the alarm misses does not inflate the noise
    mc = m * jnp.where(armed, jnp.minimum(1.0, jnp.sqrt(s.clip / jnp.maximum(T, 1e-300))), 1.0)
    U = jnp.where(clean, a * det.U + (1 - a) * jnp.outer(mc, mc), det.U)
    w = jnp.where(clean, a * det.w + (1 - a), det.w)
    n_clean = det.n_clean + jnp.where(clean, 1.0, 0.0)
    start = jnp.where(alarm, det.quiet + 1, det.start)
    hold = jnp.where(in_ep & quiet_now & ~alarm, det.hold + 1, 0)
    # side fit: from the alarm on, the episode's rows alone
    x_snap = _rls_solution(det.S_snap, det.n_snap)[0]
    S0 = _rls_init(x_snap, s.prior_weight)
    S_side = jnp.where(alarm, S0, det.S_side)
    n_side = jnp.where(alarm, 0.0, det.n_side)
    S_side, n_side = _rls_update(S_side, n_side, A, y, s.lam_side, in_ep & use)
    ended = in_ep & (hold >= s.hold)
    side_rms2 = S_side[p, p] ** 2 / jnp.maximum(n_side - p, 1.0)
    snap_rms2 = det.S_snap[p, p] ** 2 / jnp.maximum(det.n_snap - p, 1.0)
    long = in_ep & ~ended & (k - start >= s.max_len)
    step = long & (side_rms2 <= s.step_ratio ** 2 * snap_rms2)
    # the factor kept: frozen in the episode, rolled back at the alarm, the side fit at a step
    if s.freeze:
        S = jnp.where(alarm, det.S_snap, jnp.where(in_ep, st_S, new_S))
        n = jnp.where(alarm, det.n_snap, jnp.where(in_ep, st_n, new_n))
        S, n = jnp.where(step, S_side, S), jnp.where(step, n_side, n)
    else:
        S, n = new_S, new_n
    in_ep_next = in_ep & ~ended & ~step
    quiet = jnp.where(quiet_now & ~in_ep_next, k, det.quiet)
    snap = quiet_now & ~in_ep_next
    m = jnp.where(step, 0.0, m)
    new = DetectState(m, U, w, n_clean, in_ep_next, start, quiet, jnp.where(ended, 0, hold),
                      jnp.where(snap, S, det.S_snap), jnp.where(snap, n, det.n_snap),
                      S_side, n_side)
    event = jnp.where(step, 2, jnp.where(ended, 1, 0))
    out = DetectOutput(e, T, in_ep, event, start, jnp.where(ended, k - hold + 1, k))
    return S, n, new, out


def _detect_scan(state, samples, settings: DetectorSettings):
    """:func:`_online_step` over a record with the detector in the carry (one ``lax.scan``)."""

    def body(carry, smp):
        st, det = carry
        new, out = _online_step(st, smp)
        S, n, det, dout = _detect_update(det, st.S, st.n_rows, new.S, new.n_rows, out.A,
                                         out.y, st.k, out.used, settings)
        new = eqx.tree_at(lambda s: (s.S, s.n_rows), new, (S, n))
        x, sigma, srho = _rls_solution(S, n)
        frozen = dout.in_episode | (dout.event == 2)
        out = out._replace(x=x, sigma=sigma, sigma_rho=srho,
                           used=out.used & ~(frozen if settings.freeze else False))
        return (new, det), (out, dout)

    det0 = _detect_init(state.S, state.config.dt.dtype)
    return jax.lax.scan(body, (state, det0), samples)


_detect_scan_jit = jax.jit(_detect_scan, static_argnums=2)


def online_episodes(t, x, names, dout: DetectOutput, lag: int = 0) -> list[Episode]:
    """The events of the detector's output as :class:`cdprid.episodes.Episode` (numpy).

    Parameters
    ----------
    t : (n,)
        Sample times, s.
    x : (n, p)
        Parameter trajectory (the mass first).
    names : tuple of str
    dout : DetectOutput of numpy arrays
    lag : int
        Delay of the short mean (``short_s / dt`` samples: an exponential mean's delay),
        taken off the start and end the statistic gives.

    Returns
    -------
    list of Episode
        ``external_wrench`` (mean wrench on the platform: minus the mean innovation) and
        ``payload_step``; both with ``impulse_Ns`` (minus the innovation's force integrated
        over the episode: the matched filter keeps integrals) and the step also with
        ``mass_before_kg``, ``mass_after_kg``, ``mass_change_kg``: the
        estimate before the episode and at the restart); ``p_value`` is None (a sequential
        test's threshold, not a p-value). An episode still open at the end has ``open: True``.
    """
    ev = np.asarray(dout.event)
    marks = [(int(dout.event_start[k]), int(dout.event_end[k]), int(ev[k]))
             for k in np.flatnonzero(ev)]
    if bool(dout.in_episode[-1]) and ev[-1] == 0:
        marks.append((int(dout.event_start[-1]), len(t) - 1, 0))
    out = []
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    for a0, b0, code in marks:
        a0 = max(a0, 0)
        a, b = max(a0 - lag, 0), max(b0 - (lag if code == 1 else 0), a0)
        inn = np.asarray(dout.innovation[a0:b0 + 1])
        e = inn.mean(axis=0)
        f, mo = tuple(float(v) for v in -e[:3]), tuple(float(v) for v in -e[3:])
        detail = {"impulse_Ns": [float(v) for v in -inn[:, :3].sum(axis=0) * dt]}
        kind = "payload_step" if code == 2 else EXTERNAL_WRENCH
        if code == 2 and names and names[0] == "m":
            m0, m1 = float(x[max(a - 1, 0), 0]), float(x[b, 0])
            detail.update(mass_before_kg=m0, mass_after_kg=m1, mass_change_kg=m1 - m0)
        if code == 0:
            detail["open"] = True
        out.append(Episode(float(t[a]), float(t[b]), kind, f, mo, float(np.linalg.norm(f)),
                           float(np.linalg.norm(mo)), None, detail))
    return out


def episode_rows(dout: DetectOutput) -> np.ndarray:
    """The samples of the episodes: the rows a frozen update left out.

    Parameters
    ----------
    dout : DetectOutput of numpy arrays

    Returns
    -------
    ndarray (n,) of bool
        From each alarm's (rolled-back) start to its end or step.
    """
    n = len(dout.event)
    diff = np.zeros(n + 1, int)
    ev = np.asarray(dout.event)
    ends = [(int(dout.event_start[k]), k) for k in np.flatnonzero(ev)]
    if bool(dout.in_episode[-1]) and ev[-1] == 0:
        ends.append((int(dout.event_start[-1]), n - 1))
    for a, b in ends:
        diff[max(a, 0)] += 1
        diff[b + 1] -= 1
    return np.cumsum(diff[:n]) > 0


def run_detect_scan(st0, samples, settings: DetectorSettings):
    """The online scan with the detector (jitted :func:`_detect_scan`).

    Parameters
    ----------
    st0 : OnlineState
    samples : OnlineSample
        Stacked samples (n, ...).
    settings : DetectorSettings

    Returns
    -------
    state : OnlineState
        Final state.
    out : OnlineOutput
        Per-sample outputs (numpy), ``x``/``sigma`` those of the factor kept.
    dout : DetectOutput
        Per-sample detector outputs (numpy).
    """
    (st, _), (out, dout) = _detect_scan_jit(st0, samples, settings)
    o = OnlineOutput(*(np.asarray(v) for v in out))
    d = DetectOutput(*(np.asarray(v) for v in dout))
    return st, o, d
