"""The episodes stage: fit, locate what happens only sometimes, refit without it, locate again.

:func:`find_episodes` works on a recording's aligned signals (:func:`cdprid.io.align`) and
the robot; ``identify`` and ``diagnose`` call it before their fits and leave the samples of
:attr:`Episodes.excluded` out (the blocks keep their own time stamps; nothing is bridged).

1. Pose glitches (:mod:`cdprid.episodes._glitches`) are found on the raw positions (and
   orientations).
2. The motion is differentiated (``euler-filtfilt`` at ``cutoff_hz``) and the measured wrench
   ``W tau`` and each cable's column of W go through the same zero-phase filter (matched).
3. The paper's model (the full model when the platform rotates) plus the load-cell effects
   that persist over the whole recording (:mod:`cdprid.episodes._null`: per cable a zero
   offset, Coulomb friction on its pulley, a hysteretic band, a relative gain and a slowly
   drifting zero, and one clock offset; a few columns per cable, their hysteresis columns
   from a first fit) is fitted by least squares on the samples outside the episodes,
   whitened by the residual's noise model, the persistent columns' coefficients held near
   their fit on every usable sample outside the episodes by a ridge (:data:`PERSISTENT_RIDGE`; the energy test of
   step 4 takes the rigid body fitted alone); the residual is scanned
   (:mod:`cdprid.episodes._scan`) at the stated false-alarm rate; each flagged stretch is
   refined to the interval where a constant wrench explains the most. Repeated until the
   episodes stop changing (at most :data:`PASSES` passes).
   Samples where a cable reads below ``TAUT_THRESHOLD_N`` (and the matched filter's
   transient around them) are not scanned: a slack cable is not the straight taut line of
   the wrench model, and its snap is not an outside wrench.
4. When the winches are locked, the energy balance is a second, independent test
   (:mod:`cdprid.episodes._energy`): outside work where the energy rises (a push), and
   where it falls faster than the passive losses fitted on the recording take it (a hand
   that stops the platform; ``energy_J`` < 0).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdprid.base import (
    CUTOFF_HZ,
    TAUT_THRESHOLD_N,
    TRIM_S,
    InputError,
    chi2_sf,
)
from cdprid.core import (
    ROTATION_WARN_DEG,
    estimate_motion,
    regressor_blocks,
    rotation_angle_deg,
    segment_mask,
    wrench_matrix_series,
)
from cdprid.effects import EXTERNAL_WRENCH
from cdprid.episodes._energy import (
    braking_runs,
    energy_runs,
    locked,
    mechanical_energy,
    outside_work,
    winch_power,
)
from cdprid.episodes._glitches import find_glitches
from cdprid.episodes._null import cells, persistent_null, speed_noise
from cdprid.episodes._scan import (
    SCALES_S,
    filter_autocorrelation,
    locate,
    noise_model,
    robust_whitening,
    runs,
    window_level,
)
from cdprid.signal import zero_phase_filter

__all__ = ["FAR_PER_HOUR", "PASSES", "Episode", "Episodes", "find_episodes"]

#: default false-alarm rate of the scan, episodes per hour of clean recording
FAR_PER_HOUR = 0.5
#: fit -> locate -> refit passes at most
PASSES = 3
#: the robust fit leaves out samples beyond this many robust std (MAD) in any row
REJECT_SIGMAS = 5.0
#: episodes covering more than this share of the scanned samples are not local in time: the
#: robust fit (median and MAD) breaks down at half the samples, beyond which the null is not
#: what most of the recording follows
MAX_SHARE = 0.5
#: share of an episode's mean residual one load cell's column must explain to be a step
STEP_SHARE = 0.95
#: ridge on the persistent columns' coefficients (:mod:`cdprid.episodes._null`) toward their
#: fit on every usable sample outside the episodes found so far (the glitches' stretches
#: included, each glitch's core, half the filter's transient on each side, left out), in units
#: of each column's whitened squared norm on the fit's samples: where the fit's samples
#: determine a combination of them by less than this share of a column's information, it
#: stays at that value. On a redundant robot the cells' offsets, gains and drifts along the
#: internal-force directions (tensions W maps to nothing) are nearly collinear; leaving a
#: glitch's stretch out moved them by up to 4 N and left a local 1 N shift beside the
#: stretch: false episodes on the floor-winch robot with glitches (results/episodes-combined.md;
#: 0.1 and 0.03 gave a 0.5 N one beside a glitch of the 16 s rotating 8-cable recording of
#: tests/episodes/test_episodes.py, whose four glitches are a quarter of it)
PERSISTENT_RIDGE = 0.01


@dataclasses.dataclass(frozen=True)
class Episode:
    """One time window where the data contradict the model locally.

    Attributes
    ----------
    start_s, end_s : float
        The window, s (the recording's clock).
    kind : str
        ``external_wrench``, ``load_cell_step``, ``pose_glitches`` or ``energy``.
    force_N, moment_Nm : tuple of 3 floats or None
        Mean external wrench on the platform over the window (base frame, moment about P):
        minus the mean residual of the model.
    size_N, size_Nm : float or None
        Their norms.
    p_value : float
        Adjusted for the number of windows scanned (Bonferroni; 0 when below 1e-300).
    detail : dict
        Kind-specific: ``cable`` and ``step_N`` of a load-cell step, ``n_samples`` and
        ``largest_m`` of glitches, ``energy_J`` of an energy episode (the outside work, J:
        negative where a hand takes energy out faster than the passive losses).
    """

    start_s: float
    end_s: float
    kind: str
    force_N: tuple | None
    moment_Nm: tuple | None
    size_N: float | None
    size_Nm: float | None
    p_value: float
    detail: dict = dataclasses.field(default_factory=dict)

    def as_json(self) -> dict:
        """The JSON form (the ``episodes`` list of ``identify --json`` and ``diagnose --json``).

        Returns
        -------
        dict
            ``start_s``, ``end_s`` (s), ``kind``, ``force_N`` (3 floats, N, or None),
            ``moment_Nm`` (3 floats, N m, or None), ``size_N``, ``size_Nm``, ``p_value``,
            and the kind's :attr:`detail` keys.
        """
        out = {"start_s": self.start_s, "end_s": self.end_s, "kind": self.kind,
               "force_N": list(self.force_N) if self.force_N is not None else None,
               "moment_Nm": list(self.moment_Nm) if self.moment_Nm is not None else None,
               "size_N": self.size_N, "size_Nm": self.size_Nm, "p_value": self.p_value}
        out.update(self.detail)
        return out

    def describe(self) -> str:
        """One line: when, what, how large.

        Returns
        -------
        str
            E.g. ``external_wrench 12.01-13.95 s: 14.2 N, 0.31 N m (p = 2.0e-09)``.
        """
        what = {"pose_glitches": f"{self.detail.get('n_samples', 0)} displaced pose sample(s), "
                                 f"up to {1e3 * self.detail.get('largest_m', 0.0):.0f} mm",
                "energy": f"{self.detail.get('energy_J', 0.0):+.2g} J of outside work"}.get(
            self.kind, f"{self.size_N:.3g} N, {self.size_Nm:.3g} N m" if self.size_N is not None
            else "")
        if self.kind == "load_cell_step":
            what = f"load cell {self.detail['cable']} reads {self.detail['step_N']:+.3g} N more"
        return (f"{self.kind} {self.start_s:.2f}-{self.end_s:.2f} s: {what}"
                + (f" (p = {self.p_value:.1e})" if self.kind != "pose_glitches" else ""))


@dataclasses.dataclass(frozen=True)
class Episodes:
    """What :func:`find_episodes` found.

    Attributes
    ----------
    episodes : tuple of Episode
        In time order.
    t : ndarray (n,)
        The aligned samples' times, s.
    excluded : ndarray (n,) of bool
        Samples every fit leaves out: each episode widened by the filter's transient
        (``margin_s``) on both sides, each glitch likewise.
    margin_s : float
    far_per_hour : float
        The false-alarm rate the thresholds were set for.
    passes : int
        Fit -> locate passes run.
    caveat : str or None
        Why no wrench episode is reported although the scan flagged some.
    """

    episodes: tuple
    t: np.ndarray
    excluded: np.ndarray
    margin_s: float
    far_per_hour: float
    passes: int
    caveat: str | None = None

    def excluded_at(self, t) -> np.ndarray:
        """Whether each time of ``t`` (s) is within an excluded stretch.

        Parameters
        ----------
        t : array_like
            Times, s (the recording's clock).

        Returns
        -------
        ndarray of bool, the shape of ``t``
        """
        t = np.asarray(t, float)
        out = np.zeros(t.shape, bool)
        for a, b in runs(self.excluded):
            out |= (t >= self.t[a] - 1e-9) & (t <= self.t[b - 1] + 1e-9)
        return out

    def note(self) -> str | None:
        """The sentence for a fit's notes.

        Returns
        -------
        str or None
            How many episodes of which kinds were left out, and the caveat; the caveat
            alone (or None) when nothing was found.
        """
        if not self.episodes:
            return self.caveat
        kinds = sorted({e.kind for e in self.episodes})
        return (f"{len(self.episodes)} episode(s) ({', '.join(kinds)}) left out of the fit: "
                f"{int(self.excluded.sum())} samples ({self.margin_s:g} s of filter transient "
                "on each side; nothing bridged); --keep-episodes keeps them"
                + (f"; {self.caveat}" if self.caveat else ""))

    def retimed(self, clock) -> Episodes:
        """The same episodes with their times mapped by ``clock`` (s -> s), e.g. from the
        joined axis of a budgeted subset to the recording's own clock (``t`` and
        ``excluded`` stay on the analysed samples).

        Parameters
        ----------
        clock : callable
            ``clock(s) -> s``, applied to every episode's ``start_s`` and ``end_s``.

        Returns
        -------
        Episodes
        """
        eps = tuple(dataclasses.replace(e, start_s=clock(e.start_s), end_s=clock(e.end_s))
                    for e in self.episodes)
        return dataclasses.replace(self, episodes=eps)

    def as_json(self) -> list:
        """The ``episodes`` list.

        Returns
        -------
        list of dict
            :meth:`Episode.as_json` of each episode, in time order.
        """
        return [e.as_json() for e in self.episodes]


def _dilate(mask: np.ndarray, k: int) -> np.ndarray:
    if k <= 0 or not mask.any():
        return mask.copy()
    c = np.concatenate([[0], np.cumsum(mask.astype(int))])
    n = len(mask)
    i = np.arange(n)
    return (c[np.minimum(n, i + k + 1)] - c[np.maximum(0, i - k)]) > 0


def _filtered(x, sig, cutoff_hz):
    """Zero-phase filter of ``x`` (n, ...) along time, each segment on its own."""
    x = np.asarray(x, float)
    out = np.empty_like(x)
    flat = x.reshape(len(x), -1)
    for a, b in sig.segments:
        out.reshape(len(x), -1)[a:b] = zero_phase_filter(flat[a:b], sig.dt, cutoff_hz, 2)
    return out


def _data(robot, sig, cutoff_hz):
    """Filtered measured wrench (n, 6), regressor with offset columns (n, 6, p + m), model."""
    rot = sig.has_rotation and rotation_angle_deg(sig.quaternion) > ROTATION_WARN_DEG
    model = "full" if rot else "translation"
    mo = estimate_motion(sig, "euler-filtfilt", {"cutoff_hz": cutoff_hz}, angular=rot)
    W = wrench_matrix_series(robot, np.asarray(mo.position), np.asarray(mo.B_R_P))
    Wf = _filtered(W, sig, cutoff_hz)
    y = _filtered(np.einsum("nim,nm->ni", W, sig.tension), sig, cutoff_hz)
    A = regressor_blocks(model, *(np.asarray(x) for x in (
        mo.B_R_P, mo.acceleration, mo.omega, mo.alpha)), np.asarray(robot.gravity))(0, len(W))
    twist = np.concatenate([np.asarray(mo.velocity), np.asarray(mo.omega)], axis=1)
    c = cells(W, twist, sig.tension, float(sig.dt), sig.segments,
              lambda x: _filtered(x, sig, cutoff_hz), np.asarray(sig.t, float),
              speed_noise(sig.position, float(sig.dt), cutoff_hz))
    return y, A, Wf, model, mo, c


def _robust_fit(y, Z, rows, whiten, steps: int = 3, prior=None):
    """:func:`_fit` with the samples whose residual is beyond :data:`REJECT_SIGMAS` robust std
    (the rows' MAD) in any row left out, refitted ``steps`` times: a push must not pull the
    fit (it would leave an offset everywhere else). A step that would fit the same samples
    again is not run (its fit, and every later one, would be the same)."""
    Zw = np.matmul(whiten, Z)  # whitened once for every refit
    r, beta = _fit(y, Z, rows, whiten, prior, Zw)
    used = rows
    for _ in range(steps):
        x = r[rows]
        med = np.median(x, 0)  # a pushed fit is offset elsewhere: centre on the bulk
        mad = 1.4826 * np.median(np.abs(x - med), 0)
        ok = np.all(np.abs(r - med) <= REJECT_SIGMAS * np.maximum(mad, 1e-12), axis=1)
        if (rows & ok).sum() < max(10 * Z.shape[2], rows.sum() // 2):
            break
        if np.array_equal(rows & ok, used):
            break
        used = rows & ok
        r, beta = _fit(y, Z, used, whiten, prior, Zw)
    return r, beta


def _noise_fit(y, Z, rows, whiten, rounds: int = 2, prior=None):
    """:func:`_robust_fit` weighted by its own residual's row covariance: ``rounds`` times the
    robust covariance of the last residual (:func:`robust_whitening`) whitens the next fit.
    Returns ``(residual, beta, whitening)``.

    The scan tests the residual in the noise's own metric; a fit weighted otherwise (e.g. by
    the rows' signal scale, blind to the force-moment correlation of the cells' noise through
    W) projects obliquely in that metric, and its many null columns then carry the noise of
    the well-measured directions into the poorly measured ones, locally, where a column is
    large (on the 8-cable redundant robot: window statistics of 60-150 against a threshold
    of 34 on clean recordings)."""
    r, beta = _robust_fit(y, Z, rows, whiten, prior=prior)
    for _ in range(rounds):
        whiten = robust_whitening(r[rows])[0]
        r, beta = _robust_fit(y, Z, rows, whiten, prior=prior)
    return r, beta, whiten


def _fit(y, Z, rows, whiten, prior=None, Zw=None):
    """Least squares of ``y ~ Z beta`` on ``rows``, whitened (6 x 6); the residual (n, 6).
    ``prior = (beta0 (q,), lam)``: a ridge ``lam |s (beta - beta0)|^2`` on the last q
    coefficients, ``s`` their columns' whitened norms on ``rows`` (:data:`PERSISTENT_RIDGE`).
    ``Zw``: ``whiten @ Z`` when already at hand (several fits with one whitening)."""
    p = Z.shape[2]
    Zw = (np.matmul(whiten, Z) if Zw is None else Zw)[rows].reshape(-1, p)
    yw = (y[rows] @ whiten.T).reshape(-1)
    # normal equations of the scaled columns (p x p, ~10x faster than an SVD of the
    # (6 n, p) matrix); rcond 1e-15 on the Gram matrix is 3e-8 on the singular values. The
    # columns' whitened norms are the root of the Gram's diagonal.
    G, g = Zw.T @ Zw, Zw.T @ yw
    scale = np.sqrt(np.diag(G)).copy()
    scale[scale == 0] = 1.0
    G = G / np.outer(scale, scale)
    g = g / scale
    if prior is not None:
        b0, lam = prior
        q = len(b0)
        G[-q:, -q:] += lam * np.eye(q)  # in the scaled columns' units: lam on the diagonal
        g[-q:] += lam * np.asarray(b0, float) * scale[-q:]
    beta = np.linalg.lstsq(G, g, rcond=1e-15)[0] / scale
    return y - Z @ beta, beta


TAUT_SHARE_MIN = 0.2
"""Below this share of taut samples among the scanned ones the slack ones are scanned too
(e.g. tensions in kN read as N: every sample would be left out and nothing tested)."""


def find_episodes(robot, sig, cutoff_hz: float = CUTOFF_HZ, far_per_hour: float = FAR_PER_HOUR,
                  trim: float = TRIM_S, use=None, lengths=None) -> Episodes:
    """Locate the episodes of a recording (see the module docstring).

    Parameters
    ----------
    robot : CableRobot
    sig : AlignedSignals
        The aligned recording (:func:`cdprid.io.align`), as the fit uses it.
    cutoff_hz : float
        Differentiator and matched-filter cutoff, Hz.
    far_per_hour : float
        False-alarm rate of the scan on clean data, episodes per hour.
    trim : float
        Seconds at the edges of every segment left out (filter transients), s.
    use : ndarray (n,) of bool, optional
        Samples the fit may use at all (e.g. every cable taut); default all.
    lengths : ndarray (n, m), optional
        Winch encoder lengths at the pose times, m: the energy test runs when they stay
        within :data:`cdprid.episodes._energy.LOCKED_RANGE_M`, and the work the cables carry
        away through the winches (tension times reeling rate) is booked. None: the energy
        test runs when the geometric lengths from the poses stay within that range (a freely
        swinging platform on locked winches).

    Returns
    -------
    Episodes
    """
    t = np.asarray(sig.t, float)
    n, dt = len(t), float(sig.dt)
    if lengths is not None and np.shape(lengths) != (n, robot.n_cables):
        raise InputError(f"lengths: shape {np.shape(lengths)}, expected ({n}, "
                         f"{robot.n_cables}) (one column per cable at the pose times)")
    margin = max(2, int(math.ceil(2.0 / (cutoff_hz * dt))))
    keep = segment_mask(t, sig.segments, trim) & (np.ones(n, bool) if use is None
                                                  else np.asarray(use, bool))
    glitch, gsize = find_glitches(sig.position, sig.segments,
                                  sig.quaternion if sig.has_rotation else None)
    gl_excl = _dilate(glitch, margin)
    y, A, Wf, model, mo, c = _data(robot, sig, cutoff_hz)
    rows = np.std(y, 0) > 1e-9 * np.std(y, 0).max()  # nil rows (point mass): no test there
    y, A, Wf = y[:, rows], A[:, rows], Wf[:, rows]
    slack = _dilate(np.any(np.asarray(sig.tension) < TAUT_THRESHOLD_N, axis=1), margin)
    scan_use = keep & ~gl_excl & ~slack
    few_taut = scan_use.sum() < TAUT_SHARE_MIN * max(int((keep & ~gl_excl).sum()), 1)
    if few_taut:  # (almost) every sample below the taut threshold: scan them all, say so
        scan_use = keep & ~gl_excl
    # the anchor fit's samples (PERSISTENT_RIDGE): the glitches' stretches in, their cores out
    usable = (keep if few_taut else keep & ~slack) & ~_dilate(glitch, margin // 2)
    found, excl, nm, beta, passes, caveat = _null_and_passes(
        y, A, c, rows, (scan_use, usable), gl_excl, dt, margin, cutoff_hz, far_per_hour)
    if few_taut:
        caveat = ((caveat + "; ") if caveat else "") + (
            f"fewer than {TAUT_SHARE_MIN:.0%} of the samples have every tension above "
            f"{TAUT_THRESHOLD_N:g} N (a tension unit or threshold to check): slack samples "
            "were scanned too")
    n_windows = (t[-1] - t[0]) * sum(2.0 / s for s in SCALES_S)
    eps = [_wrench_episode(t, a, b, T, mean, Wf, nm, n_windows, rows)
           for a, b, T, mean in found]
    eps += _glitch_episodes(t, glitch, gsize)
    energy, excl = _energy_episodes(robot, sig, mo, beta, model,
                                    segment_mask(t, sig.segments, trim) & ~gl_excl, excl,
                                    margin, far_per_hour, lengths)
    eps += energy
    eps.sort(key=lambda e: e.start_s)
    return Episodes(tuple(eps), t, excl, margin * dt, far_per_hour, passes, caveat)


def _null_and_passes(y, A, c, rows, uses, gl_excl, dt, margin, cutoff_hz, far_per_hour):
    """The persistent null (:func:`persistent_null`, the glitches' transients ``gl_excl`` left
    out of its band positions: their residual is no cell's error, and taken for one it moves
    the hysteretic cells' play operators, whose wrong state outlasts it until the next full
    reversal, ``tests/episodes/test_band_quiet.py``) and the fit -> locate passes
    (:func:`_wrench_passes`).

    The null is built once. Building it again without the episodes the first passes found
    was measured on the floor-winch robot with pushes and glitches
    (benchmarks/episodes_combined.py): it removed the false episodes of two recordings at the
    4 Hz cutoff but gave three new ones at identify's data-chosen cutoff (all next to a
    glitch's excluded stretch), so it is not done (docs/episodes.md).

    ``uses`` is ``(scan_use, usable)``: the samples scanned, and every usable one (the
    glitches' stretches included, their cores not) for the fit that anchors the persistent
    columns' coefficients (:data:`PERSISTENT_RIDGE`)."""
    scan_use, usable = uses
    whiten = np.diag(1.0 / np.maximum(np.std(y[scan_use], 0), 1e-9))
    Z = persistent_null(A, c, rows, lambda Z1: _noise_fit(y, Z1, scan_use, whiten)[:2], gl_excl)
    return _wrench_passes(y, Z, (scan_use, usable), gl_excl, dt, margin, cutoff_hz,
                          far_per_hour, A.shape[2])


def _wrench_passes(y, Z, uses, gl_excl, dt, margin, cutoff_hz, far_per_hour, p):
    """Fit -> locate -> refit passes: ``(episodes (a, b, T, mean), excluded, noise model,
    beta, passes, caveat)``; ``beta`` is the rigid body's (the first ``p`` columns of ``Z``)
    fitted alone on the last fit's samples and whitening, for the energy test. When the
    episodes would cover more than :data:`MAX_SHARE` of the scanned samples, the residual is
    not local in time (the model misses something all along: the diagnosis's question): no
    wrench episode is reported, and ``caveat`` says so. ``uses`` is ``(scan_use, usable)``
    (:func:`_null_and_passes`): each pass anchors the persistent columns on ``usable`` less
    the episodes found so far (:data:`PERSISTENT_RIDGE`)."""
    scan_use, usable = uses
    level = window_level(far_per_hour)
    max_lag = int(math.ceil(1.5 / (cutoff_hz * dt)))  # correlation length, filtered residual
    whiten = np.diag(1.0 / np.maximum(np.std(y[scan_use], 0), 1e-9))
    rho = filter_autocorrelation(dt, cutoff_hz)
    excl, found, passes, caveat = gl_excl.copy(), [], 0, None
    while passes < PASSES:
        passes += 1
        rows = scan_use & ~excl
        anchor_rows = usable & ~(excl & ~gl_excl)
        r, anchor, w = _noise_fit(y, Z, anchor_rows, whiten)
        if not np.array_equal(anchor_rows, rows):  # the same samples: the anchor is the fit
            r, _, w = _noise_fit(y, Z, rows, whiten, prior=(anchor[p:], PERSISTENT_RIDGE))
        whiten = w
        beta = _robust_fit(y, Z[..., :p], rows, whiten)[1]
        nm = noise_model(r, rows, max_lag, rho)
        whiten = nm.whiten
        found = locate(r, scan_use, dt, nm, level, guard=margin)
        new = gl_excl.copy()
        for a, b, _, _ in found:
            new[a:b] = True
        new = _dilate(new, margin) | gl_excl
        share = float((new & scan_use).sum()) / max(1, int(scan_use.sum()))
        if share > MAX_SHARE:
            caveat = (f"the wrench residual departs from its noise over {100 * share:.0f} % of "
                      "the recording: the model misses something all along, not only at "
                      "times, so no external_wrench episode is reported (see diagnose)")
            beta = _fit(y, Z[..., :p], scan_use & ~gl_excl, whiten)[1]
            return [], gl_excl.copy(), nm, beta, passes, caveat
        if np.array_equal(new, excl):
            break
        excl = new
    return found, excl, nm, beta, passes, caveat


def _energy_episodes(robot, sig, mo, beta, model, use, excl, margin, far_per_hour,
                     lengths=None):
    """The energy test's episodes when the winches are locked, and the exclusion widened.
    Locked: the winch lengths ``lengths`` (n, m) when given (their creep's work booked by
    :func:`outside_work`), else the geometric lengths from the poses."""
    if lengths is not None:
        L = np.asarray(lengths, float)
    else:  # straight exit-to-attachment distances (a pulley's wrap changes them by far
        # less than the locked range)
        b = np.einsum("nij,mj->nmi", np.asarray(mo.B_R_P), np.asarray(robot.P_b))
        L = np.linalg.norm(np.asarray(robot.B_A)[None] - np.asarray(mo.position)[:, None] - b,
                           axis=2)
    if not locked(L, use):
        return [], excl
    E = mechanical_energy(beta, model, mo.velocity, mo.omega, mo.B_R_P, mo.position,
                          robot.gravity)
    if lengths is not None:
        E = outside_work(E, winch_power(sig.tension, L, float(sig.dt)), float(sig.dt))
    t = np.asarray(sig.t, float)
    out, new = [], np.zeros_like(excl)
    for a, b, work, p in energy_runs(t, E, use, excl, far_per_hour):
        out.append(Episode(float(t[a]), float(t[b - 1]), "energy", None, None, None, None, p,
                           {"energy_J": work}))
        new[a:b] = True
    speed = np.linalg.norm(np.asarray(mo.velocity, float), axis=1)
    for a, b, work, p in braking_runs(t, E, speed, use, excl | new, far_per_hour):
        out.append(Episode(float(t[a]), float(t[b - 1]), "energy", None, None, None, None, p,
                           {"energy_J": work}))  # < 0: taken out faster than passive losses
        new[a:b] = True
    return out, _dilate(new, margin) | excl


def _wrench_episode(t, a, b, T, mean, Wf, nm, n_windows, rows) -> Episode:
    """An external wrench or, when one load cell's column explains it, a load-cell step."""
    p = float(min(1.0, chi2_sf(T, len(mean)) * max(1.0, n_windows)))
    w = np.zeros(6)
    w[rows] = -np.asarray(mean, float)
    zr = nm.whiten @ mean
    best, share, step = None, 0.0, 0.0
    for i in range(Wf.shape[2]):
        col = nm.whiten @ Wf[a:b, :, i].mean(0)
        c = float(col @ zr / max(col @ col, 1e-300))
        s = 1.0 - float(np.sum((zr - c * col) ** 2) / max(zr @ zr, 1e-300))
        if s > share:
            best, share, step = i, s, c
    kind, detail = EXTERNAL_WRENCH, {}
    if best is not None and share >= STEP_SHARE and (t[b - 1] - t[a]) > 5.0:
        kind, detail = "load_cell_step", {"cable": best + 1, "step_N": step}
    return Episode(float(t[a]), float(t[b - 1]), kind, tuple(map(float, w[:3])),
                   tuple(map(float, w[3:])), float(np.linalg.norm(w[:3])),
                   float(np.linalg.norm(w[3:])), p, detail)


def _glitch_episodes(t, glitch, gsize) -> list:
    """One episode per burst of glitches (samples within 0.5 s of each other)."""
    out = []
    gap = max(1, int(round(0.5 / max(float(np.median(np.diff(t))), 1e-9))))
    for a, b in runs(_dilate(glitch, gap // 2)):
        idx = np.flatnonzero(glitch[a:b]) + a
        out.append(Episode(float(t[idx[0]]), float(t[idx[-1]]), "pose_glitches", None, None,
                           None, None, 0.0, {"n_samples": int(idx.size),
                                             "largest_m": float(gsize[idx].max())}))
    return out
