"""Frequency response of the tuned differentiators: bounds, the exact linear response of
SIHD observers, the describing response of nonlinear ones, and the verification by sinusoids."""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.tuning._sihd_params import SIHD_METHODS, default_params
from cdprid.tuning._training import any_differentiate

RESPONSE_TOL = 0.05


PHASE_MAX_DEG = 30.0


GAIN_MAX_BELOW = 1.1


GAIN_MAX_ABOVE = 1.0 + RESPONSE_TOL


PENALTY_WEIGHT = 100.0


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
                raise InputError(f"response bound {k} must be a positive number, got {v!r}.")

    def as_json(self) -> dict:
        """The bounds as JSON numbers.

        Returns
        -------
        dict
        """
        return dataclasses.asdict(self)


def dense_freqs(dt: float, bandwidth_hz: float | None = None, n: int = 160) -> np.ndarray:
    """Verification grid of frequencies.

    ``n`` log-spaced frequencies from 0.05 Hz to ``0.45 / dt`` (plus the bandwidth itself and
    40 linearly spaced points up to it).

    Parameters
    ----------
    dt : float
        Sampling period, s.
    bandwidth_hz : float, optional
    n : int

    Returns
    -------
    ndarray
        Sorted frequencies, Hz.
    """
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

    Parameters
    ----------
    H : array (F,) complex
        Acceleration response.
    freqs_hz : array (F,)
        Its frequencies, Hz.
    bounds : ResponseBounds
    margin : float
        Fraction of the tolerances aimed at.

    Returns
    -------
    scalar array
        Dimensionless penalty (0 within the tightened bounds).
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
        """Numbers for ``tune --json`` (key ``frequency_response``).

        Returns
        -------
        dict
        """
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
        """The verification against the stated bounds (top-level keys of ``tune --json``).

        Returns
        -------
        dict
        """
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
        """One line of numbers.

        Returns
        -------
        str
        """
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
    """True when ``method`` with ``params`` is a linear filter.

    SIHD with alpha = 1 and gains below the dead-beat clip are linear; Levant and SIHD with
    alpha < 1 are not.

    Parameters
    ----------
    method : str
    params : dict

    Returns
    -------
    bool
    """
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

    Returns
    -------
    FrequencyResponse
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
        raise InputError(f"the stated bandwidth {b.bandwidth_hz:g} Hz is below the lowest "
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
