"""Identification on real recordings: dynamic parameters jointly with sensor nuisances.

A real recording differs from the paper's model in ways a simulation does not: load cells
carry offsets (and possibly gains), the tension log and the motion capture are not exactly
aligned in time, cables go slack, the pulleys move the exit points and the platform rotates.
This module fits, by nonlinear least squares (optimistix Levenberg-Marquardt), the linear
dynamic parameters ``x`` (translation model ``[m, mxG, myG, mzG]`` or the full 10-parameter
model) jointly with

- ``offset`` (m,): load-cell offsets ``o_i``, N (``tau_true = k_i (tau_meas - o_i)``);
- ``gain`` (m,): relative load-cell gains ``k_i`` with ``sum(k_i) = m`` (a common gain of all
  cells cannot be told apart from the mass: only ratios are identified);
- ``delay``: ``tau_true(t) = tau_meas(t + delay)`` s (delay > 0: the tension log lags the
  pose), by linear interpolation of the 1 kHz tension stream;

on the equation ``F(W(pose) tau_true) = A(pose, a, omega, alpha) x`` where ``F`` is the same
zero-phase low-pass filter (:func:`cdprid.differentiators.zero_phase_filter`) through which the
accelerations were obtained (matched filtering; here implemented in JAX so that the delay
is differentiable). Rows are used only in TAUT phases (every cable above
``taut_threshold_N`` over a window around the sample): when a cable goes slack and snaps
taut the force has content far above the filter's band that no rigid-body model explains.

Uncertainties: ``cov = s^2 (J^T J)^-1`` of the weighted Jacobian at the solution (by SVD),
inflated by the residual's correlation length (consecutive filtered residuals are strongly
correlated): the reported standard deviations are the formal ones times ``sqrt(n_corr)``,
with ``n_corr`` = 1 + 2 sum of the residual autocorrelation up to its first zero crossing.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from .differentiators import differentiate
from .dynamics import PARAMETER_NAMES, regressor_full, regressor_translation
from .filters import make_zero_phase_filter
from .geometry import CableRobot, wrench_matrix
from .identification import least_squares
from .io.dataset import Dataset, align
from .rotations import angular_rates_from_quat, quat_to_matrix

__all__ = [
    "RealData",
    "RealResult",
    "prepare_real",
    "taut_mask",
    "weight_at_rest",
    "rest_windows",
    "identify_real",
    "compare_extensions",
    "jax_zero_phase_filter",
]


# --------------------------------------------------------------------------- matched filter


def jax_zero_phase_filter(x, dt: float, cutoff_hz: float = 4.0, order: int = 2):
    """JAX twin of :func:`cdprid.differentiators.zero_phase_filter` (differentiable);
    ``x`` is (n, k). Thin wrapper of :class:`cdprid.filters.ZeroPhaseFilter`."""
    return make_zero_phase_filter(float(dt), cutoff_hz, order)(x)


# --------------------------------------------------------------------------- data


@dataclasses.dataclass(frozen=True)
class RealData:
    """Pose-side quantities on the pose time base and the raw tension stream.

    Attributes
    ----------
    robot : CableRobot
    t, dt : pose time base
    p, R, a, omega, alpha : position, rotation, acceleration, angular rates (base frame)
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
    a: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    W: np.ndarray
    tension_t: np.ndarray
    tension: np.ndarray
    cutoff_hz: float

    def with_robot(self, robot: CableRobot) -> RealData:
        """The same data with the wrench matrices of another geometry (e.g. no pulleys)."""
        W = np.asarray(jax.vmap(lambda p, R: wrench_matrix(robot, p, R))(self.p, self.R))
        return dataclasses.replace(self, robot=robot, W=W)

    def tension_at(self, t, offset=None) -> np.ndarray:
        """Raw tensions interpolated at times ``t`` (minus ``offset``)."""
        tau = np.column_stack([np.interp(t, self.tension_t, self.tension[:, i])
                               for i in range(self.tension.shape[1])])
        return tau if offset is None else tau - np.asarray(offset)[None, :]


def prepare_real(ds: Dataset, cutoff_hz: float = 4.0, robot: CableRobot | None = None) -> RealData:
    """Align, differentiate (``euler-filtfilt`` at ``cutoff_hz``) and build W along the pose."""
    sig = align(ds)
    dt = sig.dt
    robot = ds.robot if robot is None else robot
    _, a = differentiate(sig.position, dt, method="euler-filtfilt", cutoff_hz=cutoff_hz)
    qd, qdd = differentiate(sig.quaternion, dt, method="euler-filtfilt", cutoff_hz=cutoff_hz)
    om, al = (np.asarray(z) for z in jax.vmap(angular_rates_from_quat)(
        jnp.asarray(sig.quaternion), jnp.asarray(qd), jnp.asarray(qdd)))
    R = np.asarray(jax.vmap(quat_to_matrix)(jnp.asarray(sig.quaternion)))
    W = np.asarray(jax.vmap(lambda p, RR: wrench_matrix(robot, p, RR))(
        jnp.asarray(sig.position), jnp.asarray(R)))
    return RealData(robot, sig.t, dt, sig.position, R, np.asarray(a), om, al, W,
                    np.asarray(ds.tension_t), np.asarray(ds.tension), cutoff_hz)


def taut_mask(data: RealData, threshold_N: float = 5.0, window_s: float = 0.1,
              offset=None) -> np.ndarray:
    """Pose samples where every cable stays above ``threshold_N`` (after ``offset``) during
    ``t +- window_s`` (the matched filter spreads a slack event over about 1/cutoff s)."""
    tau = data.tension - (0.0 if offset is None else np.asarray(offset)[None, :])
    low = tau.min(axis=1) > threshold_N
    tdt = float(np.median(np.diff(data.tension_t)))
    k = max(1, int(round(window_s / tdt)))
    bad = np.convolve((~low).astype(float), np.ones(2 * k + 1), mode="same") > 0
    ok = np.interp(data.t, data.tension_t, (~bad).astype(float)) > 0.999
    inside = (data.t >= data.tension_t[0] + window_s) & (data.t <= data.tension_t[-1] - window_s)
    return ok & inside


def rest_windows(data: RealData, max_speed: float = 0.02, max_rate: float = 0.1,
                 min_duration_s: float = 0.5) -> list[tuple[float, float]]:
    """Time windows where the platform is at rest (filtered speed and angular rate small)."""
    v, _ = differentiate(data.p, data.dt, method="euler-filtfilt", cutoff_hz=data.cutoff_hz)
    still = (np.linalg.norm(v, axis=1) < max_speed) & (np.linalg.norm(data.omega, axis=1) < max_rate)
    out, i, n = [], 0, len(still)
    while i < n:
        if still[i]:
            j = i
            while j < n and still[j]:
                j += 1
            if data.t[j - 1] - data.t[i] >= min_duration_s:
                out.append((float(data.t[i]), float(data.t[j - 1])))
            i = j
        else:
            i += 1
    return out


def weight_at_rest(data: RealData, offset=None, gain=None, windows=None) -> dict:
    """Mass from the weight measured at rest: ``-g . sum_i k_i (tau_i - o_i) u_i / |g|^2``.

    Returns ``{"mass", "std", "n", "windows", "per_window"}`` (std: spread over samples /
    sqrt(number of windows), a rough figure).
    """
    windows = rest_windows(data) if windows is None else windows
    if not windows:
        raise ValueError("no rest window found (the platform never stays still for 0.5 s).")
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
    return {"mass": float(allm.mean()), "std": float(np.std(per) / math.sqrt(len(per)))
            if len(per) > 1 else float(allm.std()), "n": int(allm.size), "windows": windows,
            "per_window": per}


# --------------------------------------------------------------------------- identification


@dataclasses.dataclass
class RealResult:
    """Joint estimate of the dynamic parameters and the nuisances.

    Attributes
    ----------
    model : "translation" or "full"
    names : tuple of parameter names (dynamic first, then nuisances)
    values, std : dict name -> float (std corrected for residual correlation)
    x : ndarray, the dynamic parameter vector
    offset, gain : ndarray (m,)
    delay : float, s
    train_rms, heldout_rms : dict ``{"force_N", "moment_Nm"}`` (taut samples only)
    n_train, n_test : int
    n_corr : float
        Correlation length used to inflate the formal standard deviations.
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
    train_rms: dict
    heldout_rms: dict
    n_train: int
    n_test: int
    n_corr: float
    residual: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    train: np.ndarray
    test: np.ndarray
    options: dict

    def summary(self) -> dict:
        """Plain-Python summary (JSON / TOML)."""
        return {
            "model": self.model,
            "parameters": {n: {"value": self.values[n], "std": self.std[n]} for n in self.names},
            "train_rms": self.train_rms, "heldout_rms": self.heldout_rms,
            "n_train": self.n_train, "n_test": self.n_test, "n_corr": self.n_corr,
            "options": self.options,
        }


def _regressors(data: RealData, model: str) -> np.ndarray:
    g = jnp.asarray(data.robot.gravity)
    if model == "translation":
        f = jax.vmap(lambda R, a: regressor_translation(R, a, g))
        return np.asarray(f(jnp.asarray(data.R), jnp.asarray(data.a)))
    if model == "full":
        f = jax.vmap(lambda R, a, w, al: regressor_full(R, a, w, al, g))
        return np.asarray(f(jnp.asarray(data.R), jnp.asarray(data.a), jnp.asarray(data.omega),
                            jnp.asarray(data.alpha)))
    raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")


def _corr_length(e: np.ndarray) -> float:
    """1 + 2 sum of autocorrelations up to the first non-positive lag (per column, median)."""
    out = []
    for col in np.atleast_2d(e.T):
        c = col - col.mean()
        n = len(c)
        f = np.fft.rfft(c, 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[:n]
        ac = ac / ac[0]
        k = int(np.argmax(ac <= 0)) if np.any(ac <= 0) else n
        out.append(1.0 + 2.0 * ac[1:k].sum())
    return float(max(1.0, np.median(out)))


def identify_real(
    data: RealData | Dataset,
    model: str = "translation",
    train_until: float = 25.0,
    test_until: float | None = None,
    taut_threshold_N: float = 5.0,
    offsets: bool | str = True,
    gains: bool = False,
    delay: bool = True,
    delay0: float = 0.0,
    trim: float = 1.0,
    max_steps: int = 100,
) -> RealResult:
    """Joint nonlinear LS of the dynamic parameters and the nuisances (module docstring).

    Parameters
    ----------
    data : RealData (from :func:`prepare_real`) or Dataset
    model : "translation" (paper, eq. 10) or "full" (10 parameters)
    train_until : fit on taut samples with t < train_until
    test_until : held-out window is [train_until, test_until) (default: to the end)
    taut_threshold_N : every cable above this (raw tension minus the offset estimate)
    offsets, gains, delay : which nuisances to estimate (otherwise 0, 1, ``delay0``);
        ``offsets="zero_sum"`` estimates offsets with ``sum(o) = 0``: a common offset of all
        cells adds a nearly constant, nearly vertical force that the data cannot tell apart
        from the weight ``m g`` (accelerations are small next to g), so free offsets make
        the mass unidentifiable (the free fit is kept for comparison).
    trim : seconds dropped at both ends of the recording
    max_steps : Levenberg-Marquardt steps

    Returns
    -------
    RealResult
    """
    import optimistix as optx

    if not isinstance(data, RealData):
        data = prepare_real(data)
    n, _, m = data.W.shape
    dt = data.dt
    A = _regressors(data, model)
    names_x = PARAMETER_NAMES[model]
    px = len(names_x)
    t = data.t
    end = t[-1] if test_until is None else test_until
    usable = (t >= max(t[0], data.tension_t[0]) + trim) & (t <= min(t[-1], data.tension_t[-1]) - trim)

    # parameter vector: x | offsets | gain ratios (m-1) | delay
    zero_sum = offsets == "zero_sum"
    sizes = [("x", px), ("offset", (m - 1 if zero_sum else m) if offsets else 0), ("gain", m - 1 if gains else 0),
             ("delay", 1 if delay else 0)]
    idx, i0 = {}, 0
    for k_, s_ in sizes:
        idx[k_] = slice(i0, i0 + s_)
        i0 += s_
    ntheta = i0
    # gain basis: k = 1 + B g with sum(B g) = 0 (common gain fixed: it is the mass)
    Bg = np.zeros((m, m - 1))
    for j in range(m - 1):
        Bg[j, j], Bg[m - 1, j] = 1.0, -1.0
    tt = jnp.asarray(data.tension_t)
    tau_raw = jnp.asarray(data.tension)
    Wj = jnp.asarray(data.W)
    Aj = jnp.asarray(A)
    tj = jnp.asarray(t)

    def unpack(theta):
        x = theta[idx["x"]]
        if not offsets:
            o = jnp.zeros(m)
        elif zero_sum:
            o = jnp.asarray(Bg) @ theta[idx["offset"]]
        else:
            o = theta[idx["offset"]]
        k = 1.0 + jnp.asarray(Bg) @ theta[idx["gain"]] if gains else jnp.ones(m)
        d = theta[idx["delay"]][0] if delay else jnp.asarray(delay0)
        return x, o, k, d

    def measured(theta):
        _, o, k, d = unpack(theta)
        tau = jax.vmap(lambda col: jnp.interp(tj + d, tt, col), in_axes=1, out_axes=1)(tau_raw)
        tau = (tau - o[None, :]) * k[None, :]
        w = jnp.einsum("nij,nj->ni", Wj, tau)
        return jax_zero_phase_filter(w, dt, data.cutoff_hz)

    def resid_all(theta):
        x = theta[idx["x"]]
        return measured(theta) - jnp.einsum("nij,j->ni", Aj, x)

    def masks(o):
        taut = taut_mask(data, taut_threshold_N, offset=None if o is None else np.asarray(o))
        train = usable & taut & (t < train_until)
        test = usable & taut & (t >= train_until) & (t < end)
        return train, test

    train, test = masks(None)
    if train.sum() < 100:
        raise ValueError(f"only {int(train.sum())} taut training samples before "
                         f"t = {train_until:g} s; lower taut_threshold_N or move train_until.")
    # start: linear LS with the other parameters at their neutral values
    theta = np.zeros(ntheta)
    if delay:
        theta[idx["delay"]] = delay0
    y0 = np.asarray(measured(jnp.asarray(theta)))
    ls = least_squares(A[train].reshape(-1, px), y0[train].reshape(-1), names_x)
    theta[idx["x"]] = ls.x
    e0 = y0 - np.einsum("nij,j->ni", A, ls.x)
    wrow = np.array([1.0 / np.sqrt(np.mean(e0[train][:, :3] ** 2))] * 3
                    + [1.0 / np.sqrt(np.mean(e0[train][:, 3:] ** 2))] * 3)
    # scale the parameters so that LM steps are well balanced (delay in 10 ms units)
    scale = np.ones(ntheta)
    if delay:
        scale[idx["delay"]] = 0.01
    if gains:
        scale[idx["gain"]] = 0.01
    for _ in range(2):  # second pass with row weights from the first solution
        trj = jnp.asarray(np.nonzero(train)[0])
        wj = jnp.asarray(wrow)
        sj = jnp.asarray(scale)

        def fun(z, args):
            rows, w_, s_ = args
            return (resid_all(z * s_)[rows] * w_[None, :]).ravel()

        solver = optx.LevenbergMarquardt(rtol=1e-10, atol=1e-10)
        sol = optx.least_squares(fun, solver, jnp.asarray(theta / scale), args=(trj, wj, sj),
                                 max_steps=max_steps, throw=False)
        theta = np.asarray(sol.value) * scale
        e = np.asarray(resid_all(jnp.asarray(theta)))
        wrow = np.array([1.0 / np.sqrt(np.mean(e[train][:, :3] ** 2))] * 3
                        + [1.0 / np.sqrt(np.mean(e[train][:, 3:] ** 2))] * 3)
    # covariance of the weighted problem at the solution (scaled variables), SVD-based
    trj = jnp.asarray(np.nonzero(train)[0])
    wj = jnp.asarray(wrow)
    sj = jnp.asarray(scale)

    def fun2(z):
        return (resid_all(z * sj)[trj] * wj[None, :]).ravel()

    z = jnp.asarray(theta / scale)
    J = np.asarray(jax.jacfwd(fun2)(z))
    r = np.asarray(fun2(z))
    s2 = float(r @ r) / max(len(r) - ntheta, 1)
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    inv = np.where(sv > sv[0] * 1e-13, 1.0 / np.maximum(sv, 1e-300) ** 2, 0.0)
    cov = (Vt.T * inv) @ Vt * s2 * np.outer(scale, scale)
    e = np.asarray(resid_all(jnp.asarray(theta)))
    ncorr = _corr_length(e[train] * wrow[None, :])
    std_theta = np.sqrt(np.clip(np.diag(cov), 0, None) * ncorr)
    x, o, k, d = (np.asarray(v) for v in unpack(jnp.asarray(theta)))
    names, values, std = list(names_x), {}, {}
    for j, nm in enumerate(names_x):
        values[nm], std[nm] = float(theta[j]), float(std_theta[j])
    if offsets:
        co = cov[idx["offset"], idx["offset"]] * ncorr
        ostd = np.sqrt(np.clip(np.diag(Bg @ co @ Bg.T if zero_sum else co), 0, None))
        for j in range(m):
            nm = f"offset_{j + 1}"
            names.append(nm)
            values[nm], std[nm] = float(o[j]), float(ostd[j])
    if gains:
        cg = cov[idx["gain"], idx["gain"]] * ncorr
        kstd = np.sqrt(np.clip(np.diag(Bg @ cg @ Bg.T), 0, None))
        for j in range(m):
            nm = f"gain_{j + 1}"
            names.append(nm)
            values[nm], std[nm] = float(k[j]), float(kstd[j])
    names.append("delay")
    values["delay"] = float(d)
    std["delay"] = float(std_theta[idx["delay"]][0]) if delay else 0.0
    meas = np.asarray(measured(jnp.asarray(theta)))
    pred = meas - e

    def rms(mask):
        if not mask.any():
            return {"force_N": float("nan"), "moment_Nm": float("nan")}
        return {"force_N": float(np.sqrt(np.mean(e[mask][:, :3] ** 2))),
                "moment_Nm": float(np.sqrt(np.mean(e[mask][:, 3:] ** 2)))}

    return RealResult(
        model=model, names=tuple(names), values=values, std=std, x=x, offset=o, gain=k,
        delay=float(d), train_rms=rms(train), heldout_rms=rms(test), n_train=int(train.sum()),
        n_test=int(test.sum()), n_corr=ncorr, residual=e, measured=meas, predicted=pred,
        train=train, test=test,
        options={"train_until": train_until, "test_until": test_until,
                 "taut_threshold_N": taut_threshold_N, "offsets": offsets, "gains": gains,
                 "delay": delay, "pulleys": bool(data.robot.has_pulleys),
                 "cutoff_hz": data.cutoff_hz},
    )


def compare_extensions(data: RealData, train_until: float = 25.0, test_until: float | None = None,
                       taut_threshold_N: float = 5.0, steps=None, **kw) -> list[dict]:
    """The paper's model, then one extension added at a time (cumulative), with the held-out
    taut residuals of each step.

    Default steps: fixed exit points (pulleys removed), translation model -> + pulleys (moving
    exit points) -> + time delay -> + rotational dynamics (full model) -> + relative load-cell
    gains (final) ; and, as alternatives to the final step, zero-sum offsets and free offsets.
    Every step uses the same taut mask (raw tensions), so held-out figures are comparable.
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
        out.append({"step": label, "result": r})
    return out
