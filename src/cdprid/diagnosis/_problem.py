"""Stage 0 of the diagnosis: the aligned data, masks, matched filter and held-out error.

:func:`prepare` turns a dataset into a :class:`Problem` (frozen) that every later stage
reads; :func:`design` linearises the forward model at theta; :func:`heldout_rms` is the one
held-out criterion of every selection step.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import CUTOFF_HZ, TAUT_THRESHOLD_N, TRIM_S, UserError
from cdprid.core import (
    CATMULL_ROM,
    ROTATION_WARN_DEG,
    SLIDE_NOISE_M_S,  # noqa: F401  (the diagnosis' friction sign: re-exported)
    SMOOTH_HZ,
    Motion,
    TensionStream,
    estimate_motion,
    rotation_angle_deg,
    sliding_sign,
    taut_mask,
    tension_at,
    wrench_matrices,
)
from cdprid.effects import hysteresis_regressor
from cdprid.diagnosis._model import (
    DiagData,
    ThetaLayout,
    assemble_jac,
    geometry_blocks,
    geometry_jac,
    model_jac_jit,
    model_jit,
    regs_jit,
    tension_jac,
)
from cdprid.diagnosis._testing import blocks, fold_sse
from cdprid.io import Dataset, align
from cdprid.model import cable_lengths
from cdprid.signal import zero_phase_filter


@dataclasses.dataclass(frozen=True)
class Problem:
    """Everything the stages share: data in JAX form, masks, filter settings, row weights."""

    d: DiagData
    layout: ThetaLayout
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    tension: np.ndarray  # (n, m) at the pose times (the forward model's interpolant, no delay)
    tau_grid: np.ndarray
    R: np.ndarray
    v: np.ndarray
    a: np.ndarray
    om: np.ndarray
    W_all: np.ndarray  # (n, 6, m) nominal wrench matrices
    has_rotation: bool
    dt: float
    tdt: float
    cutoff_hz: float
    use: np.ndarray
    train: np.ndarray
    test: np.ndarray | None
    n_slack: int
    n_folds: int
    lags: int
    wrow: np.ndarray = dataclasses.field(default_factory=lambda: np.ones(6))
    #: the platform rotates more than :data:`cdprid.core.ROTATION_WARN_DEG`: the base model is
    #: the full (10-parameter) model, the one ``identify --model auto`` uses
    rotational_base: bool = False
    #: rotation of the used samples, deg (99th percentile from the mean orientation)
    rotation_deg: float = 0.0
    #: the core's motion estimate (:func:`cdprid.core.estimate_motion`): its differentiator
    #: and settings serve every later derivative (the null replicates)
    motion: Motion | None = dataclasses.field(default=None, compare=False, repr=False)
    #: cables whose ``load_cell_hysteresis`` regressor in ``d.hyst_h`` comes from the model's
    #: force on the cell (:func:`cdprid.diagnosis._hysteresis.refine_hysteresis`), not the
    #: reading alone
    hysteresis_refined: tuple = ()
    #: the force stream: ``"tensions"`` (load cells) or ``"currents"`` (the winch drives'
    #: currents read as the datasheet's tension ``k i``; :func:`cdprid.diagnosis.diagnose`)
    source: str = "tensions"
    #: the effect parameters every fit starts from and holds where not refitted (the drive
    #: model on currents, :func:`cdprid.diagnosis._drives.drive_theta`); None: zero
    theta0: np.ndarray | None = dataclasses.field(default=None, compare=False, repr=False)
    #: linearisations already computed (see :func:`design`); not part of the problem's value
    cache: dict = dataclasses.field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        """Number of aligned samples."""
        return len(self.t)

    @property
    def m(self) -> int:
        """Number of cables."""
        return self.layout.m

    def filt(self, x):
        """Matched filter (zero-phase Butterworth, order 2) along time of ``(n, ...)``."""
        x = np.asarray(x)
        y = zero_phase_filter(x.reshape(x.shape[0], -1), self.dt, self.cutoff_hz, 2)
        return y.reshape(x.shape)


def prepare(ds: Dataset, train_until: float | None = None, cutoff_hz: float = CUTOFF_HZ,
            trim: float = TRIM_S, n_folds: int = 5, taut_N: float = TAUT_THRESHOLD_N, *,
            joins: tuple = (), clock=None, source: str = "tensions") -> Problem:
    """Align, differentiate, build the forward-model data and the masks: samples inside the
    trimmed recording where every cable is taut (:func:`cdprid.core.taut_mask`, as real data).

    Parameters
    ----------
    ds : Dataset
    train_until : float (s), optional
        t < train_until is fitted, the rest held out; None: blocked cross-validation over
        ``n_folds`` time blocks.
    cutoff_hz, trim, n_folds, taut_N : float (Hz), float (s), int, float (N)
        The differentiator's low-pass, left out at each end, folds, slack threshold.
    joins : tuple of float (s)
        Where blocks of a budgeted subset meet (:mod:`cdprid.diagnosis._budget`); the samples
        within the trim margin of each are left out.
    clock : callable, optional
        Times -> the recording's clock for time-dependent effects (default t - tension_t[0]).
    source : str
        ``"tensions"`` or ``"currents"`` (with :func:`length_accelerations`).

    Returns
    -------
    Problem

    Raises
    ------
    UserError
        ``train_until`` leaves too few training or held-out samples.
    """
    sig = align(ds)
    robot = ds.robot
    m = robot.n_cables
    dt = sig.dt
    motion = estimate_motion(sig, "euler-filtfilt", {"cutoff_hz": cutoff_hz})
    v, a, R, om, al = (motion.velocity, motion.acceleration, motion.B_R_P, motion.omega,
                       motion.alpha)
    stream = TensionStream.on_uniform_grid(ds.tension_t, ds.tension)
    grid_t, tau_grid, tdt = np.asarray(stream.t), np.asarray(stream.values), stream.dt
    W_all = np.asarray(jax.jit(wrench_matrices)(robot, jnp.asarray(sig.position), R))
    ldot = -np.einsum("nim,ni->nm", W_all, np.concatenate([v, om], axis=1))
    lengths = np.asarray(jax.jit(jax.vmap(cable_lengths, in_axes=(None, 0, 0)))(
        robot, jnp.asarray(sig.position), jnp.asarray(R)))
    slide, _, _ = sliding_sign(lengths, dt, cutoff_hz)
    clk = (np.asarray(sig.t) - float(ds.tension_t[0]) if clock is None
           else np.asarray(clock(np.asarray(sig.t)), float))
    d = DiagData(robot, jnp.asarray(sig.t), jnp.asarray(sig.position), jnp.asarray(R),
                 jnp.asarray(v), jnp.asarray(a), jnp.asarray(om), jnp.asarray(al),
                 stream.values, jnp.asarray(ldot), jnp.asarray(clk), stream.t0, tdt,
                 jnp.asarray(slide), smoothed_stream(stream).values, hysteresis_regressor(
                     stream.values, tdt), _accelerations(lengths, dt, sig, source))
    margin = max(trim, 0.1)
    use = ((sig.t >= max(sig.t[0], grid_t[0]) + margin)
           & (sig.t <= min(sig.t[-1], grid_t[-1]) - margin))
    for tj in joins:
        use &= np.abs(sig.t - tj) > margin
    taut = taut_mask(sig.t, grid_t, tau_grid, threshold_N=taut_N)  # the shared rule
    n_slack = int((use & ~taut).sum())
    use = use & taut
    test = None
    train = use
    if train_until is not None:
        train = use & (sig.t < train_until)
        test = use & (sig.t >= train_until)
        if train.sum() < 200 or test.sum() < 50:
            raise UserError(
                f"--train-until {train_until:g} leaves {int(train.sum())} training and "
                f"{int(test.sum())} held-out samples; choose a time inside the recording."
            )
    rot_deg = rotation_angle_deg(sig.quaternion[use]) if sig.has_rotation and use.any() else 0.0
    return Problem(
        rotational_base=bool(rot_deg > ROTATION_WARN_DEG), rotation_deg=float(rot_deg),
        d=d, layout=ThetaLayout(m), t=sig.t, position=sig.position, quaternion=sig.quaternion,
        tension=np.asarray(tension_at(stream, sig.t, CATMULL_ROM)), tau_grid=tau_grid, R=R, v=v,
        a=a, om=om, W_all=W_all, motion=motion, has_rotation=bool(sig.has_rotation), dt=dt,
        source=source, tdt=tdt, cutoff_hz=cutoff_hz, use=use, train=train, test=test,
        n_slack=n_slack, n_folds=n_folds,
        lags=int(math.ceil(3.0 / (cutoff_hz * dt))),  # correlation length, filtered residual
    )


def _accelerations(lengths, dt: float, sig, source: str):
    """The data's cable length accelerations on a current stream (None on load cells)."""
    if source != "currents":
        return None
    return jnp.asarray(length_accelerations(lengths, dt, sig.segments))


def length_accelerations(lengths, dt: float, segments=()) -> np.ndarray:
    """Second central differences of cable lengths, segment by segment, ``(n, m)`` m/s^2.

    Raw (not low-passed): the measured side's matched filter then smooths them as the
    differentiator smooths the platform's accelerations (its Butterworth after the same
    second difference), so a drive's inertia ``J l''`` and the platform's ``m a`` see one
    filter. A segment's end samples repeat their neighbour's value; a segment shorter than
    three samples gets zeros (those samples are trimmed from every fit).

    Parameters
    ----------
    lengths : (n, m) m
    dt : float, s
    segments : sequence of (int, int), optional
        Half-open gap-free index ranges (default: one).

    Returns
    -------
    numpy.ndarray (n, m)
    """
    x = np.asarray(lengths, float)
    out = np.zeros_like(x)
    for a, b in (segments or ((0, len(x)),)):
        if b - a < 3:
            continue
        dd = (x[a + 2:b] - 2.0 * x[a + 1:b - 1] + x[a:b - 2]) / dt ** 2
        out[a + 1:b - 1] = dd
        out[a], out[b - 1] = dd[0], dd[-1]
    return out


def smoothed_stream(stream: TensionStream) -> TensionStream:
    """The tension stream the forward model interpolates at shifted times: through the core's
    zero-phase low-pass at :data:`cdprid.core.SMOOTH_HZ` (far above the matched filter's
    cut-off), or as recorded when that is above 80 % of the stream's Nyquist frequency.

    Without it the cost ripples in the delay with the tension step (the interpolated noise's
    variance changes within each sample interval) and the clock offset stops in a ripple with
    a dishonest interval: a clean 800 Hz floor8 recording read -2.02 +- 0.04 ms, its profile
    over the delay a 1.25 ms-periodic ripple of 2 % on a nearly flat cost.

    Parameters
    ----------
    stream : cdprid.core.TensionStream
        The raw stream (uniform grid).

    Returns
    -------
    cdprid.core.TensionStream
    """
    if SMOOTH_HZ is None or SMOOTH_HZ > 0.8 * 0.5 / stream.dt:
        return stream
    return stream.smoothed(SMOOTH_HZ)


#: linearisations kept in ``Problem.cache`` (each holds a filtered (n, 6, ntheta) Jacobian)
DESIGN_CACHE_SIZE = 4


def _design_key(theta, x_cur, rotational: bool):
    x = np.asarray(x_cur if rotational else np.asarray(x_cur)[:4], float)
    return (np.asarray(theta, float).tobytes(), x.tobytes(), bool(rotational))


#: entries kept per kind in ``Problem.cache`` (a "jac" entry holds a (n, 6, ntheta) Jacobian)
_CACHE_SIZES = {"design": DESIGN_CACHE_SIZE, "jac": 2, "measured": 32, "geometry": 2}


def _remember(prob: Problem, key, value, kind: str = "design"):
    cache = prob.cache.setdefault(kind, {})
    cache.pop(key, None)
    cache[key] = value
    while len(cache) > _CACHE_SIZES[kind]:
        cache.pop(next(iter(cache)))


def measured(prob: Problem, theta) -> np.ndarray:
    """Unfiltered measured side (n, 6) at theta (kept when computed by :func:`cable_side`)."""
    key = np.asarray(theta, float).tobytes()
    hit = prob.cache.get("measured", {}).get(key)
    if hit is None:  # the parts cable_side uses (compiled once; meas_and_jac joins them)
        hit = np.asarray(assemble_jac(prob.layout, _geometry(prob, theta), tension_jac(
            prob.d, jnp.asarray(theta), prob.layout))[0])
        _remember(prob, key, hit, "measured")
    return hit


def cable_side(prob: Problem, theta):
    """Matched-filtered measured side (n, 6) and its theta-Jacobian (n, 6, ntheta) at theta.

    Kept in ``prob.cache`` (read-only arrays): the base fit and the first selection step use
    the same one. The geometry part (pulleys, attachments, cable weight; the expensive
    derivatives) is kept apart and reused while theta's geometry blocks are unchanged
    (:func:`_geometry`).
    """
    key = np.asarray(theta, float).tobytes()
    hit = prob.cache.get("jac", {}).get(key)
    if hit is None:
        ym, Jm = assemble_jac(prob.layout, _geometry(prob, theta),
                              tension_jac(prob.d, jnp.asarray(theta), prob.layout))
        ym = np.asarray(ym)
        _remember(prob, key, ym, "measured")
        hit = (prob.filt(ym), prob.filt(Jm))
        for a in hit:
            a.setflags(write=False)
        _remember(prob, key, hit, "jac")
    return hit


def _geometry(prob: Problem, theta):
    """:func:`cdprid.diagnosis._model.geometry_jac` at theta, kept in ``prob.cache`` under the
    values of the theta blocks it depends on (a refit of sensor-side effects moves none)."""
    th = np.asarray(theta, float)
    key = b"".join(th[prob.layout.slices[name]].tobytes() for name in geometry_blocks())
    hit = prob.cache.get("geometry", {}).get(key)
    if hit is None:
        hit = geometry_jac(prob.d, jnp.asarray(th), prob.layout)
        _remember(prob, key, hit, "geometry")
    return hit


def design(prob: Problem, theta, x_cur, rotational: bool):
    """Filtered measured wrench y, model regressor A and theta columns C at theta.

    Linearisation: ``y(theta') - model(theta') ~ y - A x - C (theta' - theta)``. The cable side
    and its theta-Jacobian are jitted once (the data are an argument); the matched filter is
    applied along time after (linear, so filtering the Jacobian equals the Jacobian of the
    filtered side). The last :data:`DESIGN_CACHE_SIZE` linearisations are kept in
    ``prob.cache`` (the selection stages ask for the same one several times); the arrays
    returned are shared with the cache and must not be modified.

    Parameters
    ----------
    prob : Problem
    theta : array_like (size,)
        Effect parameters to linearise at.
    x_cur : array_like (10,)
        Platform parameters (the first 4 when not ``rotational``).
    rotational : bool
        Whether the inertia is part of the model.

    Returns
    -------
    y : numpy.ndarray (n, 6)
        The filtered cable side minus the model's part not linear in x, N and N m.
    A : numpy.ndarray (n, 6, 4 or 10)
        The regressor in x.
    C : numpy.ndarray (n, 6, size)
        The theta columns (model minus cable side Jacobian). Read-only.
    """
    key = _design_key(theta, x_cur, rotational)
    hit = prob.cache.get("design", {}).get(key)
    if hit is not None:
        return hit
    d, layout = prob.d, prob.layout
    th = jnp.asarray(theta)
    xin = jnp.asarray(x_cur if rotational else x_cur[:4])
    Jmod = model_jac_jit(d, th, xin, layout, rotational)
    Am = regs_jit(d, th, layout, rotational)
    mod = model_jit(d, th, xin, layout, rotational)
    ym, Jm = cable_side(prob, theta)  # (n, 6), (n, 6, ntheta)
    Am = np.asarray(Am)
    y_now = ym - (np.asarray(mod) - np.einsum("nij,j->ni", Am, np.asarray(xin)))
    out = (y_now, Am, np.asarray(Jmod) - Jm)
    for a in out:
        a.setflags(write=False)
    _remember(prob, key, out)
    return out


def seed_design(prob: Problem, theta, x_cur, rotational: bool, lin) -> None:
    """Keep ``lin = (y, A, C)`` as the linearisation at (theta, x) (a converged refit's last).

    A Gauss-Newton refit that has converged linearised the model at a theta within a small
    fraction of a standard deviation of the final one; ``lin`` is that linearisation with
    ``y`` shifted to first order (``y - C dtheta``), so that the linear model built from it at
    the final theta is the one the refit solved.
    """
    for a in lin:
        a.setflags(write=False)
    _remember(prob, _design_key(theta, x_cur, rotational), tuple(lin))


def heldout_rms(prob: Problem, Z, y) -> float:
    """Held-out RMS (weighted units): blocked CV over the used samples, or train/test split."""
    if prob.test is None:  # cdprid.diagnosis._testing.cv_sse, by segments' Gram matrices
        parts, count = _fold_grams(prob, Z, y)
        return math.sqrt(sum(fold_sse(*part) for part in parts) / count)
    p = Z.shape[2]
    beta, *_ = np.linalg.lstsq(Z[prob.train].reshape(-1, p), y[prob.train].reshape(-1),
                               rcond=None)
    r = y[prob.test] - np.einsum("nip,p->ni", Z[prob.test], beta)
    return float(np.sqrt(np.mean(r * r)))


def _fold_grams(prob: Problem, Z, y):
    """Gram matrices of the blocked CV over the used samples (:func:`heldout_rms`): for each
    fold ``(Z^T Z, Z^T y)`` of its training rows (outside the fold and its guard of ``lags``
    samples) and ``(Z^T Z, Z^T y, y^T y)`` of its rows, from sums over the contiguous segments
    between the folds' edges and guards; and the number of held-out values."""
    Zu, yu = Z[prob.use], y[prob.use]
    n, _, p = Zu.shape
    folds = blocks(n, prob.n_folds)
    edges = sorted({0, n} | {min(n, max(0, e)) for lo, hi in folds
                             for e in (lo - prob.lags, lo, hi, hi + prob.lags)})
    seg = {}
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        Zs, ys = Zu[a:b].reshape(-1, p), yu[a:b].reshape(-1)
        seg[a] = (Zs.T @ Zs, Zs.T @ ys, float(ys @ ys), b)
    G = sum(v[0] for v in seg.values())
    g = sum(v[1] for v in seg.values())

    def part(a, b):
        out = [np.zeros_like(G), np.zeros_like(g), 0.0]
        for s0, (Gs, gs, ys, s1) in seg.items():
            if s0 >= a and s1 <= b:
                out[0], out[1], out[2] = out[0] + Gs, out[1] + gs, out[2] + ys
        return out

    parts = []
    for lo, hi in folds:
        Gx, gx, _ = part(max(0, lo - prob.lags), min(n, hi + prob.lags))
        Gb, gb, yb = part(lo, hi)
        parts.append((G - Gx, g - gx, Gb, gb, yb))
    return parts, n * y.shape[1]


def subset_heldout_rms(prob: Problem, Z, y, subsets) -> np.ndarray:
    """:func:`heldout_rms` of many column subsets of ``Z`` at once: ``rms[k]`` equals
    ``heldout_rms(prob, Z[:, :, subsets[k]], y)``.

    The training and held-out Gram matrices of every fold are formed once (sums over the
    contiguous segments between the folds' edges and guards); each subset then costs one
    small solve per fold (:func:`cdprid.diagnosis._testing.fold_sse`, as :func:`cv_sse`).
    Used by the search over pairs of candidates, where the columns are the base model's and
    every candidate's.
    """
    if prob.test is None:
        parts, count = _fold_grams(prob, Z, y)
    else:
        Zt, yt, Ze, ye = Z[prob.train], y[prob.train], Z[prob.test], y[prob.test]
        parts = [(np.einsum("nip,niq->pq", Zt, Zt), np.einsum("nip,ni->p", Zt, yt),
                  np.einsum("nip,niq->pq", Ze, Ze), np.einsum("nip,ni->p", Ze, ye),
                  float(np.sum(ye ** 2)))]
        count = ye.size
    out = np.empty(len(subsets))
    for k, sub in enumerate(subsets):
        ix = np.asarray(sub, int)
        sse = sum(fold_sse(Gt[np.ix_(ix, ix)], gt[ix], Gb[np.ix_(ix, ix)], gb[ix], yb)
                  for Gt, gt, Gb, gb, yb in parts)
        out[k] = math.sqrt(sse / count)
    return out


def heldout_residuals(prob: Problem, Z, y):
    """Held-out residuals (weighted units) of every held-out sample: ``(index, r (k, 6))``.

    The same predictions as :func:`heldout_rms` (``sqrt(mean(r**2))`` equals it): blocked CV
    over the used samples with a guard of ``lags`` samples around each fold, or the
    train/test split.
    """
    p = Z.shape[2]
    if prob.test is None:
        idx = np.nonzero(prob.use)[0]
        parts = []
        for lo, hi in blocks(len(idx), prob.n_folds):
            tr = np.ones(len(idx), bool)
            tr[max(0, lo - prob.lags):hi + prob.lags] = False
            beta, *_ = np.linalg.lstsq(Z[idx[tr]].reshape(-1, p), y[idx[tr]].reshape(-1),
                                       rcond=None)
            parts.append(y[idx[lo:hi]] - np.einsum("nip,p->ni", Z[idx[lo:hi]], beta))
        return idx, np.concatenate(parts, axis=0)
    beta, *_ = np.linalg.lstsq(Z[prob.train].reshape(-1, p), y[prob.train].reshape(-1),
                               rcond=None)
    idx = np.nonzero(prob.test)[0]
    return idx, y[idx] - np.einsum("nip,p->ni", Z[idx], beta)


def force_heldout_rms(prob: Problem, Z, y) -> float:
    """Held-out RMS of the force rows in newtons (weighted fit, unweighted residual).

    Parameters
    ----------
    prob : Problem
    Z : numpy.ndarray (n, 6, p)
        The model's columns (weighted rows).
    y : numpy.ndarray (n, 6)
        The weighted response.

    Returns
    -------
    float
        N.
    """
    _, r = heldout_residuals(prob, Z, y)
    return float(np.sqrt(np.mean((r[:, :3] / prob.wrow[None, :3]) ** 2)))
