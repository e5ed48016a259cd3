"""A push's residual is not a load cell's error (issue 38): the hysteresis band positions of the
scan's null model must not take it for one.

The band position of a hysteretic cell comes from its tension corrected by the wrench balance
(``tau_j = y_j - err_j - W_j . r / |W_j|^2``). During a push the residual ``r`` is the push:
the correction moves the tension by the push's share and back, the play operator turns at
the top, and its state stays wrong after the push until the force's next full reversal
(on the floor-winch robot of ``tests/_testbench`` with pushes and glitches: a false 1 N
episode seconds later). With the push's samples marked ``quiet`` the band is the one the
cell's own reading gives, exactly."""

from __future__ import annotations

import numpy as np


def _cells():
    from cdprid.effects import play_operator
    from cdprid.episodes._null import cells

    t = np.arange(0.0, 20.0, 0.01)
    tau = 60.0 + 12.0 * np.sin(2 * np.pi * 0.05 * t)  # a slow rise, its top near 5 s
    reading = np.column_stack([play_operator(tau, 3.0), np.full(len(t), 40.0)])
    W = np.zeros((len(t), 6, 2))
    W[:, 0, 0] = 1.0
    W[:, 1, 1] = 1.0
    c = cells(W, np.zeros((len(t), 6)), reading, 0.01, ((0, len(t)),), lambda x: x)
    return t, c


def test_push_residual_left_out_of_the_band_positions():
    from cdprid.episodes._null import band_positions, n_columns

    t, c = _cells()
    m = 2
    coef = np.zeros(n_columns(c))
    coef[2 * m] = -1.5  # cable 1: half-width 1.5 N (band 3 N)
    rows = np.ones(6, bool)
    push = (t >= 4.0) & (t < 5.0)
    r = np.zeros((len(t), 6))
    r[push, 0] = -8.0  # a push of 8 N along cable 1's direction: the residual is minus it
    ref = band_positions(c, coef, np.zeros_like(r), rows)
    taken = band_positions(c, coef, r, rows)
    quiet = band_positions(c, coef, r, rows, quiet=push)
    after = (t >= 5.0) & (t < 9.0)
    # taken for the cell's error, the push turns the play operator: wrong for seconds after
    assert np.mean(np.abs(taken[after, 0] - ref[after, 0])) > 0.5
    assert np.array_equal(quiet, ref)
