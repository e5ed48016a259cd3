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

__all__ = ["SPEC", "read", "play_operator", "reversal_regressor", "hysteresis_regressor",
           "play_regressor", "SMOOTH_S", "THRESHOLD_SIGMA"]

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
    ``y + w h``, h in [-1/2, 1/2]. To find a hysteretic cell, h comes from the reading alone:
    ``+1/2`` where it rises, ``-1/2`` where it falls (two plays of a few noise stds, along
    time and against it, tell the direction of its last and next move whatever the rate)
    and, across each flat stretch that separates a rise and a fall, ``d (1/2 - tau^2)`` (tau
    the time across the stretch, d the direction before it: the parabola of the tension at
    its reversal). Once the cell is in the model, h is the play of the current width on the
    force the rest of the model says the cell felt (the reading plus the model's residual
    projected on the cable), which holds the reversals inside the band that never move the
    reading; three passes. The width's interval adds a 7 % form error to the fit's."""

#: half the span of the moving average that :func:`reversal_regressor` applies to the reading
#: before it looks for the reading's moves, s
SMOOTH_S = 0.05

#: the width of :func:`reversal_regressor`'s direction plays, in noise standard deviations of
#: the averaged reading (a move is a change larger than this)
THRESHOLD_SIGMA = 4.0


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


def _mad_std(d, count: int):
    """Std of white noise from its ``count``-term differences ``d`` (variance ``count``
    sigma^2 per difference for third differences: 20), by the mean absolute deviation (a
    median sorts the whole stream: 30 times slower inside the diagnosis's model)."""
    return (math.sqrt(math.pi / 2.0) * jnp.mean(jnp.abs(d - jnp.mean(d, 0)), 0)
            / math.sqrt(count))


def _moving_average(z, span: int):
    """Centred mean of ``z`` (k, m) over ``2 span + 1`` samples (edges extended)."""
    zp = jnp.concatenate([jnp.repeat(z[:1], span, 0), z, jnp.repeat(z[-1:], span, 0)], 0)
    S = jnp.concatenate([jnp.zeros_like(z[:1]), jnp.cumsum(zp, axis=0)], axis=0)
    k = z.shape[0]
    return (S[2 * span + 1:2 * span + 1 + k] - S[:k]) / (2 * span + 1)


def _play_direction(z, half, reverse: bool):
    """Direction of the last move (+1 up, -1 down, 0 none yet) of the play of half-width
    ``half`` (m,) driven by ``z`` (k, m), along time or (``reverse``) against it."""
    def step(carry, zk):
        y, d = carry
        yn = jnp.minimum(jnp.maximum(y, zk - half), zk + half)
        d = jnp.where(yn > y, 1.0, jnp.where(yn < y, -1.0, d))
        return (yn, d), d

    z0 = z[-1] if reverse else z[0]
    _, ds = jax.lax.scan(step, (z0, jnp.zeros_like(z0)), z, reverse=reverse)
    return ds


def reversal_regressor(z, dt: float, smooth_s: float = SMOOTH_S,
                       threshold_sigma: float = THRESHOLD_SIGMA):
    """The hysteresis regressor h of load-cell readings (JAX): the tension is ``z + w h``.

    The reading is averaged over ``2 smooth_s``; two play operators of width delta
    (``threshold_sigma`` times the averaged reading's noise std) run over it, one along time
    and one against it: the first gives at each sample the direction of the reading's last
    move larger than delta, the second the direction of its next one. Where they agree the
    reading moves (or pauses between two moves the same way) and ``h = +-1/2``; a run where
    they differ holds a reversal, the flat stretch of the play, and gets ``d (1/2 - tau^2)``
    (tau in [0, 1] across the run, d the direction before it: the parabola of the tension at
    its reversal); before the first move and after the last h takes the one known direction.

    Why direction plays, not the sign of a smoothed rate (issue 37, session 11). The reading
    of a hysteretic cell is flat after each reversal until the tension has moved by the
    width, so what the form needs is where the reading moves, up or down, and where it does
    not. The previous detector thresholded a 60 ms derivative at six times its noise: on
    robots whose tensions are sampled at 100 Hz with 0.7 N of noise and change by 4-10 N/s
    (median; the 4-, 6- and CRAFT-like 8-cable robots of ``benchmarks/diagnosis.py``) no
    sample passed and the form was zero (the least-squares width of noisy readings against
    the true force on the cell: 0.0 of the truth on the 4- and 8-cable robots, 0.1 on the
    6-cable one), and the diagnosis named cable mass, anchor errors or gains instead. A play
    detects a change in level whatever its rate: the same readings read 0.5-0.9 (4-cable),
    0.8-1.0 (6-cable), 0.5-0.9 (8-cable), the wider bands lowest, and 0.94-1.01 on the
    floor-winch robot's 500-800 Hz readings with AR(1) noise (0.92-0.97 before). The noise
    std of the averaged reading is the larger of the white level (third differences of the
    raw reading over the averaging count) and the third differences of the averaged reading
    taken a full span apart (which see the AR(1) part's low frequencies).

    What remains is the form's: it sees the reading only, so a reversal of the force inside
    the band (a minor loop that never moves the reading) leaves no trace in it and the width
    reads low where the tension reverses often by less than the width (the wide bands of the
    slow robots above). Once a cell is named, the diagnosis replaces this regressor by
    :func:`play_regressor` of the force the model says the cell felt
    (:mod:`cdprid.diagnosis._hysteresis`).

    Parameters
    ----------
    z : (k, m) readings on a uniform grid, N
    dt : float, the grid's step, s (static)
    smooth_s : float, half the span of the moving average, s (static)
    threshold_sigma : float, the direction plays' width in noise stds of the averaged reading

    Returns
    -------
    (k, m) array in [-1/2, 1/2]
    """
    k = z.shape[0]
    span = max(1, int(round(smooth_s / dt)))
    n_avg = 2 * span + 1
    za = _moving_average(z, span)
    white = _mad_std(jnp.diff(z, 3, axis=0), 20.0) / math.sqrt(n_avg)
    if k >= 4 * n_avg:
        coarse = _mad_std(jnp.diff(za[::n_avg], 3, axis=0), 20.0)
        sigma = jnp.maximum(white, coarse)
    else:
        sigma = white
    half = 0.5 * threshold_sigma * jnp.maximum(sigma, 1e-12)
    d_prev = _play_direction(za, half, reverse=False)
    # against time, a move up is a fall of the reading ahead: the next move's direction
    d_next = -_play_direction(za, half, reverse=True)
    idx = jnp.broadcast_to(jnp.arange(k)[:, None], z.shape)
    turn = (d_prev != 0) & (d_next != 0) & (d_prev != d_next)
    # the run of turning samples around each one (running max / min by associative scans)
    last = jax.lax.associative_scan(jnp.maximum, jnp.where(turn, -1, idx), axis=0)
    nxt = jax.lax.associative_scan(jnp.minimum, jnp.where(turn, k, idx), axis=0, reverse=True)
    tau = (idx - last - 0.5) / jnp.maximum(nxt - last - 1, 1)
    agree = 0.5 * jnp.where(d_prev != 0, d_prev, d_next)
    return jnp.where(turn, d_prev * (0.5 - tau * tau), agree)


#: the form's own relative error of the width (one standard deviation), added in quadrature to
#: the fit's in the reported interval: the flat stretches and minor loops of the regressor are
#: estimated from noisy data (the model's force on the cell,
#: :mod:`cdprid.diagnosis._hysteresis`). Measured over the 4-, 6- and 8-cable robots of
#: ``benchmarks/diagnosis.py`` (widths 0.5-4 N, session 11): named widths 0.84-1.05 of the
#: truth, mean 0.96, spread 0.05, while the fit's own 95 % intervals held the truth in 9 of 15
FORM_REL_STD = 0.07


def _interval(lo, hi, extra) -> dict:
    """The width's 95 % interval: the fit's widened by :data:`FORM_REL_STD` of the width."""
    c, hw = 0.5 * (float(lo[0]) + float(hi[0])), 0.5 * (float(hi[0]) - float(lo[0]))
    hw = math.hypot(hw, 1.959963984540054 * FORM_REL_STD * abs(c))
    return {"width_N": [c - hw, c + hw]}


def play_regressor(x, width_N: float, dt: float, smooth_s: float = SMOOTH_S) -> np.ndarray:
    """The hysteresis regressor of a known force on the cell: ``h = (x_s - P_w[x_s]) / w``,
    ``x_s`` the force averaged over ``2 smooth_s`` as :func:`reversal_regressor` averages the
    reading, ``P_w`` :func:`play_operator` of width ``w = width_N``.

    Parameters
    ----------
    x : array_like (k,)
        The force on the cell on a uniform grid, N.
    width_N : float
        The play's width, N (> 0).
    dt : float
        The grid's step, s.
    smooth_s : float
        Half the span of the moving average, s.

    Returns
    -------
    ndarray (k,) in [-1/2, 1/2]
    """
    span = max(1, int(round(smooth_s / dt)))
    xs = np.asarray(_moving_average(jnp.asarray(x, float)[:, None], span))[:, 0]
    return (xs - play_operator(xs, width_N)) / width_N


_REGRESSOR_JIT = jax.jit(reversal_regressor, static_argnums=(1, 2))


def hysteresis_regressor(z, dt: float):
    """:func:`reversal_regressor` of a whole tension stream ``z`` (k, m) on its uniform grid of
    step ``dt`` (s), compiled (once per stream shape and step) and evaluated once: what the
    diagnosis keeps with its data so that its models do not run the two plays' scans at every
    evaluation.

    Parameters
    ----------
    z : array_like (k, m)
        Load-cell readings on a uniform grid, N.
    dt : float
        The grid's step, s.

    Returns
    -------
    jax.Array (k, m) in [-1/2, 1/2]
    """
    return _REGRESSOR_JIT(jnp.asarray(z), float(dt))


def _hysteresis_model(y, d, q):
    """Model side (diagnosis): ``W y_reading = Y x - sum_i W_i w_i h_i`` (x = y + w h)."""
    from cdprid.model import wrench_matrix

    # (k, m) on the tension grid: computed once with the data (a scan over the stream)
    H = reversal_regressor(d.tau_grid, d.tau_dt) if d.hyst_h is None else d.hyst_h
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
        stream="tensions",
        model=_hysteresis_model, bounds={"width_N": 100.0}, nonneg=("width_N",),
        interval=_interval, cell_play=True,
        separated_by={
            "time_delay": "a trajectory with reversals at several tension rates (a clock "
                          "offset grows with the rate, the play's step does not; only this "
                          "cell lags)",
            "pulley_friction": "motion where the tension reverses while the cable keeps its "
                               "direction (friction follows the cable's speed, hysteresis the "
                               "tension's rate)",
        }),
)
