"""The free motion's regression rows, its pushes located by the energy balance, and its
consistency over time (``identify --source free-motion``).

**Rows: project, then filter.** The locked cables' tensions act only along ``range(W)``; at
every sample ``N_n^T S Z_n x = 0`` holds exactly (``N_n`` the free directions,
:func:`cdprid.identify._free_motion.free_directions`). The rows are built from accurate rates
(central differences exact to degree 5, :func:`cdprid.identify._free_rates.free_rates`: the
core's second-order stencils biased a 100 Hz recording's parameters by up to 1 %) at the
measured poses, projected,
and only then passed through the differentiator's zero-phase low-pass ``F``:
``F[N^T S Z] x = F[0] = 0``, exact for any filter. The earlier rows projected the
matched-filtered regressor, ``N^T F[S Z] x = N^T F[S W tau]``, which is not zero (``F`` does not
commute with the pose-dependent ``N`` and ``W``): a bias that grows as the cutoff falls
(``docs/drives.md``, "Measured").

**Pushes.** A hand pushing the platform acts in the free directions, exactly what the fit
reads (on simulated recordings a push-laden fit doubled z_G). The episodes stage
(:func:`cdprid.episodes.find_episodes`, the load cells' wrench residual and the energy balance)
locates them when tensions are recorded; the caller leaves them out. (Tried and dropped: the
energy test on the free motion's own estimate, without tensions, flagged 80 % of a simulated
recording even from a good estimate.)

**Consistency.** :func:`window_disagreement` fits the kept samples' thirds apart: a push no
test located (one that only slows a swing, or any recording without tensions) makes them
disagree.
"""

from __future__ import annotations

import numpy as np

from cdprid.base import InputError
from cdprid.core import (
    choose_cutoff,
    least_squares_blocks,
    noise_levels,
    regressors,
    wrench_matrices,
)
from cdprid.identify._free_rates import free_rates
from cdprid.signal import acceleration_filter

__all__ = ["free_directions", "projected_regressor", "projected_filtered_rows", "fit_rows",
           "window_disagreement", "widen_cutoff", "WIDEN", "com_over_thirds"]

#: the free motion's data-chosen cutoff may reach WIDEN times the core grid's widest (4 Hz)
WIDEN = 4.0

#: window disagreement (combined std) beyond which the command warns
WINDOW_Z = 3.0


def free_directions(W, radius: float) -> np.ndarray:
    """Orthonormal bases ``N`` (n, 6, 6 - m) of the null space of ``S W`` transposed, with
    ``S = diag(1, 1, 1, 1/radius, ...)`` (moments in newtons at the platform's radius), so
    that ``N^T S W = 0``.

    Parameters
    ----------
    W : (n, 6, m) wrench matrices, m < 6
    radius : float
        Platform radius, m.
    """
    S = np.array([1.0] * 3 + [1.0 / radius] * 3)
    U = np.linalg.svd(S[None, :, None] * np.asarray(W), full_matrices=True)[0]
    return U[:, :, W.shape[2]:]


def projected_regressor(Z, W, radius: float) -> np.ndarray:
    """``N^T S Z`` (n, 6 - m, p): the regressor on the free directions (:func:`free_directions`).

    Parameters
    ----------
    Z : (n, 6, p) the Newton-Euler regressor (``W tau = Z x``)
    W : (n, 6, m) wrench matrices
    radius : float
        Platform radius, m.
    """
    S = np.array([1.0] * 3 + [1.0 / radius] * 3)
    return np.matmul(free_directions(W, radius).transpose(0, 2, 1), S[None, :, None] * Z)


def projected_filtered_rows(robot, sig, motion, model: str, params: dict, rho: float,
                            chunk: int) -> np.ndarray:
    """``F[N^T S Z]`` (n, 6 - m, p) at every aligned sample (see the module docstring).

    Parameters
    ----------
    robot : CableRobot
    sig : AlignedSignals
        Its positions and quaternions (the measured poses).
    motion : Motion
        The differentiator's motion (its segments; rates come from central differences).
    model : {"translation", "full"}
    params : dict
        The euler-filtfilt parameters (``cutoff_hz``, ``order``).
    rho : float
        Platform radius, m (moments weighed as forces at that radius).
    chunk : int
        Samples per block.

    Returns
    -------
    ndarray (n, 6 - m, p)
    """
    a, om, al = free_rates(motion, sig.quaternion)
    if model != "full":
        om, al = np.zeros_like(om), np.zeros_like(al)
    n, g = len(sig.t), np.asarray(robot.gravity, float)
    out = None
    for i0 in range(0, n, chunk):
        i1 = min(n, i0 + chunk)
        R = motion.B_R_P[i0:i1]
        Z = np.asarray(regressors(model, R, a[i0:i1], om[i0:i1], al[i0:i1], g))
        W = np.asarray(wrench_matrices(robot, sig.position[i0:i1], R))
        P = projected_regressor(Z, W, rho)
        if out is None:
            out = np.empty((n,) + P.shape[1:])
        out[i0:i1] = P
    flat = out.reshape(n, -1)
    for s0, s1 in motion.segments:
        flat[s0:s1] = acceleration_filter(flat[s0:s1], sig.dt, "euler-filtfilt", **params)
    return flat.reshape(out.shape)


def fit_rows(P, idx, ref_i: int, names, chunk: int):
    """Least squares with HAC covariance of ``P[idx] x = 0`` with ``x[ref_i] = 1``.

    Parameters
    ----------
    P : (n, k, p) rows
    idx : (n_kept,) the samples fitted
    ref_i : int
        The reference parameter's index.
    names : tuple of str
    chunk : int

    Returns
    -------
    LSResult (without the reference parameter)
    """
    o = np.delete(np.arange(P.shape[2]), ref_i)

    def rows(i0, i1):
        Z = P[idx[i0:i1]]
        return Z[:, :, o], -Z[:, :, ref_i]

    return least_squares_blocks(rows, len(idx), tuple(names[k] for k in o),
                                covariance="hac", chunk=int(chunk))


def window_disagreement(P, idx, ref_i: int, names, chunk: int, t,
                        value: float) -> tuple[list, float]:
    """How far the kept samples' thirds (in time) disagree: one warning when two differ by more
    than :data:`WINDOW_Z` combined std in some parameter (pushes not located, a drift), and
    the Birge ratio ``R2`` (>= 1): the thirds' chi-squared about their inverse-variance mean,
    per degree of freedom, over the parameters. The caller multiplies the covariance by it,
    so that the std covers the spread the thirds show (unmodelled forces vary in time; noise
    alone gives ``R2`` near 1).

    Parameters
    ----------
    P, idx, ref_i, names, chunk : as in :func:`fit_rows`
    t : (n,) times, s
    value : float
        The reference's value (the estimates are scaled by it).

    Returns
    -------
    list of str (empty or one sentence), float R2
    """
    parts = np.array_split(idx, 3)
    if min(len(p) for p in parts) < 20 * P.shape[2]:
        return [], 1.0
    fits = []
    for part in parts:
        try:
            fits.append(fit_rows(P, part, ref_i, names, chunk))
        except InputError:
            return [], 1.0
    x = np.array([f.x for f in fits])
    v = np.array([np.diag(f.cov) for f in fits]) + 1e-300
    mean = np.sum(x / v, 0) / np.sum(1.0 / v, 0)
    r2 = max(1.0, float(np.mean(np.sum((x - mean) ** 2 / v, 0) / 2.0)))
    worst = (0.0, 0, 0, 0)
    for i in range(3):
        for j in range(i + 1, 3):
            z = np.abs(x[i] - x[j]) / np.sqrt(v[i] + v[j])
            k = int(np.argmax(z))
            if z[k] > worst[0]:
                worst = (float(z[k]), i, j, k)
    zmax, i, j, k = worst
    if zmax <= WINDOW_Z:
        return [], r2
    win = [f"{t[p[0]]:.1f}-{t[p[-1]]:.1f} s" for p in parts]
    return [f"the estimate depends on the time window: {fits[0].names[k]} is "
            f"{value * x[i, k]:.4g} over {win[i]} and {value * x[j, k]:.4g} over {win[j]} "
            f"({zmax:.1f} combined std): outside forces no test located (a push that only "
            "slows a swing, contact, drag) or a drift bias the fit; the covariance is scaled "
            f"by the thirds' spread (x {r2:.2g}), which may still not cover a bias they share. "
            "Use a push-free release, or --t-start/--t-end on a window you trust."], r2


def com_over_thirds(P, idx, ref_i: int, names, chunk: int, t) -> str | None:
    """One sentence with the centre of mass's height ``z_G`` fitted on each time third of the
    kept samples (with its HAC std), or None when the model has no ``mzG`` or the reference
    is not the mass: how much the data decide ``z_G`` beyond the pooled std.

    Parameters
    ----------
    P, idx, ref_i, names, chunk : as in :func:`fit_rows`
    t : (n,) times, s
    """
    if "mzG" not in names or ref_i != 0 or names[0] != "m":
        return None
    parts = np.array_split(idx, 3)
    if min(len(p) for p in parts) < 20 * P.shape[2]:
        return None
    out = []
    for part in parts:
        try:
            f = fit_rows(P, part, ref_i, names, chunk)
        except InputError:
            return None
        k = list(f.names).index("mzG")
        out.append((t[part[0]], t[part[-1]], f.x[k], np.sqrt(max(f.cov[k, k], 0.0))))
    z = [o[2] for o in out]
    spans = "; ".join(f"{a:.1f}-{b:.1f} s: {c:.4f} +- {d:.4f} m" for a, b, c, d in out)
    return (f"the time thirds give z_G {spans}: spread {max(z) - min(z):.4f} m "
            f"({100 * (max(z) - min(z)) / abs(np.mean(z)):.0f} % of their mean)")


def widen_cutoff(ds, sig, params: dict, notes: list) -> dict:
    """The data-chosen cutoff on a grid ``WIDEN`` times wider (4-16 Hz) when the core's grid
    (1-4 Hz, :func:`cdprid.core.choose_cutoff`) stopped at its cap.

    The core's grid was set for the tension path; a free swing on short locked cables moves
    faster (UACDPR: 1.6-2.2 Hz, its second harmonic at 3.3-3.9 Hz, angular accelerations up
    to 5.6 Hz), and a 4 Hz zero-phase low-pass halves the harmonic: the fit loses the rows
    that carry z_G while the forces it lacks (a hand braking the swing) are slow and stay. The
    free-motion rows are exact for any cutoff (``F[N^T S Z] x = 0``), so only the same
    errors-in-variables budget limits it. The wider grid is the core's on a time axis
    stretched ``WIDEN`` times: the budget's ratio (noise over signal power of the second
    differences) is invariant under ``dt -> k dt`` with ``f -> f / k``, so
    ``WIDEN * choose_cutoff(x, q, WIDEN * dt).cutoff_hz`` is the widest cutoff of
    ``{4, 5, ..., 16}`` Hz within the budget.

    Parameters
    ----------
    ds : Dataset
        Its tensions (or a placeholder) for :func:`cdprid.core.noise_levels`.
    sig : AlignedSignals
    params : dict
        The parameters with the core's data-chosen ``cutoff_hz``.
    notes : list
        Its last sentence (the core's choice) is replaced when the cutoff is widened.

    Returns
    -------
    dict
        ``params``, ``cutoff_hz`` widened when the wider grid allows it.
    """
    _, _, s_pos, s_rot = noise_levels(ds, sig)
    rot = sig.quaternion if sig.has_rotation else None
    segs = getattr(sig, "segments", ()) or ((0, len(sig.t)),)
    c = choose_cutoff(sig.position, rot, WIDEN * sig.dt, segs, s_pos, s_rot)
    wide = WIDEN * c.cutoff_hz
    if not c.within_budget or wide <= float(params["cutoff_hz"]):
        return params
    r = ", ".join(f"{k} {v:.1e}" for k, v in c.ratio.items())
    notes[-1] = (f"differentiator bandwidth chosen from the data: cutoff {wide:g} Hz, the widest "
                 f"of 1-{4 * WIDEN:g} Hz with a predicted errors-in-variables attenuation below "
                 f"1e-03 (noise over signal power: {r}); the free-motion rows are exact for any "
                 "cutoff, and a swing at a few hertz needs the wider grid (set --params "
                 "cutoff_hz to override)")
    return dict(params, cutoff_hz=wide)
