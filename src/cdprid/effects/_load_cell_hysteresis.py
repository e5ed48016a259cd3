"""``load_cell_hysteresis``: a load cell whose reading stays flat after each reversal of the
tension (a play, or backlash, operator of width ``width_N``; one module, one effect).

Everything the tool knows about this effect is here, in :data:`SPEC`: its parameters, its model
text (for ``docs/effects.md``), what the load cell reads (the simulator's sensor chain, an exact
recurrence in ``lax.scan``) and its form in the diagnosis (a regressor that reproduces the flat
stretch after each reversal). :mod:`cdprid.effects._registry` registers it with one line.

Derivation of the diagnosis form. With x the force on the cell and y = P_w[x] its reading (the
play operator), the state ``h = (x - y) / w`` lies in ``[-1/2, 1/2]``: ``+1/2`` while the force
rises (the reading trails it from below), ``-1/2`` while it falls. At a reversal of x the
reading stops; it moves again once x has crossed the band, i.e. moved by w. Near the reversal x
is a parabola, ``x - x_r = -d w tau^2`` with ``tau`` in [0, 1] the time across the flat
stretch and d the direction before it, so there ``h = d (1/2 - tau^2)``. The tension behind
the reading is therefore ``x = y + w h`` with h a function of the reading alone (where it
moves, where it is flat, and which way it went before and after): linear in w, the reading's
flat stretches and the directions around them give the regressor (:func:`reversal_regressor`).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC", "read", "play_operator", "reversal_regressor", "SMOOTH_S",
           "THRESHOLD_SIGMA"]

_DOC = """``load_cell_hysteresis {cable, width_N}``
    The load cell of cable ``cable`` is hysteretic (friction in its flexure or its mount,
    backlash in its linkage): a play (backlash) operator of width w = ``width_N`` acts on the
    force x the cell feels (the tension at the cell, after ``pulley_friction``), before its
    gain, offset, drift and noise: ``y_k = min(max(y_{k-1}, x_k - w/2), x_k + w/2)`` on the
    tension samples, ``y_0 = x_0 - w/2`` (the cable was tensioned up to its first value).
    While the tension rises the cell reads ``w/2`` too little, while it falls ``w/2`` too
    much, and after each reversal the reading stays flat until the tension has moved by w.
    The recurrence is exact when the tension is monotone between two samples. ``width_N``
    >= 0; 0 is no hysteresis. The diagnosis's form: the tension behind the reading is
    ``y + w h``, h in [-1/2, 1/2] from the reading's own direction (``+1/2`` rising,
    ``-1/2`` falling) and, across each flat stretch that separates a rise and a fall,
    ``d (1/2 - tau^2)`` (tau the time across the stretch, d the direction before it: the
    parabola of the tension at its reversal)."""

#: time scale of the smoothed tension rate of :func:`reversal_regressor`, s (half the span of
#: its triangular derivative kernel)
SMOOTH_S = 0.06

#: the reading moves when its smoothed rate exceeds this many noise standard deviations
THRESHOLD_SIGMA = 6.0


@jax.jit
def _play_scan(x, half):
    def step(y, xk):
        y = jnp.minimum(jnp.maximum(y, xk - half), xk + half)
        return y, y

    y0 = x[0] - half
    _, ys = jax.lax.scan(step, y0, x[1:])
    return jnp.concatenate([y0[None], ys], axis=0)


def play_operator(x, width_N) -> np.ndarray:
    """The play (backlash) operator of width ``width_N`` along time, column by column.

    Parameters
    ----------
    x : (k,) or (k, m) input force, N (samples in time order)
    width_N : float or (m,) band width, N (>= 0)

    Returns
    -------
    ndarray, the shape of ``x``
        ``y_j = min(max(y_{j-1}, x_j - w/2), x_j + w/2)``, ``y_0 = x_0 - w/2``, N.
    """
    x = np.asarray(x, float)
    two = x.reshape(x.shape[0], -1)
    half = 0.5 * np.broadcast_to(np.asarray(width_N, float), (two.shape[1],))
    if np.any(half < 0):
        raise InputError(f"the width of a play operator must be >= 0, got {width_N!r}.")
    if two.shape[0] == 0:
        return x.copy()
    return np.asarray(_play_scan(two, half)).reshape(x.shape)  # no jnp.asarray: no conversion compiled


def read(reading: np.ndarray, params: dict, ctx: dict) -> np.ndarray:
    """The load-cell readings ``(k, m)`` with the play of cable ``params["cable"]`` applied.

    Parameters
    ----------
    reading : (k, m) forces on the cells at the tension time stamps, N
    params : dict
        ``cable`` (1-based) and ``width_N``.
    ctx : dict
        Unused (the simulator's sensor-chain context).

    Returns
    -------
    ndarray (k, m), N
    """
    out = np.array(reading, float)
    i = params["cable"] - 1
    out[:, i] = play_operator(out[:, i], params["width_N"])
    return out


def _smoothed_rate(z, dt: float, span: int):
    """Rate of ``z`` (k, m): difference of the means over ``span`` samples after and before
    each sample, divided by their distance (a triangular derivative kernel; edges extended)."""
    zp = jnp.concatenate([jnp.repeat(z[:1], span, 0), z, jnp.repeat(z[-1:], span, 0)], 0)
    S = jnp.concatenate([jnp.zeros_like(z[:1]), jnp.cumsum(zp, axis=0)], axis=0)
    k = z.shape[0]
    i = jnp.arange(k) + span  # index of sample j in zp
    after = S[i + span + 1] - S[i + 1]
    before = S[i + 1] - S[i + 1 - span]
    return (after - before) / (span * span * dt)


def reversal_regressor(z, dt: float, smooth_s: float = SMOOTH_S,
                       threshold_sigma: float = THRESHOLD_SIGMA, erode: bool = True):
    """The hysteresis regressor h of load-cell readings (JAX): the tension is ``z + w h``.

    Each sample is *moving* (up or down) when the reading's smoothed rate exceeds
    ``threshold_sigma`` times its noise std (from the readings' white-noise level: third
    differences, by their mean absolute deviation), else *still*; with ``erode`` (the
    default) only where the rates one kernel half-span before and after it agree in
    direction too. Moving samples get
    ``h = +-1/2``; a still run between a rise and a fall (a reversal, the flat stretch of the
    play) gets ``d (1/2 - tau^2)``, tau in [0, 1] across the run and d the direction before
    it; a still run between two moves the same way, or at an end of the recording, keeps
    that direction's ``+-1/2``; no move at all gives 0.

    Why the erosion and the 60 ms kernel (issue 37; the width's least-squares regression on
    the readings of the independent test simulator, its play a plain loop: the ratio of the
    estimated to the true width). The rate's kernel smears each move by up to its half-span
    into the flat stretch that follows it, so the flat stretches came out short and ``h``
    too large: on noise-free readings of floor8 (seeds 0, 2, 4) the 40 ms kernel alone read
    0.93-0.96. The AR(1) part of the noise (pole 0.95-0.98 per sample, in the kernel's
    band) is not in the white-noise threshold and breaks flat stretches into spurious moves:
    the noisy readings read 0.90, 0.93, 0.94 (floor8 seeds 0, 2, 4), 0.74-0.83 at 1000 Hz.
    Requiring the rates a half-span on either side to agree removes both the smear (the
    kernel on one side lies wholly in the flat stretch) and most isolated spurious moves;
    with a 60 ms half-span the same readings read 0.98, 1.00, 0.97 (closer to 1 on 19 of 21
    floor8 recordings, within 2 % on the other two; worst 0.63 where it was 0.42). What
    remains is the form's: it sees the reading only, so a reversal of the force inside the
    band (a minor loop that never moves the reading) and a friction step on the same
    pulley smaller than the width leave no trace in it, and the width reads low (0.74-0.86
    on noise-free readings of a floor8 cell with a 4-5 N band and no friction; on the slow
    4-cable test robot, whose tension rates are near the threshold, 0.2-0.7 before and
    after). The cure is a form that runs the play on the model's force on the cell, not on
    the reading.

    Parameters
    ----------
    z : (k, m) readings on a uniform grid, N
    dt : float, the grid's step, s (static)
    smooth_s : float, half the span of the rate's kernel, s
    threshold_sigma : float
    erode : bool, moving only where the rates a half-span on either side agree (static)

    Returns
    -------
    (k, m) array in [-1/2, 1/2]
    """
    k = z.shape[0]
    span = max(1, int(round(smooth_s / dt)))
    rate = _smoothed_rate(z, dt, span)
    d3 = jnp.diff(z, 3, axis=0)
    # white-noise std from third differences (var 20 sigma^2), by the mean absolute deviation
    # (a median sorts the whole stream: 30 times slower inside the diagnosis's model)
    sigma = (math.sqrt(math.pi / 2.0) * jnp.mean(jnp.abs(d3 - jnp.mean(d3, 0)), 0)
             / math.sqrt(20.0))
    rate_std = sigma * math.sqrt(2.0 / span) / (span * dt)
    thr = threshold_sigma * jnp.maximum(rate_std, 1e-12)
    move = jnp.where(jnp.abs(rate) > thr, jnp.sign(rate), 0.0)
    if erode:  # moving only where the rates a span before and a span after agree
        before = move[jnp.clip(jnp.arange(k) - span, 0, k - 1)]
        after = move[jnp.clip(jnp.arange(k) + span, 0, k - 1)]
        move = jnp.where(before == after, before, 0.0)
    idx = jnp.broadcast_to(jnp.arange(k)[:, None], z.shape)
    # running max / min by associative scans (O(k log k); lax.cummax lowers to a window of k)
    last = jax.lax.associative_scan(jnp.maximum, jnp.where(move != 0, idx, -1), axis=0)
    nxt = jax.lax.associative_scan(jnp.minimum, jnp.where(move != 0, idx, k), axis=0,
                                   reverse=True)
    d_prev = jnp.where(last >= 0, jnp.take_along_axis(move, jnp.clip(last, 0, k - 1), 0), 0.0)
    d_next = jnp.where(nxt < k, jnp.take_along_axis(move, jnp.clip(nxt, 0, k - 1), 0), 0.0)
    tau = (idx - last) / jnp.maximum(nxt - last, 1)
    flat = d_prev * (0.5 - tau * tau)
    still = jnp.where((d_prev != 0) & (d_next != 0) & (d_prev != d_next), flat,
                      0.5 * jnp.where(d_prev != 0, d_prev, d_next))
    return jnp.where(move != 0, 0.5 * move, still)


def _hysteresis_model(y, d, q):
    """Model side (diagnosis): ``W y_reading = Y x - sum_i W_i w_i h_i`` (x = y + w h)."""
    from cdprid.model import wrench_matrix

    H = reversal_regressor(d.tau_grid, d.tau_dt)  # (k, m) on the tension grid
    k = H.shape[0]
    u = jnp.clip((d.t + q.get("delay", 0.0) - d.tau_t0) / d.tau_dt, 0.0, k - 1.0)
    i = jnp.clip(jnp.floor(u).astype(int), 0, k - 2)
    f = (u - i)[:, None]
    h = (1.0 - f) * H[i] + f * H[i + 1]  # (n, m) at the pose times
    W = jax.vmap(functools.partial(wrench_matrix, d.robot))(d.p, d.R)  # (n, 6, m)
    return y - jnp.einsum("nim,nm->ni", W, q["hysteresis"] * h)


SPEC = EffectSpec(
    name="load_cell_hysteresis",
    parameters=(Parameter("cable", "cable"), Parameter("width_N", "float", "N", minimum=0.0)),
    doc=_DOC, place=Place.CELL, read=read,
    diagnosis=DiagnosisForm(
        blocks=(("hysteresis", 1),), per_cable=True, group=1, keys=("width_N",),
        model=_hysteresis_model, bounds={"width_N": 100.0}, nonneg=("width_N",),
        separated_by={
            "time_delay": "a trajectory with reversals at several tension rates (a clock "
                          "offset grows with the rate, the play's step does not; only this "
                          "cell lags)",
            "pulley_friction": "motion where the tension reverses while the cable keeps its "
                               "direction (friction follows the cable's speed, hysteresis the "
                               "tension's rate)",
        }),
)
