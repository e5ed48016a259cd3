"""End-to-end identification of a dataset: the data path in one call.

dataset -> :func:`~cdprid.io._align` -> :func:`~cdprid.core.estimate_motion` ->
:func:`~cdprid.core.build_regression` -> :func:`~cdprid.core.least_squares`,
with the checks that keep the printed numbers honest (:mod:`cdprid.core._physical` and the
guards below): each guard that fires adds one sentence to ``warnings``.

Defaults chosen so that the estimate is unbiased and its ``std`` covers the real error:

* ``model="auto"``: the full model when the quaternions show rotation (the translation model
  on rotating data biases m s_G), else the paper's translation model;
* matched filtering of ``W tau`` for every differentiator
  (:func:`cdprid.signal.acceleration_filter`): the zero-phase filter for the
  Euler recipe, the differentiator's own response for the causal ones (their lag would
  otherwise shrink mzG by 10-60 %);
* ``std`` from the HAC covariance (:mod:`cdprid.core._covariance`); eq. 20 kept as ``std_iid``.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import TRIM_S, InputError
from cdprid.core import (
    CHUNK,
    EIV_NOTE,
    ROTATION_WARN_DEG,
    CRBResult,
    LSResult,
    Motion,
    Regression,
    StreamedRegression,
    cable_wrench,
    crb,
    eiv_fit,
    estimate_motion,
    least_squares_blocks,
    linear_match_regression,
    noise_gains,
    noise_levels,
    physical_fit,
    physical_warnings,
    platform_radius,
    regressor_blocks,
    regressor_scale,
    regressors,
    rotation_angle_deg,
    seen_mass,
    settled,
    uses_linear_match,
    uses_zero_phase_match,
    zero_phase_matched_regression,
)
from cdprid.identify._auto import cutoff_from_data, resolve_params
from cdprid.identify._episodes import without_episodes
from cdprid.identify._report import IdentificationReport, format_table
from cdprid.io import AlignedSignals, Dataset, align
from cdprid.model import PARAMETER_NAMES, quat_to_matrix
from cdprid.signal import METHODS, acceleration_filter

__all__ = [
    "COND_WARN",
    "DEFAULT_TRIM_S",
    "FitInputs",
    "FitSettings",
    "IdentificationReport",
    "MODELS",
    "ROTATION_WARN_DEG",
    "WRENCH_FILTERS",
    "excitation_warnings",
    "format_table",
    "identify_dataset",
    "physical_report",
    "rotation_angle_deg",
]

DEFAULT_TRIM_S = TRIM_S
"""Seconds dropped at both ends after differentiation (kept for compatibility)."""

MODELS = ("auto", "translation", "full")
WRENCH_FILTERS = ("matched", "none")
#: ``none``: ordinary least squares; ``groups``: force and moment row weights (two steps);
#: ``eiv``: errors-in-variables GLS (:mod:`cdprid.core._eiv`)
WEIGHTINGS = ("none", "groups", "eiv")

COND_WARN = 1.0e3
"""Scaled condition number of W_ID above which the excitation is reported as too little."""

ZERO_COLUMN_REL = 1.0e-6
"""A column of W_ID whose norm is below this fraction of the largest is 'near zero'."""


@dataclasses.dataclass(frozen=True)
class FitSettings:
    """How a batch regression is fitted (the options of :func:`identify_dataset` that reach
    the least squares).

    Attributes
    ----------
    model : {"translation", "full"}
        The model ("auto" resolved).
    differentiator : str
        Method of :func:`cdprid.differentiate` that gave the motion.
    params : dict
        Its parameters (cutoff resolved).
    weighting : {"eiv", "none", "groups"}
        Row weighting (:data:`WEIGHTINGS`).
    covariance : {"hac", "iid"}
        Covariance reported as ``cov``.
    chunk : int
        Time samples per block of the streamed regressor.
    bias_fix : bool
        Apply the errors-in-variables second-order bias correction (a cutoff chosen from the
        data).
    """

    model: str
    differentiator: str
    params: dict
    weighting: str = "eiv"
    covariance: str = "hac"
    chunk: int = CHUNK
    bias_fix: bool = False


@dataclasses.dataclass(frozen=True, eq=False)
class FitInputs:
    """The data a batch fit works on.

    Attributes
    ----------
    dataset : Dataset
        The recording (robot and raw streams: noise levels).
    signals : AlignedSignals
        The aligned streams.
    motion : Motion
        Differentiated motion.
    keep : ndarray of bool (n,)
        Samples used.
    regression : Regression or StreamedRegression
        The kept samples' regression.
    wrench_filter : callable or None
        The matched filter of ``W tau`` (a linear match has ``taps``).
    """

    dataset: Dataset
    signals: AlignedSignals
    motion: Motion
    keep: np.ndarray
    regression: Regression | StreamedRegression
    wrench_filter: object = None


def _choose_model(model: str, sig: AlignedSignals, path, warns0=()) -> tuple[str, float, list]:
    """``model`` resolved ("auto"), the rotation (deg) and the warnings (after ``warns0``)."""
    rot = rotation_angle_deg(sig.quaternion) if sig.has_rotation else 0.0
    warns = list(warns0)
    if model == "full" and not sig.has_rotation:
        raise InputError(
            f"{path}: the full model needs orientations (qw, qx, qy, qz in pose.csv) "
            "to identify the inertia; this dataset has none."
        )
    if model == "auto":
        model = "full" if rot > ROTATION_WARN_DEG else "translation"
    elif model == "translation" and rot > ROTATION_WARN_DEG:
        warns.append(f"the platform rotates by up to {rot:.2g} deg but the translation model "
                     "ignores rotation (its inertia and rotating first moment bias m s_G): use "
                     "--model full or auto.")
    return model, rot, warns


def _wrench_filter(robot, differentiator: str, params: dict, dt: float, wrench_filter: str):
    """The matched filter of ``W tau`` (a callable), its note and warnings.

    The callable filters (n, k) channels; ``scale`` (k,) is each channel's amplitude
    normalisation (default: the wrench's, mass times 1 for forces and the platform radius for
    moments).
    """
    causal = METHODS[differentiator].causal
    if wrench_filter == "none":
        warns = []
        if causal or differentiator != "euler-filtfilt":
            warns.append(f"the differentiator {differentiator} lags or attenuates the "
                         "accelerations but W tau is not filtered the same way "
                         "(--wrench-filter none): m s_G and the inertia are biased towards zero.")
        return None, None, warns
    rows = np.array([1.0] * 3 + [platform_radius(robot)] * 3)

    def wf(y, scale=None):
        """Filter (n, 6) wrenches, or (n, k) channels of amplitude ``scale`` (k,)."""
        if scale is None:
            scale = seen_mass(robot, y) * rows
        return acceleration_filter(y, dt, differentiator, scale=scale, **params)

    kind = "causal" if causal else "zero-phase"
    note = (f"matched filtering: W tau passed through the same {kind} filter as the "
            f"accelerations ({differentiator})")
    return wf, note, []


def _pose_term_correction(model: str, motion: Motion, robot, wf, y, chunk: int):
    """The regressor's pose-only part (gravity moment of the rotating m s_G), filtered too.

    ``W tau`` carries ``B_R_P m s_G x g``, which varies with the orientation; once ``W tau`` is
    filtered, the same term in the regressor must be filtered too, or a causal filter's lag
    leaves a residual correlated with the rotation (a bias on the inertia and m s_G).

    Returns ``(mask, corr)``: the (6, p) entries of the regressor that depend on the pose alone
    (found by evaluating it at three rotations with zero motion; the others are constant and pass
    the filter unchanged) and, per sample, filtered minus raw values of those entries (n, k).
    Only those k channels are held, not the (n, 6, p) regressor.
    """
    q = np.random.default_rng(0).normal(size=(3, 4))
    Rs = jnp.asarray(np.asarray(jax.vmap(quat_to_matrix)(q / np.linalg.norm(q, axis=1)[:, None])))
    z3 = jnp.zeros((3, 3))
    A3 = np.asarray(regressors(model, Rs, z3, z3, z3, robot.gravity))
    mask = np.any(A3 != A3[0], axis=0)
    n = len(motion.t)
    z = np.zeros((n, 3))
    block = regressor_blocks(model, motion.B_R_P, z, z, z, robot.gravity, chunk)
    Ag = np.empty((n, int(mask.sum())))
    for i0 in range(0, n, chunk):
        Ag[i0:i0 + chunk] = block(i0, min(i0 + chunk, n))[:, mask]
    scale = regressor_scale(robot, y, A3.shape[-1])[mask]
    return mask, np.asarray(wf(Ag, scale)) - Ag


def _streamed_regression(robot, motion: Motion, tension, model: str, wf, keep,
                         chunk: int) -> StreamedRegression:
    """The kept samples' regression, its regressor evaluated block by block (bounded memory).

    Same numbers as :func:`cdprid.core.build_regression` followed by the matched
    filtering of the pose-only terms (:func:`_pose_term_correction`), without holding the
    (n, 6, p) regressor or the (n, 6, m) wrench matrices.
    """
    y = cable_wrench(robot, motion.position, motion.B_R_P, tension, chunk)
    if wf is not None:
        y = np.asarray(wf(y))
    mask = corr = None
    if wf is not None and model == "full":
        mask, corr = _pose_term_correction(model, motion, robot, wf, y, chunk)
    idx = np.flatnonzero(keep)
    sel = slice(idx[0], idx[-1] + 1) if idx[-1] - idx[0] + 1 == len(idx) else idx
    base = regressor_blocks(model, motion.B_R_P[sel], motion.acceleration[sel],
                            motion.omega[sel], motion.alpha[sel], robot.gravity, chunk)
    corr = None if corr is None else corr[sel]

    def block(i0: int, i1: int) -> np.ndarray:
        A = base(i0, i1)
        if corr is not None:
            A[:, mask] += corr[i0:i1]
        return A

    return StreamedRegression(motion.t[sel], y[sel], model, block)


def excitation_warnings(names, column_norms, cond_scaled: float) -> list:
    """The "too little excitation" guard: near-zero regressor columns or a large condition number.

    Parameters
    ----------
    names : sequence of str
        Parameter names.
    column_norms : array (p,)
        Norms of the columns of W_ID.
    cond_scaled : float
        Condition number of W_ID with unit-norm columns.

    Returns
    -------
    list of str
        At most one sentence (the batch and the online identification share it).
    """
    norms = np.asarray(column_norms, float)
    small = [n for n, v in zip(names, norms, strict=True) if v < ZERO_COLUMN_REL * norms.max()]
    warns = []
    if small:
        warns.append(f"too little excitation: the regressor columns of {', '.join(small)} are "
                     "near zero, so these parameters are not identified by this motion.")
    elif cond_scaled > COND_WARN:
        warns.append(f"too little excitation: cond(W_ID) scaled = {cond_scaled:.3g} > "
                     f"{COND_WARN:g}, the estimates are poorly separated (check their std or "
                     "excite more: cdprid excite).")
    return warns


def identify_dataset(
    ds: Dataset,
    model: str = "auto",
    differentiator: str = "euler-filtfilt",
    params: dict | None = None,
    t_start: float | None = None,
    t_end: float | None = None,
    trim: float = TRIM_S,
    weighting: str = "eiv",
    matched_filter: bool | None = None,
    covariance: str = "hac",
    wrench_filter: str | None = None,
    inertia_about: str = "P",
    chunk: int = CHUNK,
    bound: bool = True,
    keep_episodes: bool | None = False,
) -> IdentificationReport:
    """Identify the platform's dynamic parameters from a dataset.

    Parameters
    ----------
    ds : Dataset
        The recording (spec v1: robot, poses, tensions).
    model : {"auto", "translation", "full"}
        The paper's 4-parameter model, the 10-parameter model with inertia, or ``auto``
        (default): full when the quaternions show more than :data:`ROTATION_WARN_DEG` of
        rotation, translation otherwise.
    differentiator : str
        Method of :func:`cdprid.differentiate` for velocities and accelerations.
    params : dict, optional
        The differentiator's parameters.
    t_start, t_end : float, optional
        Time window (s) of the data used.
    trim : float
        Seconds dropped at each end of the window after differentiation.
    weighting : {"eiv", "none", "groups"}
        ``eiv`` (default): errors-in-variables GLS (:func:`cdprid.core.eiv_fit`), each sample
        whitened by its residual covariance, the pose noise's second-order bias removed when
        the cutoff is chosen from the data; ``none``: OLS; ``groups``: force/moment row weights.
    matched_filter : bool, optional
        Older switch for ``wrench_filter`` (True = "matched", False = "none").
    covariance : {"hac", "iid"}
        ``std`` from HAC (default, honest on correlated residuals) or eq. 20 (JSON: both).
    wrench_filter : {"matched", "none"}, optional
        ``matched`` (default): ``W tau`` goes through the filter the differentiator applies to
        the accelerations (:func:`cdprid.signal.acceleration_filter`).
    inertia_about : {"P", "G"}
        Reference point of the inertia in the output (platform frame).
    chunk : int
        Time samples per block of the streamed regressor (:func:`cdprid.core.least_squares_blocks`):
        memory does not grow with ``n x 6 x p``; the result does not depend on it (to rounding).
    bound : bool
        Compute the recording's Cramer-Rao bound (:func:`cdprid.core.crb`, noise levels
        estimated from the data) for ``crb_std`` and ``efficiency``.
    keep_episodes : bool or None
        Keep the located episodes in the fit (``--keep-episodes``); None: none located.

    Returns
    -------
    IdentificationReport
        Typed estimates (``.parameters()``), fit, notes, warnings; ``.as_json()`` is the JSON.
    """
    wrench_filter = _check_options(model, differentiator, weighting, wrench_filter,
                                   matched_filter, inertia_about)
    notes = list((sig := align(ds, t_start, t_end)).notes)
    fix = cutoff_from_data(differentiator, params)
    params, w0 = resolve_params(ds, sig, differentiator, params, notes)
    model, rot, warns = _choose_model(model, sig, ds.path, w0)
    motion = estimate_motion(sig, differentiator, params, angular=(model == "full"))
    wf, note, w2 = _wrench_filter(ds.robot, differentiator, params, sig.dt, wrench_filter)
    warns, notes = warns + w2, notes + ([note] if note else [])
    keep, eps = without_episodes(ds, sig, params, trim, keep_episodes, notes)
    reg, wf, keep = _regression(ds, sig, motion, model, differentiator, wrench_filter, wf,
                                keep, trim, int(chunk), notes, warns)
    res = _fit(FitInputs(ds, sig, motion, keep, reg, wf), FitSettings(
        model, differentiator, params, weighting, covariance, int(chunk), bias_fix=fix), notes)
    warns, notes, bnd = _checks(ds, sig, motion, keep, model, res, warns, notes, bound)
    return IdentificationReport(res, model, differentiator, params, int(keep.sum()), sig, motion,
                                reg, tuple(notes), tuple(warns), inertia_about, wrench_filter,
                                rotation_deg=rot, crb=bnd, episodes=eps)


def _regression(ds, sig, motion, model, differentiator, wrench_filter, wf, keep, trim, chunk,
                notes: list, warns: list):
    """Regression, wrench filter and kept samples: :mod:`cdprid.core._zero_phase_match` for
    the full model with euler-filtfilt, :mod:`cdprid.core._linear_match` for the full model
    with a causal differentiator (its note replaces the matched filter's), else
    :func:`_streamed_regression`."""
    if uses_zero_phase_match(model, differentiator, wrench_filter, sig.quaternion):
        return zero_phase_matched_regression(ds.robot, motion, sig.quaternion, sig.tension, wf,
                                             keep, chunk), wf, keep
    if not uses_linear_match(model, METHODS[differentiator].causal, wrench_filter):
        return _streamed_regression(ds.robot, motion, sig.tension, model, wf, keep, chunk), wf, keep
    reg, lm, note, w4 = linear_match_regression(ds.robot, motion, sig.quaternion, sig.tension,
                                                model, keep, trim, chunk)
    notes[-1:], warns[len(warns):] = [note], w4
    return reg, lm, settled(keep, motion.segments, len(lm.taps))


def _checks(ds, sig, motion, keep, model, res, warns: list, notes: list, bound: bool):
    """The excitation and physics warnings, their notes, and the recording's bound (or None):
    ``(warnings, notes, bound)``."""
    warns = warns + excitation_warnings(res.names, res.column_norms, res.cond_scaled)
    w3, n3 = physical_warnings(res.x, model, res.cov)
    warns, notes = warns + w3, notes + n3
    return warns, notes, (_bound_noted(ds, sig, motion, keep, model, res.x, notes) if bound
                          else None)


def _bound_noted(ds, sig, motion, keep, model, x, notes: list):
    """:func:`recording_bound`, its reason for no bound appended to ``notes``."""
    bnd, why = recording_bound(ds, sig, motion, keep, model, x)
    if why:
        notes.append(why)
    return bnd


def _check_options(model, differentiator, weighting, wrench_filter, matched_filter,
                   inertia_about) -> str:
    """One sentence for an unknown option (before any work); the wrench filter to use."""
    if model not in MODELS:
        raise InputError(f"unknown model {model!r}; use one of {', '.join(MODELS)}.")
    if differentiator not in METHODS:
        raise InputError(
            f"unknown differentiator {differentiator!r}; choose one of {', '.join(METHODS)}."
        )
    if weighting not in WEIGHTINGS:
        raise InputError(f"unknown weighting {weighting!r}; use one of {', '.join(WEIGHTINGS)}.")
    if wrench_filter is None:
        wrench_filter = "none" if matched_filter is False else "matched"
    if wrench_filter not in WRENCH_FILTERS:
        raise InputError(f"wrench filter {wrench_filter!r} is not available in batch "
                         f"identification; use one of {', '.join(WRENCH_FILTERS)}.")
    if inertia_about not in ("P", "G"):
        raise InputError(f"inertia_about must be 'P' or 'G', got {inertia_about!r}.")
    return wrench_filter


def _fit(inputs: FitInputs, settings: FitSettings, notes: list) -> LSResult:
    """The regression's least-squares fit with the chosen weighting (:data:`WEIGHTINGS`).

    ``settings.bias_fix``: the errors-in-variables estimate gets the second-order bias
    correction (:func:`cdprid.core.bias_correction`): only with a cutoff chosen from the data,
    whose noise budget keeps the first-order correction accurate (at a fixed 4 Hz or with a
    causal differentiator it raised the median RMSE / CRB by 5-17 % on 10 recordings per robot
    in ``benchmarks/efficiency.py``). The notes of the weighting are appended to ``notes``."""
    wf, reg, s = inputs.wrench_filter, inputs.regression, settings
    mb = float(len(wf.taps)) if hasattr(wf, "taps") else 1.0  # the linear match's memory
    if s.weighting == "eiv":
        notes += [EIV_NOTE] + (["errors-in-variables bias correction: the pose noise's "
                                "second-order bias removed"] if s.bias_fix else [])
        return _eiv_result(inputs, s, mb)
    return least_squares_blocks(reg.wrench_block, len(reg.t), PARAMETER_NAMES[s.model],
                                groups=reg.groups if s.weighting == "groups" else None,
                                covariance=s.covariance, chunk=s.chunk, min_bandwidth=mb)


def _eiv_result(inputs: FitInputs, settings: FitSettings,
                min_bandwidth: float = 1.0) -> LSResult:  # --weighting eiv
    ds, sig, s = inputs.dataset, inputs.signals, settings
    s_tau, _, s_pos, s_rot = noise_levels(ds, sig)
    C = noise_gains(s.differentiator, s.params, sig.dt, inputs.wrench_filter)
    return eiv_fit(inputs.regression, ds.robot, s.model, inputs.motion, sig.tension,
                   np.flatnonzero(inputs.keep), (s_tau, max(s_pos, 1e-12), s_rot), C,
                   PARAMETER_NAMES[s.model], s.covariance, s.chunk, min_bandwidth,
                   bias_correct=s.bias_fix)


def recording_bound(ds: Dataset, sig: AlignedSignals, motion: Motion, keep, model: str,
                    x) -> tuple[CRBResult | None, str]:
    """The Cramer-Rao bound of the samples ``keep`` with noise levels from the data.

    Parameters
    ----------
    ds : Dataset
        The recording (robot; raw streams for :func:`cdprid.core.noise_levels`).
    sig : AlignedSignals
        Its aligned streams (tensions at the pose times, N).
    motion : Motion
        The differentiated motion.
    keep : array of bool (n,)
        Samples used by the fit.
    model : {"translation", "full"}
        The model identified.
    x : array (p,)
        The estimate at which the bound is evaluated (SI units).

    Returns
    -------
    (CRBResult, "") or (None, str)
        The bound (its ``noise`` says the levels used), or None and the reason it could not be
        computed.
    """
    s_tau, per_pose, s_pos, s_rot = noise_levels(ds, sig)
    k = np.asarray(keep, bool)
    try:
        with np.errstate(all="ignore"):
            b = crb(ds.robot, model, x, motion.t[k], motion.position[k], motion.B_R_P[k],
                    motion.acceleration[k], motion.omega[k], motion.alpha[k],
                    np.asarray(sig.tension)[k], s_tau, s_pos, s_rot)
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as e:
        return None, f"Cramer-Rao bound not computed ({e})"
    if not np.all(np.isfinite(b.std)) or not np.all(b.std > 0):
        return None, "Cramer-Rao bound not computed (the information matrix is singular)"
    noise = {**b.noise, "tension_N": [float(v) for v in s_tau * np.sqrt(per_pose)],
             "tension_samples_per_pose_sample": float(per_pose),
             "source": "estimated from the data (4th differences)"}
    return dataclasses.replace(b, noise=noise), ""


def physical_report(rep: IdentificationReport) -> IdentificationReport:
    """The report with the full model's estimate constrained to a realisable body (--physical).

    Uses :func:`cdprid.core.physical_fit` on the LS estimate and its covariance; equal to the
    LS estimate when that is already realisable. The i.i.d. covariance is propagated the same way.

    Parameters
    ----------
    rep : IdentificationReport
        A full-model report.

    Returns
    -------
    IdentificationReport
        The same report with the constrained estimate, its covariances and residual, a note
        saying whether the constraint is active, and the "physically impossible" warning gone.

    Raises
    ------
    cdprid.base.InputError
        The report is not of the full model.
    """
    if rep.model != "full":
        raise InputError("--physical constrains the full model's inertia: use --model full (or "
                         "auto on data with rotation).")
    r = rep.result
    A = r.weights[:, None] * rep.regression.W_ID if r.weights is not None else rep.regression.W_ID
    R = np.linalg.qr(A, mode="r")
    x, cov = physical_fit(r.x, R, r.cov)
    _, cov_iid = physical_fit(r.x, R, r.cov if r.cov_iid is None else r.cov_iid)
    res = dataclasses.replace(r, x=x, cov=cov, cov_iid=cov_iid,
                              residual=rep.regression.Y_ID - rep.regression.W_ID @ x)
    changed = not np.allclose(x, r.x)
    notes = (*(n for n in rep.notes if not n.startswith("the inertia estimate is not")),
             "physical: estimate constrained to a realisable body (Cholesky-factored "
             "pseudo-inertia)" + (" — the constraint is active" if changed else
                                  ", equal to least squares (already realisable)"))
    warns = tuple(w for w in rep.warnings if not w.startswith("physically impossible"))
    return dataclasses.replace(rep, result=res, notes=notes, warnings=warns)
