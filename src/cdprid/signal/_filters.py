# ruff: noqa: F722  (jaxtyping shape strings)
"""Butterworth low-pass filters without SciPy: design, causal and zero-phase filtering.

Two implementations of one filter:

* numpy (:func:`butter_lowpass`, :func:`butter_sos`, :func:`sosfilt`, :func:`sosfiltfilt`): the
  closed-form Butterworth design (analog prototype poles, pre-warped bilinear transform, as
  ``scipy.signal.butter``) and the direct-form-II-transposed recursion evaluated block by block
  (exact block state-space form: per block of ``L`` samples the output is a Toeplitz matrix of
  the impulse response times the input plus the observability matrix times the block's initial
  state; only the (order, k) state is carried from block to block in Python), on second-order
  sections (:func:`butter_sos`: well conditioned at any order). :func:`sosfiltfilt` uses
  SciPy's odd padding and steady-state (``lfilter_zi``) initial conditions. Tested against
  ``scipy.signal`` to 1e-12 (``tests/signal/test_differentiators.py``). Importing ``scipy.signal``
  took about half of ``cdprid identify``'s cold start, hence this module.
* JAX (:class:`ZeroPhaseFilter`): the same recursion as a forward then backward ``lax.scan``,
  differentiable, for the diagnosis that refits effects through the matched filter.
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Float

from cdprid.base import InputError

__all__ = ["ZeroPhaseFilter", "butter_lowpass", "butter_sos", "lfilter", "lfilter_zi",
           "make_zero_phase_filter", "sosfilt", "sosfilt_zi", "sosfiltfilt"]


def butter_lowpass(order: int, cutoff_hz: float, fs: float
                   ) -> tuple[Float[np.ndarray, " o"], Float[np.ndarray, " o"]]:
    """Digital Butterworth low-pass ``(b, a)``, as ``scipy.signal.butter(order, cutoff_hz,
    btype="low", fs=fs)``.

    Parameters
    ----------
    order : int
        Filter order (>= 1).
    cutoff_hz : float
        -3 dB frequency, Hz, in (0, fs / 2).
    fs : float
        Sampling frequency, Hz.

    Returns
    -------
    b, a : ndarray (order + 1,)
        Numerator and denominator, ``a[0] = 1``.
    """
    n = int(order)
    if n < 1:
        raise InputError(f"Butterworth order must be >= 1, got {order!r}.")
    if not 0.0 < cutoff_hz < 0.5 * fs:
        raise InputError(f"cutoff_hz must lie in (0, Nyquist = {0.5 * fs:g} Hz), got "
                         f"{cutoff_hz!r}.")
    m = np.arange(-n + 1, n, 2)
    p = -np.exp(1j * np.pi * m / (2 * n))  # analog prototype poles, unit cut-off
    wn = 2.0 * cutoff_hz / fs
    warped = 4.0 * np.tan(np.pi * wn / 2.0)  # pre-warped analog cut-off (bilinear, fs = 2)
    p = warped * p
    k = warped**n
    pz = (4.0 + p) / (4.0 - p)  # bilinear transform
    kz = k * np.real(1.0 / np.prod(4.0 - p))
    b = kz * np.real(np.poly(-np.ones(n)))
    a = np.real(np.poly(pz))
    return b, a


def lfilter_zi(b: Float[np.ndarray, " o"], a: Float[np.ndarray, " o"]
               ) -> Float[np.ndarray, " r"]:
    """Steady-state initial state of :func:`lfilter` for a unit step (``scipy.signal.lfilter_zi``).

    Parameters
    ----------
    b, a : array (order + 1,)

    Returns
    -------
    ndarray (order,)
    """
    b = np.asarray(b, float) / a[0]
    a = np.asarray(a, float) / a[0]
    n = max(len(a), len(b))
    a = np.r_[a, np.zeros(n - len(a))]
    b = np.r_[b, np.zeros(n - len(b))]
    companion = np.zeros((n - 1, n - 1))
    companion[0] = -a[1:]
    companion[np.arange(1, n - 1), np.arange(n - 2)] = 1.0
    return np.linalg.solve(np.eye(n - 1) - companion.T, b[1:] - a[1:] * b[0])


_BLOCK = 64
"""Samples per block of the block state-space evaluation of :func:`lfilter`."""


@functools.lru_cache(maxsize=32)
def _block_operators(b: tuple, a: tuple, L: int):
    """(T, O, AL, Ctrl) of the DF2T state space over a block of L samples."""
    b, a = np.asarray(b), np.asarray(a)
    r = len(a) - 1
    A = np.zeros((r, r))
    A[:, 0] = -a[1:]
    A[np.arange(r - 1), np.arange(1, r)] = 1.0
    B = b[1:] - a[1:] * b[0]
    powers = [np.eye(r)]
    for _ in range(L):
        powers.append(A @ powers[-1])
    O = np.stack([P[0] for P in powers[:L]])  # C A^m, C = e_0
    h = np.r_[b[0], [O[m - 1] @ B for m in range(1, L)]]
    i, j = np.indices((L, L))
    T = np.where(i >= j, h[np.clip(i - j, 0, L - 1)], 0.0)
    Ctrl = np.stack([powers[L - 1 - m] @ B for m in range(L)], axis=1)  # (r, L)
    return T, O, powers[L], Ctrl


def lfilter(b: Float[np.ndarray, " o"], a: Float[np.ndarray, " o"],
            x: Float[np.ndarray, "n ..."], zi: Float[np.ndarray, "r ..."] | None = None
            ) -> Float[np.ndarray, "n ..."]:
    """Causal IIR filter along axis 0 (``scipy.signal.lfilter(b, a, x, axis=0, zi=zi)[0]``).

    Parameters
    ----------
    b, a : array (order + 1,)
        Equal lengths (as :func:`butter_lowpass` gives).
    x : ndarray (n,) or (n, k)
    zi : ndarray (order,) or (order, k), optional
        Initial state of the direct-form-II-transposed recursion (default zero).

    Returns
    -------
    ndarray, shape of ``x``
    """
    b = np.asarray(b, float) / a[0]
    a = np.asarray(a, float) / a[0]
    if len(a) != len(b):
        raise InputError("lfilter needs b and a of equal length.")
    x = np.asarray(x, float)
    x2 = x.reshape(x.shape[0], -1)
    n, k = x2.shape
    r = len(a) - 1
    if r == 0:
        return (b[0] * x2).reshape(x.shape)
    s = np.zeros((r, k)) if zi is None else np.asarray(zi, float).reshape(r, -1) * np.ones((1, k))
    L = _BLOCK
    T, O, AL, Ctrl = _block_operators(tuple(b), tuple(a), L)
    nb = -(-n // L)
    X = np.zeros((nb * L, k))
    X[:n] = x2
    X = X.reshape(nb, L, k)
    U = np.matmul(Ctrl, X)  # (nb, r, k); matmul: BLAS, einsum is not
    S = np.empty((nb, r, k))
    for j in range(nb):
        S[j] = s
        s = AL @ s + U[j]
    Y = np.matmul(T, X) + np.matmul(O, S)
    return Y.reshape(nb * L, k)[:n].reshape(x.shape)


def butter_sos(order: int, cutoff_hz: float, fs: float) -> Float[np.ndarray, "s 6"]:
    """The Butterworth low-pass of :func:`butter_lowpass` as second-order sections.

    Each conjugate pole pair of the bilinear-transformed design is one section
    ``[1, 2, 1, 1, -2 Re p, |p|^2]`` (an odd order adds ``[1, 1, 0, 1, -p, 0]``); the gain is
    applied to the first section. Mathematically the same filter as ``(b, a)``, numerically
    well conditioned at any order (the ``(b, a)`` form is not for high orders and low cut-offs).

    Parameters
    ----------
    order : int
        Filter order (>= 1).
    cutoff_hz : float
        -3 dB frequency, Hz (0 < cutoff_hz < fs / 2).
    fs : float
        Sampling rate, Hz.

    Returns
    -------
    ndarray (ceil(order / 2), 6)
        Rows ``[b0, b1, b2, 1, a1, a2]`` (``scipy.signal`` sos layout).

    Raises
    ------
    InputError
        From :func:`butter_lowpass`: an order below 1 or a cut-off outside ``(0, fs / 2)``.
    """
    n = int(order)
    b, _ = butter_lowpass(n, cutoff_hz, fs)  # validates; b[0] is the overall gain
    m = np.arange(-n + 1, n, 2)
    warped = 4.0 * np.tan(np.pi * cutoff_hz / fs)
    pz = (4.0 + warped * -np.exp(1j * np.pi * m / (2 * n))) / (4.0 - warped * -np.exp(
        1j * np.pi * m / (2 * n)))
    upper = sorted((p for p in pz if p.imag > 1e-14), key=lambda p: -abs(p))
    rows = [[1.0, 2.0, 1.0, 1.0, -2.0 * p.real, abs(p) ** 2] for p in upper]
    if n % 2:
        real = float(pz[np.argmin(np.abs(pz.imag))].real)
        rows.append([1.0, 1.0, 0.0, 1.0, -real, 0.0])
    sos = np.asarray(rows)
    sos[0, :3] *= b[0]
    return sos


def sosfilt_zi(sos: Float[np.ndarray, "s 6"]) -> Float[np.ndarray, "s 2"]:
    """Steady-state initial states of :func:`sosfilt` for a unit step (``scipy.signal.sosfilt_zi``).

    Parameters
    ----------
    sos : ndarray (n_sections, 6)
        Second-order sections ``[b0, b1, b2, a0, a1, a2]`` (:func:`butter_sos`).

    Returns
    -------
    ndarray (n_sections, 2)
        Initial states of each section (per unit of the input's first value).
    """
    sos = np.asarray(sos, float)
    zi = np.empty((sos.shape[0], 2))
    scale = 1.0
    for i, sec in enumerate(sos):
        zi[i] = scale * lfilter_zi(sec[:3], sec[3:])
        scale *= sec[:3].sum() / sec[3:].sum()
    return zi


def sosfilt(sos: Float[np.ndarray, "s 6"], x: Float[np.ndarray, "n ..."],
            zi: Float[np.ndarray, "s 2 ..."] | None = None) -> Float[np.ndarray, "n ..."]:
    """Cascade of second-order sections along axis 0 (``scipy.signal.sosfilt(sos, x, axis=0,
    zi=zi)[0]``), each by :func:`lfilter`.

    Parameters
    ----------
    sos : ndarray (s, 6)
    x : ndarray (n,) or (n, k)
    zi : ndarray (s, 2) or (s, 2, k), optional

    Returns
    -------
    ndarray, shape of ``x``
    """
    y = np.asarray(x, float)
    for i, sec in enumerate(np.asarray(sos, float)):
        y = lfilter(sec[:3], sec[3:], y, None if zi is None else zi[i])
    return y


def sosfiltfilt(sos: Float[np.ndarray, "s 6"], x: Float[np.ndarray, "n ..."], padlen: int
                ) -> Float[np.ndarray, "n ..."]:
    """Zero-phase forward-backward filter along axis 0, SciPy's odd padding and steady-state
    initial conditions (``scipy.signal.sosfiltfilt(sos, x, axis=0, padtype="odd",
    padlen=padlen)``, which equals ``scipy.signal.filtfilt`` with the ``(b, a)`` form of the
    same filter).

    Parameters
    ----------
    sos : ndarray (s, 6)
    x : ndarray (n,) or (n, k)
    padlen : int
        Samples of odd (point-symmetric) extension at each end, ``< n``.

    Returns
    -------
    ndarray, shape of ``x``
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    padlen = int(padlen)
    if not 0 <= padlen < n:
        raise InputError(f"padlen must be in [0, {n - 1}], got {padlen}.")
    if padlen > 0:
        ext = np.concatenate([2 * x[:1] - x[padlen:0:-1], x,
                              2 * x[-1:] - x[-2:-padlen - 2:-1]], axis=0)
    else:
        ext = x
    zi = sosfilt_zi(sos)
    zshape = zi.shape + (1,) * (x.ndim - 1)
    y = sosfilt(sos, ext, zi.reshape(zshape) * ext[0])
    y = sosfilt(sos, y[::-1], zi.reshape(zshape) * y[-1])[::-1]
    return np.ascontiguousarray(y[padlen:padlen + n])


def _lfilter(b, a, x, zi):
    """Direct form II transposed along axis 0 of x (n, k) with initial state zi (order, k)."""
    order = len(a) - 1

    def step(z, xn):
        yn = b[0] * xn + z[0]
        znew = [z[i + 1] + b[i + 1] * xn - a[i + 1] * yn for i in range(order - 1)]
        znew.append(b[order] * xn - a[order] * yn)
        return jnp.stack(znew), yn

    _, y = jax.lax.scan(step, zi, x)
    return y


class ZeroPhaseFilter:
    """A zero-phase Butterworth low-pass for a fixed step, usable on numpy or inside JAX.

    Parameters
    ----------
    dt : float
        Sampling period, s.
    cutoff_hz : float
    order : int
        Order of the single pass (the filter runs forward and backward).
    """

    def __init__(self, dt: float, cutoff_hz: float = 4.0, order: int = 2):
        b, a = butter_lowpass(int(order), cutoff_hz, 1.0 / dt)
        self.b = np.asarray(b / a[0])
        self.a = np.asarray(a / a[0])
        self.zi = np.asarray(lfilter_zi(b, a))
        self.dt = dt
        self.cutoff_hz = cutoff_hz
        self.order = order
        self._padlen_nominal = int(math.ceil(5.0 / (cutoff_hz * dt)))

    def __call__(self, x):
        """Filter a time-first array (n,) or (n, ...) along axis 0 (JAX-traceable)."""
        x = jnp.asarray(x)
        shape = x.shape
        x2 = x.reshape(shape[0], -1)
        n = shape[0]
        pad = min(n - 1, self._padlen_nominal)
        left = 2 * x2[0] - x2[pad:0:-1]
        right = 2 * x2[-1] - x2[-2 : -pad - 2 : -1]
        ext = jnp.concatenate([left, x2, right], axis=0)
        b, a, zi = jnp.asarray(self.b), jnp.asarray(self.a), jnp.asarray(self.zi)
        y = _lfilter(b, a, ext, zi[:, None] * ext[0][None, :])
        y = y[::-1]
        y = _lfilter(b, a, y, zi[:, None] * y[0][None, :])
        y = y[::-1]
        return y[pad : pad + n].reshape(shape)


def make_zero_phase_filter(dt: float, cutoff_hz: float = 4.0, order: int = 2) -> ZeroPhaseFilter:
    """The JAX twin of ``zero_phase_filter(x, dt, cutoff_hz, order)``: a
    :class:`ZeroPhaseFilter` for a fixed step, callable inside ``jit``.

    Parameters
    ----------
    dt : float
        Sampling period, s.
    cutoff_hz : float
        -3 dB frequency of one pass, Hz.
    order : int
        Order of one pass (the filter runs forward and backward: twice the order, no phase).

    Returns
    -------
    ZeroPhaseFilter
        ``f(x)`` filters a time-first array (n,) or (n, ...) along axis 0, units unchanged.
    """
    return ZeroPhaseFilter(dt, cutoff_hz, order)
