"""The hysteretic load cell's regressor from the model's force on the cell (issue 37).

The ``load_cell_hysteresis`` form first sees the reading only
(:func:`cdprid.effects.reversal_regressor`): where the reading moves and where it stays flat.
A reversal of the force inside the band (a minor loop) never moves the reading, so that form
cannot see it and the width reads low where the tension often reverses by less than the width:
0.5-0.9 of the truth on the slow 4- and 8-cable test robots of ``benchmarks/diagnosis.py``
(100 Hz, 0.7 N, tension rates of 4-10 N/s), the widest bands lowest.

Once a hysteretic cell is in the model, the rest of the model tells what the cell felt. With
``y`` the reading behind the measured side and ``x`` the force on the cell, the residual of the
model without that cell's play is ``W_i (P_w[x] - x)`` plus noise (every other cable and the
dynamics are in the model): projected on the cable's column ``W_i`` it gives ``x - y``, so
``x~ = y + c`` is the force on the cell, minor loops included, with the noise of the whole
residual. The play of the current width on ``x~`` (averaged as the reading-only form averages
the reading) gives ``h = (x~ - P_w[x~]) / w``, the regressor the form then uses in place of the
reading-only one; the model is refitted and the step repeated (the width moves the flat
stretches: three passes). The least-squares widths of this regressor against the true force on
the cell, on the simulator's readings of those robots with the true model's residual: 0.90-1.04
of the truth after three passes (0.5-0.9 from the reading alone).
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.core import TensionStream, tension_at
from cdprid.diagnosis._model import model_jit
from cdprid.diagnosis._problem import Problem, measured
from cdprid.diagnosis._profile import clock_index
from cdprid.diagnosis._selection import Selection, refit, with_vocabulary
from cdprid.effects import DIAGNOSIS, hysteresis_regressor, play_regressor

#: the effects whose regressor this module refines (a play on one load cell's reading)
PLAYS = tuple(name for name, form in DIAGNOSIS.items() if form.cell_play)

#: passes of (regressor from the model's force on the cell, refit)
PASSES = 3

#: the ``unexplained`` stage's structure signal of a direction-dependent load cell
TENSION_RATE_SIGNAL = "sign of tension rate"


def force_on_cell(prob: Problem, s: Selection, effect: str, cable: int) -> np.ndarray:
    """The force on the load cell of ``cable`` (1-based) on the tension grid, in the
    reading's units: the raw reading plus the projection on the cable's column of the
    residual of the model ``s`` without that cell's play ``effect`` (matched-filtered), N,
    ``(k,)``."""
    lay = prob.layout
    i = cable - 1
    th = np.asarray(s.theta, float)
    (j,) = lay.candidate_indices(effect, cable)
    th0 = th.copy()
    th0[j] = 0.0
    xin = np.asarray(s.x if s.rotational else s.x[:4], float)
    mod0 = np.asarray(model_jit(prob.d, jnp.asarray(th0), jnp.asarray(xin), lay, s.rotational))
    r = prob.filt(measured(prob, th) - mod0)  # (n, 6) = W_i (P_w[x] - x) + noise
    Wi = prob.W_all[:, :, i]
    c = -np.einsum("nk,nk->n", r, Wi) / np.einsum("nk,nk->n", Wi, Wi)
    # a pose sample at t reads the tension grid at t + delay (the forward model's interpolant):
    # c onto the grid by the core's linear interpolant (pose times: uniform but at the joins
    # of a budgeted subset, which linear interpolation reads as they are)
    at_pose = TensionStream(jnp.asarray(prob.t), jnp.asarray(c[:, None]), float(prob.t[0]),
                            float(prob.dt))
    grid = np.asarray(prob.d.stream.t)
    on_grid = np.asarray(tension_at(at_pose, jnp.asarray(grid - _delay(prob, th)), "linear"))
    return prob.tau_grid[:, i] + on_grid[:, 0]


def _delay(prob: Problem, theta) -> float:
    """The model's clock offset at ``theta``, s."""
    return float(np.asarray(prob.layout.unpack(jnp.asarray(theta))["delay"]))


def model_regressor(prob: Problem, s: Selection, effect: str, cable: int
                    ) -> np.ndarray | None:
    """``h = (x~ - P_w[x~]) / w`` on the tension grid (:func:`cdprid.effects.play_regressor`
    of :func:`force_on_cell`), w the model's current width of that cell; None when it is 0."""
    (j,) = prob.layout.candidate_indices(effect, cable)
    w = float(s.theta[j])
    if not w > 0.0:
        return None
    return play_regressor(force_on_cell(prob, s, effect, cable), w, prob.tdt)


def refine_hysteresis(prob: Problem, s: Selection, extra, say=None, passes: int = PASSES,
                      done: tuple = ()) -> tuple[Problem, Selection]:
    """The model's hysteretic cells with their regressor from the model's force on the cell.

    For every ``load_cell_hysteresis`` finding of ``s``, :data:`PASSES` times: the regressor
    of that cable from :func:`model_regressor`, then the selection refitted (the clock offset,
    when in the model, held but in the last pass, where it is profiled jointly as in every
    refit). The other cables keep the reading-only form (the candidates the later stages
    try).

    Parameters
    ----------
    prob : Problem
    s : Selection
    extra : DiagnosisContext
        For the findings' parameters and intervals.
    say : callable, optional
        Progress messages.
    passes : int
    done : tuple of int
        Cables already refined: refined again only when a new one is in the model.

    Returns
    -------
    (Problem, Selection)
        The problem whose data carry the refined regressor (a new one: its linearisations
        computed again, its cable side kept), and the refitted selection; ``(prob, s)``
        unchanged without a hysteretic finding.
    """
    plays = [(c.effect, c.cable) for c in s.accepted if c.effect in PLAYS]
    cables = [cable for _, cable in plays]
    if not cables or set(cables) <= set(done):
        return prob, s
    di = clock_index(prob)
    for k in range(passes):
        H = np.array(prob.d.hyst_h)
        changed = False
        for effect, cable in plays:
            h = model_regressor(prob, s, effect, cable)
            if h is not None:
                H[:, cable - 1] = h
                changed = True
        if not changed:
            break
        d = eqx.tree_at(lambda dd: dd.hyst_h, prob.d, jnp.asarray(H))
        # the cable side (measured side, its Jacobian, the geometry) does not read the
        # regressor, the model side does: only the linearisations are stale
        kept = {kind: dict(v) for kind, v in prob.cache.items() if kind != "design"}
        prob = dataclasses.replace(prob, d=d, cache=kept, hysteresis_refined=tuple(cables))
        if k < passes - 1 and di is not None and di in s.active_idx:
            # the clock offset held between passes (its joint profile is most of a refit's
            # time), profiled again with everything else in the last pass
            held = refit(prob, s, active_idx=tuple(i for i in s.active_idx if i != di))
            s = dataclasses.replace(held, active_idx=s.active_idx)
        else:
            s = with_vocabulary(prob, refit(prob, s), extra)
    if say is not None:
        say("hysteresis: the regressor of cable(s) " + ", ".join(str(c) for c in cables)
            + " from the model's force on the cell")
    return prob, s


def direction_feature(prob: Problem, s: Selection) -> np.ndarray:
    """``W_i sign(dtau_i/dt)`` per cable ``(n, 6, m)``: a force along each cable that flips
    with the direction of its tension (the reading a hysteretic cell or any cell that lags
    its force would leave). The direction is that of the reading's last or next move found by
    :func:`cdprid.effects.reversal_regressor` (the reading-only form; the sign of a
    differentiated stream is noise where the tension changes by a few N/s), at the pose times
    shifted by the model's clock offset (the core's linear interpolant). The ``unexplained``
    stage tests it like its other structure signals (:data:`TENSION_RATE_SIGNAL`)."""
    stream = prob.d.stream
    H = hysteresis_regressor(prob.d.tau_grid, prob.tdt)
    h = tension_at(TensionStream(stream.t, H, stream.t0, stream.dt),
                   jnp.asarray(prob.t + _delay(prob, s.theta)), "linear")
    return prob.W_all * np.sign(np.asarray(h))[:, None, :]
