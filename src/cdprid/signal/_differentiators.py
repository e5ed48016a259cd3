"""Numerical differentiators for sampled platform positions.

One public entry point, :func:`differentiate`, returns the first and second
time derivatives of time-first arrays with one of the methods listed in
:data:`METHODS`:

==========================  ======  ==========================================
method                      causal  principle
==========================  ======  ==========================================
``sihd2-cascade`` (default) yes     two SIHD-2 in cascade (seed paper, Fig. 2)
``sihd3``                   yes     one SIHD-2-like observer with 3 projectors
``euler-filtfilt``          no      zero-phase Butterworth + central differences
``euler-butter-causal``     yes     causal Butterworth + backward differences
``levant``                  yes     Levant's 2nd-order robust exact
                                    differentiator, explicit Euler
``savgol``                  no      Savitzky-Golay local polynomial fit
``kalman``                  yes     constant-jerk Kalman filter
``rts``                     no      Rauch-Tung-Striebel smoother (same model)
==========================  ======  ==========================================

The semi-implicit homogeneous differentiators (SIHD) are written as pure
per-step functions (:func:`sihd2_step`, :func:`sihd3_step`) driven by
``jax.lax.scan`` and vmapped over channels.  The derivation, the
continuous-time systems and every resolved typo of the seed paper are in
``docs/sihd.md``.

All JAX-based methods go through one module-level jitted kernel whose only
static argument is the method name; gains and the sampling period are
traced, so calling :func:`differentiate` again with new data of the same
shape (and dtype) does not recompile.  Computations are float64: callers are
expected to enable ``jax_enable_x64``; if it is disabled, :func:`differentiate`
runs its JAX kernels under a temporary x64 scope.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field

import jax
import numpy as np

from cdprid.base import InputError
from cdprid.signal import _sihd_high as _sihd_high
from cdprid.signal._baselines import (
    _euler_butter_causal,
    _euler_filtfilt,
    _savgol,
    zero_phase_filter,
)
from cdprid.signal._scan import _run_jax_kernel


@dataclass(frozen=True)
class MethodInfo:
    """Description of one differentiation method.

    Parameters
    ----------
    name : str
        Key of the method in :data:`METHODS` and value of ``method=``.
    causal : bool
        True when the estimate at sample ``k`` only uses samples ``0..k``.
    params : dict
        Default values of every accepted keyword parameter (do not mutate).
    description : str
        One-line description.
    """

    name: str
    causal: bool
    params: dict = field(hash=False)
    description: str = ""


METHODS: dict[str, MethodInfo] = {
    m.name: m
    for m in (
        MethodInfo(
            "sihd2-cascade",
            True,
            {
                "lambda1": 210.0,
                "lambda2": 210.0,
                "lambda3": 525.0,
                "lambda4": 525.0,
                "alpha": 0.95,
                "mu": 1.0,
            },
            "Two semi-implicit homogeneous differentiators SIHD-2 in cascade "
            "(position->velocity with lambda1, lambda2; velocity->acceleration "
            "with lambda3, lambda4); seed-paper gains (eq. 35).",
        ),
        MethodInfo(
            "sihd3",
            True,
            # triple pole of the linear part (alpha = 1) at s = -omega,
            # omega = 15 rad/s: (s + w)^3 = s^3 + 3w s^2 + 3w^2 s + w^3.
            {"lambda1": 45.0, "lambda2": 675.0, "lambda3": 3375.0, "alpha": 0.95, "mu": 1.0},
            "Semi-implicit homogeneous differentiator with three projectors "
            "(states z1, z2, z3), trapezoidal Taylor term; defaults place the "
            "linear part's triple pole at -15 rad/s.",
        ),
        MethodInfo(
            "euler-filtfilt",
            False,
            {"cutoff_hz": 4.0, "order": 2},
            "Zero-phase Butterworth (filtfilt as scipy's, order 2 -> effective order 4, "
            "cutoff 4 Hz), then second-order central differences (np.gradient for "
            "d1, 3-point second difference for d2).",
        ),
        MethodInfo(
            "euler-butter-causal",
            True,
            {"cutoff_hz": 4.0, "order": 2},
            "Causal Butterworth (lfilter as scipy's, steady-state initial conditions), "
            "then backward differences.",
        ),
        MethodInfo(
            "levant",
            True,
            {"L": 2.0, "lambda0": 1.1, "lambda1": 1.5, "lambda2": 2.0},
            "Levant's recursive 2nd-order robust exact differentiator, explicit "
            "Euler; L bounds |y'''|.",
        ),
        MethodInfo(
            "savgol",
            False,
            {"window_s": 1.5, "polyorder": 5},
            "Savitzky-Golay filter (scipy savgol_filter deriv=1, 2; mode='interp'); "
            "window_s is rounded to an odd number of samples.",
        ),
        MethodInfo(
            "kalman",
            True,
            {"q": 0.3, "r": 2.5e-7},
            "Constant-jerk Kalman filter (states pos, vel, acc, jerk; white snap "
            "with spectral density q, measurement variance r).",
        ),
        MethodInfo(
            "rts",
            False,
            {"q": 0.1, "r": 2.5e-7},
            "Rauch-Tung-Striebel smoother of the constant-jerk model.",
        ),
    )
}


# higher-order SIHD (5 and 4 states), see cdprid.signal._sihd_high and docs/sihd.md
for _n in (4, 5):
    _info = _sihd_high.METHOD_INFO[f"sihd{_n}"]
    METHODS[f"sihd{_n}"] = MethodInfo(f"sihd{_n}", True, dict(_info["params"]),
                                      _info["description"])


def _check_params(method, params):
    if method not in METHODS:
        raise InputError(
            f"Unknown differentiation method {method!r}; valid names are: {', '.join(METHODS)}."
        )
    info = METHODS[method]
    bad = sorted(set(params) - set(info.params))
    if bad:
        raise InputError(
            f"Unknown parameter(s) {', '.join(bad)} for method {method!r}; valid "
            f"parameters are: {', '.join(info.params)}."
        )
    p = {**info.params, **params}
    for k, v in p.items():
        if isinstance(v, bool):  # JSON true/false: float(True) is 1.0, not a number given
            raise InputError(
                f"Parameter {k!r} of method {method!r} must be a number, got {v!r}."
            )
        try:
            fv = float(v)
        except (TypeError, ValueError):
            raise InputError(
                f"Parameter {k!r} of method {method!r} must be a number, got {v!r}."
            ) from None
        if not (math.isfinite(fv) and fv > 0.0):
            raise InputError(
                f"Parameter {k!r} of method {method!r} must be finite and > 0, got {v!r}."
            )
        if k in ("order", "polyorder"):
            if fv != int(fv):
                raise InputError(
                    f"Parameter {k!r} of method {method!r} must be an integer, got {v!r}."
                )
            fv = int(fv)
        p[k] = fv
    if method == "sihd2-cascade" and not 0.5 <= p["alpha"] <= 1.0:
        raise InputError(f"sihd2-cascade needs 0.5 <= alpha <= 1, got {p['alpha']!r}.")
    if method == "sihd3" and not 2.0 / 3.0 <= p["alpha"] <= 1.0:
        raise InputError(f"sihd3 needs 2/3 <= alpha <= 1, got {p['alpha']!r}.")
    for _n in (4, 5):
        if method == f"sihd{_n}" and not (_n - 1) / _n <= p["alpha"] <= 1.0:
            raise InputError(f"sihd{_n} needs {(_n - 1) / _n:g} <= alpha <= 1, got {p['alpha']!r}.")
    if method == "levant" and p["lambda0"] <= 1.0:
        raise InputError(f"levant needs lambda0 > 1, got {p['lambda0']!r}.")
    if "cutoff_hz" in p and p["cutoff_hz"] < MIN_CUTOFF_HZ:
        raise InputError(f"cutoff_hz {p['cutoff_hz']!r} of method {method!r} is below "
                         f"{MIN_CUTOFF_HZ} Hz: such a filter removes every motion of a "
                         "recording (and its design is numerically singular).")
    return p


#: Lowest filter cut-off a differentiator accepts (a period of 1000 s).
MIN_CUTOFF_HZ = 1e-3


def _x64_scope():
    if jax.config.read("jax_enable_x64"):
        return contextlib.nullcontext()
    return jax.enable_x64(True)  # pragma: no cover - callers normally enable x64


def differentiate(y, dt, method="sihd2-cascade", **params) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of sampled signals.

    Parameters
    ----------
    y : array_like, shape (n,) or (n, k)
        Time-first samples (numpy or JAX array), uniformly sampled.
    dt : float
        Sampling period in seconds (> 0).
    method : str, optional
        One of :data:`METHODS` (default ``"sihd2-cascade"``, the seed paper's
        cascade of two SIHD-2 with its gains, eq. 35).
    **params
        Method parameters overriding ``METHODS[method].params``.

    Returns
    -------
    d1, d2 : numpy.ndarray
        float64 estimates of the first and second derivatives, same shape as
        ``y``.  Causal methods return, at sample ``k``, an estimate that only
        uses ``y[:k+1]``.

    Raises
    ------
    ValueError
        Unknown method, unknown or invalid parameter, bad shape or ``dt``.

    Examples
    --------
    >>> t = np.arange(0, 10, 0.01)
    >>> v, a = differentiate(np.c_[np.cos(t), np.sin(t)], 0.01, method="savgol")
    """
    p = _check_params(method, params)
    arr = np.asarray(y, dtype=np.float64)
    if arr.ndim not in (1, 2) or arr.shape[0] < 3:
        raise InputError(f"y must have shape (n,) or (n, k) with n >= 3, got shape {arr.shape}.")
    try:
        dt = float(dt)
    except (TypeError, ValueError):
        raise InputError(f"dt must be a positive number, got {dt!r}.") from None
    if not (math.isfinite(dt) and dt > 0.0):
        raise InputError(f"dt must be a positive number, got {dt!r}.")
    squeeze = arr.ndim == 1
    y2 = arr[:, None] if squeeze else arr

    if method == "euler-filtfilt":
        d1, d2 = _euler_filtfilt(y2, dt, p["cutoff_hz"], p["order"])
    elif method == "euler-butter-causal":
        d1, d2 = _euler_butter_causal(y2, dt, p["cutoff_hz"], p["order"])
    elif method == "savgol":
        d1, d2 = _savgol(y2, dt, p["window_s"], p["polyorder"])
    else:
        vec = np.array(list(p.values()), dtype=np.float64)
        with _x64_scope():
            d1, d2 = _run_jax_kernel(method, y2, dt, vec)
    if squeeze:
        d1, d2 = d1[:, 0], d2[:, 0]
    return np.ascontiguousarray(d1), np.ascontiguousarray(d2)


def second_difference_response(y) -> np.ndarray:
    """The central second difference's response on a smooth signal: ``(1, 10, 1) / 12``.

    ``D2 x = x'' (1 - (w dt)^2 / 12 + O(dt^4))``; this FIR has ``1 - (w dt)^2 / 12 + O(dt^4)``
    too, so ``F[(1, 10, 1) / 12 * u]`` matches ``F[D2 x]`` when ``u = x''``. The end samples
    pass unchanged.
    """
    x = np.asarray(y, np.float64)
    out = x.copy()
    if x.shape[0] > 2:
        out[1:-1] = (x[:-2] + 10.0 * x[1:-1] + x[2:]) / 12.0
    return out


def acceleration_filter(y, dt, method: str = "euler-filtfilt", scale=None, **params) -> np.ndarray:
    """Pass a signal through the filter that ``method`` applies to accelerations.

    Matched filtering (paper section 7 for the zero-phase recipe; ``results/mzg-gap.md`` for the
    causal differentiators): the regressor sees the *estimated* acceleration, i.e. the true one
    through the differentiator's low-pass ``H`` (zero-phase or causal, with its lag). Filtering
    ``W tau`` by the same ``H`` keeps both sides of ``W tau = A x`` on the same footing, so the
    lag does not bias the estimate.

    ``euler-filtfilt`` uses its zero-phase Butterworth preceded by the central second
    difference's own response: ``(x[k-1] - 2 x[k] + x[k+1]) / dt^2`` is ``x''`` times
    ``1 - (w dt)^2 / 12 + O(dt^4)``, which the FIR ``(1, 10, 1) / 12`` reproduces to that order
    (Numerov's weights). Without it the accelerations were 3e-4 smaller than ``W tau`` at
    1 Hz (100 Hz sampling), a mismatch many times the inertia's share of the moment rows:
    -5.7 % on an 8-cable robot's Ixx under the errors-in-variables weighting with tension noise
    alone (``studies/bias_sources.py --noise ten``). Every other method gets ``H``
    from itself: the mean-free signal is integrated twice (trapezoid) and differentiated twice
    by ``method``; for a linear method this is exactly ``H`` applied to the signal; for the
    homogeneous (SIHD, Levant) ones it is their response at the amplitude ``scale`` (the signal
    is divided by ``scale`` first, so that it is an acceleration-sized input like the
    positions' second derivative, then multiplied back), the describing function of the
    linearised low-pass. The mean passes unchanged (a constant wrench is what a platform at
    rest gives).

    Parameters
    ----------
    y : array_like (n,) or (n, k)
        Time-first signal (e.g. the measured wrench ``W tau``, (n, 6)).
    dt : float
        Sampling period, s.
    method : str
        A method of :data:`METHODS`.
    scale : float or array (k,), optional
        Amplitude normalisation per channel (e.g. the mass for force rows, so the input is an
        acceleration in m/s^2). Default 1.
    **params
        The method's parameters (as given to :func:`differentiate`).

    Returns
    -------
    ndarray, same shape as ``y``
    """
    arr = np.asarray(y, np.float64)
    if method == "euler-filtfilt":
        p = _check_params(method, params)
        return zero_phase_filter(second_difference_response(arr), dt, p["cutoff_hz"],
                                 p["order"])
    squeeze = arr.ndim == 1
    x = arr[:, None] if squeeze else arr
    s = np.ones(x.shape[1]) if scale is None else np.broadcast_to(np.asarray(scale, float),
                                                                   (x.shape[1],))
    mu = x.mean(axis=0)
    u = (x - mu) / s
    i1 = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(0.5 * dt * (u[1:] + u[:-1]), 0)])
    i2 = np.concatenate([np.zeros((1, u.shape[1])), np.cumsum(0.5 * dt * (i1[1:] + i1[:-1]), 0)])
    _, a = differentiate(i2, dt, method=method, **params)
    out = a * s + mu
    return out[:, 0] if squeeze else out
