"""Identification on real recordings: dynamic parameters jointly with sensor nuisances.

A real recording differs from the paper's model in ways a simulation does not: load cells
carry offsets (and possibly gains), the tension log and the motion capture are not exactly
aligned in time, cables go slack, the pulleys move the exit points and the platform rotates.
This module prepares a recording (motion by :func:`cdprid.core.estimate_motion`, ``W`` by
:func:`cdprid.core.wrench_matrices`, regressors by :func:`cdprid.core.regressors`)
and fits the linear dynamic parameters ``x`` (translation model ``[m, mxG, myG, mzG]`` or the
full 10-parameter model) jointly with

- ``offset`` (m,): load-cell offsets ``o_i``, N (``tau_true = k_i (tau_meas - o_i)``);
- ``gain`` (m,): relative load-cell gains ``k_i`` with ``sum(k_i) = m`` (a common gain of all
  cells cannot be told apart from the mass: only ratios are identified);
- ``delay``: ``tau_true(t) = tau_meas(t + delay)`` s (delay > 0: the tension log lags the
  pose);

through the ONE nuisance pipeline :mod:`cdprid.core._nuisance` (taut and rest masks, tension
interpolation, optimistix Levenberg-Marquardt with the status checked, HAC covariance from
:mod:`cdprid.core._covariance`), on ``F(W(pose) tau_true) = A(pose, a, omega, alpha) x`` with
``F`` the zero-phase low-pass through which the accelerations were obtained (matched
filtering). Rows are used only in TAUT phases (:func:`cdprid.core.taut_mask`): when a
cable goes slack and snaps taut the force has content far above the filter's band that no
rigid-body model explains.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from cdprid.base import CUTOFF_HZ, FILTER_ORDER, TAUT_THRESHOLD_N, TRIM_S, InputError
from cdprid.core import (
    INTERPOLATION,
    SMOOTH_HZ,
    InsufficientDataError,
    NuisanceSpec,
    TensionStream,
    estimate_motion,
    fit_nuisance,
    mask_windows,
    regressors,
    rest_mask,
    tension_at,
    wrench_matrices,
)
from cdprid.core import taut_mask as _stream_taut_mask
from cdprid.io import Dataset, align
from cdprid.model import PARAMETER_NAMES, CableRobot
from cdprid.signal import make_zero_phase_filter

__all__ = ["ExtensionStep", "RealData", "RealResult", "ResidualRms", "RestWeight",
           "prepare_real", "taut_mask", "weight_at_rest", "rest_windows", "identify_real",
           "compare_extensions", "jax_zero_phase_filter", "nuisance_summary"]


# --------------------------------------------------------------------------- matched filter


def jax_zero_phase_filter(x, dt: float, cutoff_hz: float = CUTOFF_HZ, order: int = FILTER_ORDER):
    """JAX twin of :func:`cdprid.signal.zero_phase_filter` (differentiable).

    Parameters
    ----------
    x : array (n, k)
    dt : float
    cutoff_hz : float
    order : int

    Returns
    -------
    array (n, k)
        Thin wrapper of :class:`cdprid.signal.ZeroPhaseFilter`.
    """
    return make_zero_phase_filter(float(dt), cutoff_hz, order)(x)


# --------------------------------------------------------------------------- data


@dataclasses.dataclass(frozen=True)
class RealData:
    """Pose-side quantities on the pose time base and the raw tension stream.

    Attributes
    ----------
    robot : CableRobot
    t, dt : pose time base
    p, R, v, a, omega, alpha : position, rotation, velocity, acceleration, angular rates
        (base frame), from :func:`cdprid.core.estimate_motion` (``euler-filtfilt``)
    W : ndarray (n, 6, m)
        Wrench matrices at the measured poses (pulleys as in ``robot``).
    tension_t, tension : raw tension stream (1 kHz)
    cutoff_hz : float
    """

    robot: CableRobot
    t: np.ndarray
    dt: float
    p: np.ndarray
    R: np.ndarray
    v: np.ndarray
    a: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    W: np.ndarray
    tension_t: np.ndarray
    tension: np.ndarray
    cutoff_hz: float

    def with_robot(self, robot: CableRobot) -> RealData:
        """The same data with the wrench matrices of another geometry (e.g. no pulleys).

        Parameters
        ----------
        robot : CableRobot

        Returns
        -------
        RealData
        """
        W = np.asarray(wrench_matrices(robot, jnp.asarray(self.p), jnp.asarray(self.R)))
        return dataclasses.replace(self, robot=robot, W=W)

    @property
    def stream(self) -> TensionStream:
        """The raw tension stream for :func:`cdprid.core.tension_at`."""
        return TensionStream.from_arrays(self.tension_t, self.tension)

    def tension_at(self, t, offset=None) -> np.ndarray:
        """Raw tensions, N, linearly interpolated at times ``t`` (minus ``offset``).

        Parameters
        ----------
        t : array (n,)
            Times, s.
        offset : array (m,), optional
            Per-cable offsets, N.

        Returns
        -------
        ndarray (n, m)
        """
        tau = np.asarray(tension_at(self.stream, jnp.asarray(t), "linear"))
        return tau if offset is None else tau - np.asarray(offset)[None, :]


def prepare_real(ds: Dataset, cutoff_hz: float = CUTOFF_HZ,
                 robot: CableRobot | None = None) -> RealData:
    """Align, differentiate (``euler-filtfilt`` at ``cutoff_hz``) and build W along the pose.

    Parameters
    ----------
    ds : Dataset
    cutoff_hz : float
        Cut-off of the differentiator's zero-phase low-pass (and of the matched filter).
    robot : CableRobot, optional
        Geometry for ``W`` (default: the dataset's).

    Returns
    -------
    RealData
    """
    sig = align(ds)
    robot = ds.robot if robot is None else robot
    mo = estimate_motion(sig, "euler-filtfilt", {"cutoff_hz": cutoff_hz})
    W = np.asarray(wrench_matrices(robot, jnp.asarray(mo.position), jnp.asarray(mo.B_R_P)))
    return RealData(robot, sig.t, sig.dt, mo.position, mo.B_R_P, mo.velocity, mo.acceleration,
                    mo.omega, mo.alpha, W, np.asarray(ds.tension_t), np.asarray(ds.tension),
                    cutoff_hz)


def taut_mask(data: RealData, threshold_N: float = TAUT_THRESHOLD_N, window_s: float = 0.1,
              offset=None) -> np.ndarray:
    """Pose samples where every cable stays taut (:func:`cdprid.core.taut_mask`).

    Parameters
    ----------
    data : RealData
    threshold_N, window_s : float
    offset : ndarray (m,), optional

    Returns
    -------
    ndarray (n,) of bool
    """
    return _stream_taut_mask(data.t, data.tension_t, data.tension, threshold_N, window_s, offset)


def rest_windows(data: RealData, min_duration_s: float | None = None) -> list[tuple[float, float]]:
    """Time windows where the platform is at rest (:func:`cdprid.core.rest_mask`).

    Parameters
    ----------
    data : RealData
    min_duration_s : float, optional
        Shortest window (default :data:`cdprid.core.REST_MIN_DURATION_S`).

    Returns
    -------
    list of (t_first, t_last)
    """
    kw = {} if min_duration_s is None else {"min_duration_s": min_duration_s}
    return mask_windows(data.t, rest_mask(data.t, np.linalg.norm(data.v, axis=1), **kw))


@dataclasses.dataclass(frozen=True)
class RestWeight:
    """The mass measured as the weight at rest (:func:`weight_at_rest`).

    Attributes
    ----------
    mass : float
        kg: the mean over every rest sample.
    std : float
        kg: the spread of the per-window means / sqrt(number of windows), or over the samples
        with one window (a rough figure).
    n : int
        Rest samples used.
    windows : list of (t_first, t_last)
        The rest windows, s.
    per_window : list of float
        Mean mass per window that had samples, kg.
    """

    mass: float
    std: float
    n: int
    windows: list
    per_window: list


def weight_at_rest(data: RealData, offset=None, gain=None, windows=None) -> RestWeight:
    """Mass from the weight measured at rest: ``-g . sum_i k_i (tau_i - o_i) u_i / |g|^2``.

    Parameters
    ----------
    data : RealData
    offset, gain : ndarray (m,), optional
        Load-cell offsets and relative gains applied to the raw tensions.
    windows : list of (t0, t1), optional
        Default :func:`rest_windows`.

    Returns
    -------
    RestWeight
        ``mass``, ``std`` (kg), ``n``, ``windows``, ``per_window``.

    Raises
    ------
    ValueError
        No rest window.
    """
    windows = rest_windows(data) if windows is None else windows
    if not windows:
        raise InputError("no rest window found (the platform never stays still for 0.5 s).")
    g = np.asarray(data.robot.gravity)
    k = np.ones(data.W.shape[2]) if gain is None else np.asarray(gain)
    per, allm = [], []
    for lo, hi in windows:
        sel = (data.t >= lo) & (data.t <= hi) & (data.t >= data.tension_t[0]) \
            & (data.t <= data.tension_t[-1])
        if not sel.any():
            continue
        tau = data.tension_at(data.t[sel], offset) * k[None, :]
        f = np.einsum("nij,nj->ni", data.W[sel, :3, :], tau)
        mm = -(f @ g) / (g @ g)
        per.append(float(mm.mean()))
        allm.append(mm)
    allm = np.concatenate(allm)
    std = float(np.std(per) / math.sqrt(len(per))) if len(per) > 1 else float(allm.std())
    return RestWeight(mass=float(allm.mean()), std=std, n=int(allm.size), windows=windows,
                      per_window=per)


# --------------------------------------------------------------------------- identification


@dataclasses.dataclass(frozen=True)
class ResidualRms:
    """Root mean square of a force/moment residual over a set of samples (NaN when empty).

    Attributes
    ----------
    force_N : float
        Over the three force components, N.
    moment_Nm : float
        Over the three moment components, N m.
    """

    force_N: float
    moment_Nm: float


@dataclasses.dataclass(frozen=True)
class RealResult:
    """Joint estimate of the dynamic parameters and the nuisances.

    Attributes
    ----------
    model : "translation" or "full"
    names : tuple of parameter names (dynamic first, then nuisances)
    values, std : dict name -> float (std: HAC, :mod:`cdprid.core._covariance`)
    x : ndarray, the dynamic parameter vector
    offset, gain : ndarray (m,)
    delay : float, s
    train_rms, heldout_rms : ResidualRms (taut samples only)
    n_train, n_test : int
    bandwidth : float
        Bartlett bandwidth of the HAC covariance, samples.
    residual : ndarray (n, 6), measured minus model at every pose sample
    measured, predicted : ndarray (n, 6), filtered cable wrench and model wrench
    train, test : boolean masks (taut and in the window)
    options : dict
    """

    model: str
    names: tuple
    values: dict
    std: dict
    x: np.ndarray
    offset: np.ndarray
    gain: np.ndarray
    delay: float
    train_rms: ResidualRms
    heldout_rms: ResidualRms
    n_train: int
    n_test: int
    bandwidth: float
    residual: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    train: np.ndarray
    test: np.ndarray
    options: dict

    def summary(self) -> dict:
        """Plain-Python summary (JSON / TOML).

        Returns
        -------
        dict
            ``model``, ``parameters`` (``{name: {"value", "std"}}``), ``train_rms`` and
            ``heldout_rms`` (``{"force_N", "moment_Nm"}``), ``n_train``, ``n_test``,
            ``hac_bandwidth`` (samples), ``options``.
        """
        return {
            "model": self.model,
            "parameters": {n: {"value": self.values[n], "std": self.std[n]} for n in self.names},
            "train_rms": dataclasses.asdict(self.train_rms),
            "heldout_rms": dataclasses.asdict(self.heldout_rms),
            "n_train": self.n_train, "n_test": self.n_test, "hac_bandwidth": self.bandwidth,
            "options": self.options,
        }


def _rms(e: np.ndarray, mask: np.ndarray) -> ResidualRms:
    if not mask.any():
        return ResidualRms(float("nan"), float("nan"))
    return ResidualRms(force_N=float(np.sqrt(np.mean(e[mask][:, :3] ** 2))),
                       moment_Nm=float(np.sqrt(np.mean(e[mask][:, 3:] ** 2))))


def _named(names_x, fit, spec: NuisanceSpec) -> tuple[list, dict, dict]:
    names, values, std = list(names_x), {}, {}
    for j, nm in enumerate(names_x):
        values[nm], std[nm] = float(fit.x[j]), float(fit.x_std[j])
    m = len(fit.offset)
    for key, on, val, sd in (("offset", spec.offsets, fit.offset, fit.offset_std),
                             ("gain", spec.gains, fit.gain, fit.gain_std)):
        if on:
            for j in range(m):
                nm = f"{key}_{j + 1}"
                names.append(nm)
                values[nm], std[nm] = float(val[j]), float(sd[j])
    names.append("delay")
    values["delay"], std["delay"] = fit.delay, fit.delay_std
    return names, values, std


def _train_test_masks(data: RealData, train_until: float, test_until: float | None,
                      taut_threshold_N: float, trim: float) -> tuple[np.ndarray, np.ndarray]:
    """Taut samples inside both streams (``trim`` s off each end), before ``train_until``
    (training) and in ``[train_until, test_until)`` (held out); raises
    :class:`InsufficientDataError` under 100 training samples."""
    t = data.t
    end = t[-1] if test_until is None else test_until
    usable = ((t >= max(t[0], data.tension_t[0]) + trim)
              & (t <= min(t[-1], data.tension_t[-1]) - trim) & taut_mask(data, taut_threshold_N))
    train = usable & (t < train_until)
    test = usable & (t >= train_until) & (t < end)
    if train.sum() < 100:
        raise InsufficientDataError(f"only {int(train.sum())} taut training samples before "
                         f"t = {train_until:g} s; lower taut_threshold_N or move train_until.")
    return train, test


def identify_real(
    data: RealData | Dataset,
    model: str = "translation",
    train_until: float = 25.0,
    test_until: float | None = None,
    taut_threshold_N: float = TAUT_THRESHOLD_N,
    offsets: bool | str = True,
    gains: bool = False,
    delay: bool = True,
    delay0: float = 0.0,
    trim: float = TRIM_S,
    max_steps: int = 200,
    interpolation: str = INTERPOLATION,
    smooth_hz: float | None = SMOOTH_HZ,
) -> RealResult:
    """Joint nonlinear LS of the dynamic parameters and the nuisances (module docstring).

    Parameters
    ----------
    data : RealData (from :func:`prepare_real`) or Dataset
    model : "translation" (paper, eq. 10) or "full" (10 parameters)
    train_until : fit on taut samples with t < train_until
    test_until : held-out window is [train_until, test_until) (default: to the end)
    taut_threshold_N : every raw tension above this (:func:`cdprid.core.taut_mask`)
    offsets, gains, delay : which nuisances to estimate (otherwise 0, 1, ``delay0``);
        ``offsets="zero_sum"`` estimates offsets with ``sum(o) = 0``: a common offset of all
        cells adds a nearly constant, nearly vertical force that the data cannot tell apart
        from the weight ``m g`` (accelerations are small next to g), so free offsets make
        the mass unidentifiable (the free fit is kept for comparison).
    delay0 : float
        Starting (or fixed) delay, s.
    trim : seconds dropped at both ends of the recording
    max_steps : Levenberg-Marquardt steps per pass
    interpolation : {"linear", "catmull-rom"}
        Interpolant of the tension stream (:data:`cdprid.core.INTERPOLATION`).
    smooth_hz : float or None
        Low-pass of the tension stream before interpolation
        (:data:`cdprid.core._nuisance.SMOOTH_HZ`;
        None: raw).

    Returns
    -------
    RealResult

    Raises
    ------
    cdprid.core._nuisance.InsufficientDataError
        Too few taut training samples.
    cdprid.base._errors.ConvergenceError
        The Levenberg-Marquardt solver did not converge.
    """
    if not isinstance(data, RealData):
        data = prepare_real(data)
    spec = NuisanceSpec(offsets=offsets, gains=gains, delay=delay, delay0=delay0,
                        interpolation=interpolation, smooth_hz=smooth_hz)
    t = data.t
    train, test = _train_test_masks(data, train_until, test_until, taut_threshold_N, trim)
    A = np.asarray(regressors(model, jnp.asarray(data.R), jnp.asarray(data.a),
                              jnp.asarray(data.omega), jnp.asarray(data.alpha),
                              jnp.asarray(data.robot.gravity)))
    filt = make_zero_phase_filter(float(data.dt), data.cutoff_hz, FILTER_ORDER)
    fit = fit_nuisance(data.W, A, data.stream, t, train, filt, spec, max_steps)
    names, values, std = _named(PARAMETER_NAMES[model], fit, spec)
    e = fit.residual
    return RealResult(
        model=model, names=tuple(names), values=values, std=std, x=fit.x, offset=fit.offset,
        gain=fit.gain, delay=fit.delay, train_rms=_rms(e, train), heldout_rms=_rms(e, test),
        n_train=int(train.sum()), n_test=int(test.sum()), bandwidth=fit.bandwidth, residual=e,
        measured=fit.measured, predicted=fit.measured - e, train=train, test=test,
        options={"train_until": train_until, "test_until": test_until,
                 "taut_threshold_N": taut_threshold_N, "offsets": offsets, "gains": gains,
                 "delay": delay, "pulleys": bool(data.robot.has_pulleys),
                 "cutoff_hz": data.cutoff_hz, "interpolation": interpolation,
                 "smooth_hz": smooth_hz},
    )


@dataclasses.dataclass(frozen=True)
class ExtensionStep:
    """One step of :func:`compare_extensions`.

    Attributes
    ----------
    step : str
        What the step adds (``"+ time delay"``; the final one's label contains ``final``).
    result : RealResult
        Its joint fit (held-out residuals in ``result.heldout_rms``).
    """

    step: str
    result: RealResult


def compare_extensions(data: RealData, train_until: float = 25.0, test_until: float | None = None,
                       taut_threshold_N: float = TAUT_THRESHOLD_N, steps=None,
                       **kw) -> list[ExtensionStep]:
    """The paper's model, then one extension added at a time (cumulative), with the held-out
    taut residuals of each step.

    Default steps: fixed exit points (pulleys removed), translation model -> + pulleys (moving
    exit points) -> + time delay -> + rotational dynamics (full model) -> + relative load-cell
    gains (final) ; and, as alternatives to the final step, zero-sum offsets and free offsets.
    Every step uses the same taut mask (raw tensions), so held-out figures are comparable.

    Parameters
    ----------
    data : RealData
        The prepared recording (:func:`prepare_real`).
    train_until, test_until : float
        End of the training window and of the held-out window, s (None: the end).
    taut_threshold_N : float
        A sample is used when every cable carries more than this, N.
    steps : list of (label, geometry, options), optional
        ``geometry`` ``"np"`` (pulleys removed) or ``"p"``; ``options`` of
        :func:`identify_real`. Default: the steps above.
    **kw
        Further options of :func:`identify_real`, common to every step.

    Returns
    -------
    list of ExtensionStep
        One per step, in order.
    """
    no_pulley = data.with_robot(data.robot.replace(pulley_radius=np.zeros(data.W.shape[2])))
    common = dict(train_until=train_until, test_until=test_until,
                  taut_threshold_N=taut_threshold_N, **kw)
    if steps is None:
        steps = [
            ("paper: translation, fixed exits", "np", dict(model="translation", offsets=False,
                                                           delay=False)),
            ("+ pulleys (moving exit points)", "p", dict(model="translation", offsets=False,
                                                         delay=False)),
            ("+ time delay", "p", dict(model="translation", offsets=False, delay=True)),
            ("+ rotational dynamics (full model)", "p", dict(model="full", offsets=False,
                                                             delay=True)),
            ("+ relative gains (final)", "p", dict(model="full", offsets=False, delay=True,
                                                   gains=True)),
            ("alt: full + delay + zero-sum offsets", "p", dict(model="full", offsets="zero_sum",
                                                              delay=True)),
            ("alt: full + delay + free offsets", "p", dict(model="full", offsets=True,
                                                          delay=True)),
        ]
    out = []
    for label, geo, opt in steps:
        r = identify_real(no_pulley if geo == "np" else data, **opt, **common)
        out.append(ExtensionStep(step=label, result=r))
    return out


def nuisance_summary(data: RealData) -> dict:
    """Load-cell offsets and time delay from the dynamics over the whole recording.

    The meta.toml ``[nuisance]`` table of ``cdprid import uacdpr``: :func:`identify_real`
    (full model, free offsets, delay, taut phases) on every usable sample, plus the weight
    at rest when the platform is ever at rest.

    Parameters
    ----------
    data : RealData

    Returns
    -------
    dict
        The table as written to meta.toml (a serialisation, hence plain): ``note``,
        ``offset_N``, ``offset_std_N``, ``delay_s``, ``delay_std_s``,
        ``mass_from_motion_kg``, ``mass_from_motion_std_kg``, ``force_residual_rms_N``,
        ``n_taut_samples``, and ``mass_at_rest_kg`` / ``rest_windows_s`` when at rest.
    """
    r = identify_real(data, model="full", train_until=float(data.t[-1]) + 1.0, offsets=True,
                      delay=True, gains=False)
    out = {
        "note": ("estimated by cdprid.identify.identify_real (cdprid.core._nuisance pipeline: full "
                 f"model, offsets + delay, taut phases, every cable > {TAUT_THRESHOLD_N:g} N) "
                 "over the whole recording; tensions.csv is NOT corrected. Model: "
                 "tau_true(t) = tau_meas(t + delay) - offset. std: HAC (Newey-West)"),
        "offset_N": r.offset.tolist(),
        "offset_std_N": [r.std[f"offset_{i + 1}"] for i in range(len(r.offset))],
        "delay_s": r.delay,
        "delay_std_s": r.std["delay"],
        "mass_from_motion_kg": r.values["m"],
        "mass_from_motion_std_kg": r.std["m"],
        "force_residual_rms_N": r.train_rms.force_N,
        "n_taut_samples": r.n_train,
    }
    windows = rest_windows(data)
    if windows:
        w = weight_at_rest(data, offset=r.offset, windows=windows)
        out["mass_at_rest_kg"] = w.mass
        out["rest_windows_s"] = [list(x) for x in w.windows]
    return out
