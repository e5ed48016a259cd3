# ruff: noqa: F722  (jaxtyping shape strings)
"""The one interpolant of a tension stream at shifted times ``tau(t + delay)`` (pure JAX).

:func:`tension_at` serves the nuisance fit of real recordings (:func:`cdprid.core.fit_nuisance`,
``"linear"`` by default, :data:`INTERPOLATION`) and the diagnosis' forward model
(``"catmull-rom"``: C1, so its derivative with respect to the delay is continuous); the
measurement that chose between them is in :mod:`cdprid.core._nuisance`'s docstring.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from cdprid.base import InputError

__all__ = ["CATMULL_ROM", "INTERPOLATION", "TensionStream", "tension_at", "tension_rate_at"]

INTERPOLATION: str = "linear"
"""Default interpolant of the tension stream at shifted times (the nuisance fit's)."""

CATMULL_ROM: str = "catmull-rom"
"""The cubic Hermite interpolant (the diagnosis' forward model uses it)."""

_METHODS = ("linear", CATMULL_ROM)


class TensionStream(eqx.Module):
    """The raw tension stream on its own uniform time grid.

    Attributes
    ----------
    t : array (k,)
        Times, s (uniform step, checked by :meth:`from_arrays`).
    values : array (k, m)
        Tensions, N.
    t0, dt : float
        First time and step (static).
    """

    t: Float[Array, " k"]
    values: Float[Array, "k m"]
    t0: float = eqx.field(static=True)
    dt: float = eqx.field(static=True)

    @classmethod
    def from_arrays(cls, t, values, rel_tol: float = 0.01) -> TensionStream:
        """Build the stream from its time stamps and values.

        The cubic interpolant assumes a uniform grid; gaps are never bridged silently.

        Parameters
        ----------
        t : array_like (k,)
            Time stamps, s (k >= 4).
        values : array_like (k, m)
            Tensions, N.
        rel_tol : float
            Largest step deviation from the median step, relative.

        Returns
        -------
        TensionStream

        Raises
        ------
        InputError
            Shapes that do not match or fewer than 4 samples; a step that varies by more than
            ``rel_tol`` (a gap).
        """
        t = np.asarray(t, float)
        values = np.asarray(values, float)
        if t.ndim != 1 or values.ndim != 2 or values.shape[0] != t.size or t.size < 4:
            raise InputError(f"tension stream: times {t.shape} and values {values.shape} do "
                             "not match (expected (k,) and (k, m), k >= 4).")
        d = np.diff(t)
        dt = float(np.median(d))
        if np.max(np.abs(d - dt)) > rel_tol * dt:
            raise InputError(f"tension stream: the step varies from {d.min():g} to {d.max():g} s "
                             f"(median {dt:g} s); a gap cannot be interpolated across.")
        return cls(jnp.asarray(t), jnp.asarray(values), float(t[0]), dt)

    @classmethod
    def on_uniform_grid(cls, t, values, rel_tol: float = 0.01) -> TensionStream:
        """The stream on a uniform grid: as recorded when its step is uniform to ``rel_tol``,
        else linearly interpolated onto ``t[0] + k * median step`` (sampling jitter; gaps
        are the alignment's to find and report, :func:`cdprid.io.align`).

        Parameters
        ----------
        t : ndarray (k,)
            Times, s, increasing.
        values : ndarray (k, m)
            Tensions, N.
        rel_tol : float
            Largest step deviation, relative to the median step, kept as recorded.

        Returns
        -------
        TensionStream
        """
        t = np.asarray(t, float)
        values = np.asarray(values, float)
        step = float(np.median(np.diff(t)))
        if np.max(np.abs(np.diff(t) - step)) > rel_tol * step:
            grid = np.arange(t[0], t[-1], step)
            values = np.column_stack([np.interp(grid, t, values[:, i])
                                      for i in range(values.shape[1])])
            t = grid
        return cls.from_arrays(t, values, rel_tol)

    def smoothed(self, cutoff_hz: float | None) -> TensionStream:
        """The stream through a zero-phase Butterworth low-pass
        (:func:`cdprid.signal.make_zero_phase_filter`).

        Parameters
        ----------
        cutoff_hz : float or None
            -3 dB frequency of one pass, Hz; None returns the stream unchanged.

        Returns
        -------
        TensionStream
            Same times; tensions in N.
        """
        if cutoff_hz is None:
            return self
        from cdprid.signal import make_zero_phase_filter

        f = make_zero_phase_filter(self.dt, cutoff_hz)
        return TensionStream(self.t, jnp.asarray(f(self.values)), self.t0, self.dt)


def _catmull_rom(stream: TensionStream, s):
    """Cubic Hermite (Catmull-Rom) inside, linear on the first and last grid intervals, the end
    values beyond them (a delay shifts the first or last samples off the stream, where the
    extrapolated cubic ran away: -175 N from a 50 N stream 25 ms before its start)."""
    k = stream.values.shape[0]
    u = jnp.clip((s - stream.t0) / stream.dt, 0.0, k - 1.0)
    i = jnp.clip(jnp.floor(u).astype(int), 1, k - 3)
    f = (u - i)[:, None]
    v = stream.values
    y0, y1, y2, y3 = v[i - 1], v[i], v[i + 1], v[i + 2]
    m1 = 0.5 * (y2 - y0)
    m2 = 0.5 * (y3 - y1)
    f2, f3 = f * f, f * f * f
    cubic = ((2 * f3 - 3 * f2 + 1) * y1 + (f3 - 2 * f2 + f) * m1 + (-2 * f3 + 3 * f2) * y2
             + (f3 - f2) * m2)
    lo = v[0] + u[:, None] * (v[1] - v[0])
    hi = v[k - 2] + (u[:, None] - (k - 2)) * (v[k - 1] - v[k - 2])
    return jnp.where(u[:, None] < 1.0, lo, jnp.where(u[:, None] > k - 2.0, hi, cubic))


def tension_at(stream: TensionStream, s: Float[Array, " n"], method: str = INTERPOLATION
               ) -> Float[Array, "n m"]:
    """Tensions at times ``s`` by ``"linear"`` or ``"catmull-rom"`` interpolation (pure JAX).

    Parameters
    ----------
    stream : TensionStream
    s : array (n,)
        Query times, s (differentiable: the delay enters through them).
    method : {"linear", "catmull-rom"}

    Returns
    -------
    array (n, m)
        Times beyond the ends read the end values (both methods); Catmull-Rom is linear on
        the first and last grid intervals (it has no neighbour there). The fits keep their
        rows inside the stream (:func:`cdprid.core.taut_mask`); the diagnosis shifts them by
        its delay and differentiates with respect to ``s`` (:func:`tension_rate_at`).
    """
    s = jnp.asarray(s)
    if method == "linear":
        return jax.vmap(lambda col: jnp.interp(s, stream.t, col), in_axes=1, out_axes=1)(
            stream.values)
    if method == "catmull-rom":
        return _catmull_rom(stream, s)
    raise InputError(f"unknown interpolation {method!r}; use one of {', '.join(_METHODS)}.")


def tension_rate_at(stream: TensionStream, s: Float[Array, " n"], method: str = INTERPOLATION
                    ) -> Float[Array, "n m"]:
    """Time derivative of the interpolant of :func:`tension_at` at times ``s`` (forward mode).

    Parameters
    ----------
    stream : TensionStream
    s : array (n,)
        Query times, s.
    method : {"linear", "catmull-rom"}

    Returns
    -------
    array (n, m)
        N/s.
    """
    return jax.jacfwd(lambda h: tension_at(stream, s + h, method))(0.0)
