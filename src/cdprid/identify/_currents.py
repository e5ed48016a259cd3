"""Identification from motor currents (``identify --source currents``): the platform jointly
with every winch drive, no load cell needed.

With the drive model of :mod:`cdprid.core._drives` (``tau = k i + J l'' + f_v l' + f_c sign(l')
- c``) the Newton-Euler equations ``W tau = Z x`` become, per pose sample,

    Z_n x - D_n d = 0,        D_n = [F[W i], W l'', W l', F[W sign(l')], -F[W]]

(``F`` the matched filter of the accelerations, ``l'``, ``l''`` the encoder lengths
differentiated like the poses): homogeneous in ``theta = (x, d)``. One parameter is taken as
known (:mod:`cdprid.identify._scale`); the others follow from least squares with the tension
path's errors-in-variables weighting (:func:`cdprid.core._eiv.whitening`: current noise times
k, encoder noise through J and f_v), the currents' noise removed from the normal equations
(``E[N] = N_0 + Q``, ``Q`` the current and encoder columns' noise covariance, ``sigma_i^2 g_F
W_j^T Omega W_j`` with the filter's variance gain ``g_F`` measured on the recording's own
clocks; the estimate solves ``(N - Q) theta = 0``: corrected least squares) and the HAC
covariance through the correction, scaled by the reference (its uncertainty in every std).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import TRIM_S, InputError
from cdprid.core import (
    CHUNK,
    DriveParameters,
    drive_columns,
    drive_names,
    drive_tension,
    estimate_motion,
    estimate_noise,
    least_squares_blocks,
    noise_gains,
    noise_levels,
    whitening,
    wrench_matrices,
)
from cdprid.core import crb as crb_bound
from cdprid.identify._auto import cutoff_from_data, resolve_params
from cdprid.identify._batch import _choose_model, _regression, _wrench_filter
from cdprid.identify._cells import CellCalibration
from cdprid.identify._currents_oe import current_weights, datasheet_drives, refit_output_error
from cdprid.identify._currents_oe import raw_rates as _raw_rates
from cdprid.identify._currents_pose import RefitSetup, pose_noise_correction, shifted_fit
from cdprid.identify._currents_sign import STILL_S, _expected_sign, _fast_rate, _friction_sign
from cdprid.identify._drive_cells import cells_against_drives
from cdprid.identify._eiv_currents import corrected, normal_and_noise
from cdprid.identify._episodes import _trimmed
from cdprid.identify._scale import ScaleReference, choose_reference, scaled_estimate
from cdprid.io import align, read_drives, read_stream
from cdprid.model import PARAMETER_NAMES, cable_lengths
from cdprid.signal import differentiate, zero_phase_filter

__all__ = ["CurrentsReport", "identify_currents"]

EIV_SHARE_WARN = 0.3
"""Share of the regressor's energy that is current noise (in its worst direction) above
which the identification is reported as weak."""
EIV_CURRENTS_NOTE = ("errors-in-variables: each sample whitened by its residual covariance "
                     "(current noise x k, encoder noise through J and f_v, pose noise), and the "
                     "current and encoder noise inside the regressor removed from the normal "
                     "equations (corrected least squares)")


@dataclasses.dataclass(frozen=True)
class CurrentsReport:
    """What :func:`identify_currents` produced.

    Attributes
    ----------
    model : str
        "translation" or "full".
    names : tuple of str
        Platform parameter names then the drives' (``k_1``, ..., ``c_m``).
    theta : ndarray (p + 5m,)
    cov : ndarray
        HAC covariance with the reference's uncertainty.
    cov_iid : ndarray
        i.i.d. covariance with the reference's uncertainty.
    reference : ScaleReference
    nominal_k : ndarray (m,) or None
        Datasheet current-to-force constants (N/A).
    n_samples : int
    sigma_rho : float
        RMS residual wrench (N, N m), unwhitened.
    crb_std : ndarray (p,) or None
        Cramer-Rao bound of the platform parameters with the drives known (a lower bound).
    notes, warnings : tuple of str
    """

    model: str
    names: tuple
    theta: np.ndarray
    cov: np.ndarray
    cov_iid: np.ndarray
    reference: ScaleReference
    nominal_k: np.ndarray | None
    n_samples: int
    sigma_rho: float
    hac_bandwidth: float
    crb_std: np.ndarray | None
    differentiator: str
    params: dict
    notes: tuple = ()
    warnings: tuple = ()
    #: the load cells against the drives (with tensions.csv), else None
    cells: CellCalibration | None = None
    #: condition numbers of the whitened joint regressor (reference column excluded), raw and
    #: with unit-norm columns
    cond: float = float("nan")
    cond_scaled: float = float("nan")
    rotation_deg: float = 0.0
    estimator: str = "cls"  #: "cls" (corrected least squares) or "oe" (output error)
    #: with "oe": the corrected least squares' ``cls_theta``, ``cls_cov`` and the output
    #: error's other covariances (``cov_sandwich``, ``cov_andrews``, ``cov_model``)
    compared: dict | None = None

    @property
    def std(self) -> np.ndarray:
        """HAC standard deviations (reference propagated)."""
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

    @property
    def drives(self) -> DriveParameters:
        """The drive parameter estimates."""
        p = len(PARAMETER_NAMES[self.model])
        return DriveParameters.from_vector(self.theta[p:])

    def table(self) -> str:
        """Plain-text table (platform then drive parameters, then the load cells' calibration).

        Returns
        -------
        str
            Lines without a trailing newline.
        """
        from cdprid.identify._currents_json import result_table

        return result_table(f"source: currents   model: {self.model}   samples: "
                            f"{self.n_samples}   units: k N/A, J kg, fv N s/m, fc and c N",
                            self.names, self.theta, self.std, self.reference, self.notes,
                            self.warnings, self.crb_std) + (
            "" if self.cells is None else "\n" + self.cells.table())

    def as_json(self) -> dict:
        """JSON of ``identify --source currents``.

        Returns
        -------
        dict
            The keys of ``identify --json`` plus ``drives`` and ``scale_reference``.
        """
        from cdprid.identify._currents_json import currents_json

        return currents_json(self)


def _streams(ds, m: int, late_s: float = 0.0):
    """``(currents (t, i), lengths (t, l) or None)`` of the dataset folder, their time stamps
    ``late_s`` earlier (one sentence when currents.csv is missing or malformed)."""
    if ds.path is None:
        raise InputError("identify --source currents reads currents.csv from a dataset folder.")
    cur = read_stream(ds.path, "currents", "i", m)
    if cur is None:
        raise InputError(f"{ds.path}: --source currents needs currents.csv (t,i_1..i_{m}, A).")
    lens = read_stream(ds.path, "lengths", "l", m)
    return (cur[0] - late_s, cur[1]), None if lens is None else (lens[0] - late_s, lens[1])


def _interp_checked(t_src, v_src, t, name: str, keep, notes: list):
    """``v_src`` linearly interpolated at ``t`` (n, m); samples outside the stream or in its gaps
    (a period above 2.5 medians) are dropped from ``keep`` (never bridged), with a note."""
    dt = float(np.median(np.diff(t_src)))
    j = np.clip(np.searchsorted(t_src, t), 1, len(t_src) - 1)
    ok = (t >= t_src[0]) & (t <= t_src[-1]) & (t_src[j] - t_src[j - 1] <= 2.5 * dt)
    out = np.column_stack([np.interp(t, t_src, v_src[:, c]) for c in range(v_src.shape[1])])
    lost = int(np.sum(keep & ~ok))
    if lost:
        notes.append(f"{lost} pose samples outside {name}.csv or in its gaps dropped")
    return out, keep & ok


def _length_rates(lengths, segments, dt: float, differentiator: str, params: dict):
    """``(l', l'')`` of the paid-out lengths on the pose clock, segment by segment, by the
    pose's differentiator (so they pass the same filter as the accelerations)."""
    v, a = np.zeros_like(lengths), np.zeros_like(lengths)
    for i0, i1 in segments:
        vi, ai = differentiate(lengths[i0:i1], dt, method=differentiator, **params)
        v[i0:i1], a[i0:i1] = np.asarray(vi), np.asarray(ai)
    return v, a


def _filter_gain(t_src, t, wf, pre=None, seed: int = 1) -> float:
    """Variance of ``F[interp(P[x])]`` for unit white noise ``x`` on the stream's own clock,
    low-passed (``P``, cutoff ``pre`` or none), interpolated onto the pose clock and filtered
    (10 % of each end dropped)."""
    x = np.random.default_rng(seed).normal(size=(len(t_src), 3))
    if pre is not None:
        x = zero_phase_filter(x, _period(t_src), pre)
    xi = np.column_stack([np.interp(t, t_src, x[:, c]) for c in range(3)])
    f = np.asarray(wf(xi, np.ones(3)))
    k = slice(len(t) // 10, len(t) - len(t) // 10)
    return float(np.mean(np.var(f[k], axis=0)))


class _SubRegression:
    """A streamed regression restricted to some of its samples (``wrench_block`` on them)."""

    def __init__(self, reg, rows):
        self._reg, self._rows = reg, rows
        self.t = np.asarray(reg.t)[rows]

    def wrench_block(self, i0: int, i1: int):
        r = self._rows[i0:i1]
        Z, y = self._reg.wrench_block(int(r[0]), int(r[-1]) + 1)
        return Z[r - r[0]], y[r - r[0]]


def _drive_design(ds, motion, cur_i, lengths, sign, wf, dt: float, params: dict) -> np.ndarray:
    """``D`` (n, 6, 5m) through the matched filter: ``F[N[W i]]``, ``F[W D2 l]``,
    ``F[N[W D1 l]]``, ``F[N[W sign]]``, ``-F[N[W]]`` (``N`` the second difference's response
    that :func:`cdprid.signal.acceleration_filter` adds for the Euler recipe: the central
    second difference ``D2`` already has it, so the acceleration column gets ``F`` alone, as
    the platform's accelerations ``D2 F[p]``)."""
    W = np.asarray(wrench_matrices(ds.robot, motion.position, motion.B_R_P))
    d1, d2 = _raw_rates(lengths, motion.segments, dt)
    D = drive_columns(W, cur_i, d1, d2, sign)
    n, _, q = D.shape
    m = q // 5
    filt = np.r_[0:m, 2 * m:5 * m]
    ch = D[:, :, filt].reshape(n, -1)
    D[:, :, filt] = np.asarray(wf(ch, np.ones(ch.shape[1]))).reshape(n, 6, -1)
    acc = D[:, :, m:2 * m].reshape(n, -1)
    D[:, :, m:2 * m] = zero_phase_filter(acc, dt, params["cutoff_hz"],
                                         params.get("order", 2)).reshape(n, 6, m)
    return D


def identify_currents(ds, reference: str | None = None, model: str = "auto",
                      differentiator: str = "euler-filtfilt", params: dict | None = None,
                      t_start: float | None = None, t_end: float | None = None,
                      trim: float = TRIM_S, chunk: int = CHUNK, bound: bool = True,
                      drives=None, estimator: str = "oe", progress=None,
                      clock_offset_s: float = 0.0) -> CurrentsReport:
    """Identify the platform and every drive from poses, winch lengths and motor currents.

    Parameters
    ----------
    ds : Dataset
        Read with ``require_tensions=False``; its folder holds currents.csv and, optionally,
        lengths.csv (else the nominal geometry's cable lengths at the measured poses).
    reference : str, optional
        The scale reference (:func:`cdprid.identify._scale.choose_reference`).
    model : {"auto", "translation", "full"}
    differentiator : str
        Only ``euler-filtfilt`` (its zero-phase filter is the drive columns' matched filter).
    params : dict, optional
        The differentiator's parameters (cutoff from the data when absent).
    t_start, t_end : float, optional
        Time window, s.
    trim, chunk : float, int
        Seconds dropped at each end after differentiation; samples per least-squares block.
    bound : bool
        Compute the Cramer-Rao bound of the platform parameters with the drives known.
    drives : DriveData, optional
        Default: robot.toml's drive fields.
    estimator : {"oe", "cls"}
        Output error (default; ``_currents_oe``) or the corrected least squares it starts from.
    progress : callable(str), optional
        Told each stage as it starts (the command's progress lines).
    clock_offset_s : float
        The drive streams' time stamps are this late against the poses' (s): subtracted
        (``diagnose --source currents`` finds it first).

    Returns
    -------
    CurrentsReport
    """
    say = progress or (lambda msg: None)
    _check_options(differentiator, estimator)
    m = ds.robot.n_cables
    drives = read_drives(ds.path) if drives is None and ds.path is not None else drives
    ref = choose_reference(reference, ds.robot, drives)
    (ct, cur_raw), lens = _streams(ds, m, clock_offset_s)
    pre, ds_i, sig, notes = _currents_aligned(ds, ct, cur_raw, t_start, t_end)
    fix = cutoff_from_data(differentiator, params)
    params, w0 = resolve_params(ds_i, sig, differentiator, params, notes)
    model, rot, warns = _choose_model(model, sig, ds.path, w0)
    motion = estimate_motion(sig, differentiator, params, angular=(model == "full"))
    wf, note, _ = _wrench_filter(ds.robot, differentiator, params, sig.dt, "matched")
    notes.append(note.replace("W tau", "every drive column"))
    keep = _trimmed(motion.t, trim, ds.path)
    lengths, keep = _lengths_on_pose_clock(ds, motion, lens, keep, notes)
    sig0 = dataclasses.replace(sig, tension=np.zeros_like(sig.tension))
    reg, wf, keep = _regression(ds, sig0, motion, model, differentiator, "matched", wf, keep,
                                trim, int(chunk), notes, warns)
    noise = _noise(ds, sig, ct, cur_raw, motion.t, lengths, wf, differentiator, params, pre)
    noise["lengths_measured"] = lens is not None
    idx, reg, D, rates = _design(ds, sig, motion, reg, keep, lengths, lens, ct, pre, wf,
                                 noise, differentiator, params, notes)
    say("corrected least squares")
    fit = _fit(ds, model, motion, idx, reg, D, ref, rates, noise, int(chunk), notes,
               _datasheet_prior(drives, ref, len(PARAMETER_NAMES[model]), m, notes))
    if estimator == "oe":
        say("output error, then its pose and encoder noise (re-noised refits and probes)")
        fit = _output_error(ds, sig, motion, model, differentiator, params, wf, keep, idx, reg,
                            trim, int(chunk), lengths, noise, ct, fit, ref, drives, notes, warns)
    cells = cells_against_drives(ds, model, motion, idx, np.asarray(sig.tension), lengths,
                                 noise.pop("sign"), wf, sig.dt, params, fit["theta"],
                                 fit["cov"], int(chunk), notes)
    rep = _report(ds, model, ref, drives, fit, motion, idx, rates, noise, bound, fix,
                  differentiator, params, notes, warns)
    rep = dataclasses.replace(rep, cond=float(fit["gls"].cond),
                              cond_scaled=float(fit["gls"].cond_scaled), rotation_deg=float(rot),
                              estimator=estimator, compared=fit.get("compared"))
    if cells is None:
        return rep
    return dataclasses.replace(rep, cells=cells, warnings=rep.warnings + cells.warnings)


def _check_options(differentiator: str, estimator: str) -> None:
    """One sentence (InputError) for a differentiator or estimator the currents path lacks."""
    if differentiator != "euler-filtfilt":
        raise InputError("--source currents uses the differentiator euler-filtfilt (its "
                         f"zero-phase filter is matched on every drive column), not "
                         f"{differentiator}.")
    if estimator not in ("cls", "oe"):
        raise InputError(f"--estimator: {estimator!r} is not one of cls, oe.")


def _output_error(ds, sig, motion, model, differentiator, params, wf, keep, idx, reg, trim,
                  chunk, lengths, noise, ct, fit, ref, drives, notes, warns) -> dict:
    """The output error refitted from the corrected least squares ``fit``
    (:mod:`cdprid.identify._currents_oe`), the pose noise's bias removed by re-noising
    (:mod:`cdprid.identify._currents_pose`)."""
    fit = refit_output_error(ds, fit["p"], motion, idx, reg, fit, ref, drives,
                             np.asarray(sig.tension), lengths, noise["sign"], wf, sig.dt,
                             params, noise, ct, notes, warns)
    if "oe" not in fit:
        return fit

    def regression(s, mo):
        """The platform regression of the poses of ``s`` at the kept samples ``idx``."""
        s0 = dataclasses.replace(s, tension=np.zeros_like(s.tension))
        r, _, k = _regression(ds, s0, mo, model, differentiator, "matched", wf, keep, trim,
                              chunk, [], [])
        return _SubRegression(r, np.searchsorted(np.flatnonzero(k), idx))

    st = RefitSetup(ds, model, differentiator, params, wf, idx, regression,
                    np.asarray(sig.tension), lengths, noise["sign"],
                    current_weights(noise, ct, sig.dt))
    sh = pose_noise_correction(st, sig, motion, fit["oe"].phi, fit["p"], ref, drives, noise)
    return shifted_fit(fit, sh, fit["p"], notes, warns)


def _currents_aligned(ds, ct, cur_raw, t_start, t_end):
    """``(pre, ds_i, sig, notes)``: the currents low-passed on their own clock when faster than
    the poses (``pre`` the cutoff or None) and aligned onto the pose clock as tensions."""
    pre = _prefilter_cutoff(ct, ds.pose_t)
    cur = cur_raw if pre is None else zero_phase_filter(cur_raw, _period(ct), pre)
    ds_i = dataclasses.replace(ds, tension_t=ct, tension=cur)
    sig = align(ds_i, t_start, t_end)
    notes = [n.replace("tension", "current") for n in sig.notes]
    if pre is not None:
        notes.append(f"currents low-passed at {pre:.3g} Hz on their own clock before the "
                     "interpolation onto the pose clock (their noise averaged; the Coulomb "
                     "column passes the same filter)")
    return pre, ds_i, sig, notes


def _datasheet_prior(drives, ref, p: int, m: int, notes: list):
    """Gaussian priors (precision, mean) on the fit's scale ``theta / v`` from the datasheet
    constants of the drives other than the reference that state a tolerance (std ``tol k /
    sqrt(3)``, the tolerance read as a uniform half-width); None without any."""
    if drives is None:
        return None
    q = p + 5 * m
    P, mean = np.zeros(q), np.zeros(q)
    for j, k0, tol in datasheet_drives(drives, ref, m):
        s = max(tol, 1e-6) * k0 / np.sqrt(3.0) / ref.value
        P[p + j], mean[p + j] = 1.0 / s ** 2, k0 / ref.value
    if not P.any():
        return None
    notes.append("the datasheet constants of the other drives enter as priors (their stated "
                 "tolerance read as a uniform half-width: std tol k / sqrt(3))")
    return P, mean


def _period(t) -> float:
    return float(np.median(np.diff(t)))


def _prefilter_cutoff(t_src, pose_t) -> float | None:
    """A stream sampled faster than the poses is low-passed at a quarter of the pose rate
    before its interpolation (None: not faster)."""
    dt, dtp = _period(t_src), _period(pose_t)
    return 0.25 / dtp if dt < dtp / 1.5 else None


def _design(ds, sig, motion, reg, keep, lengths, lens, ct, pre, wf, noise, differentiator,
            params, notes):
    """The kept samples, their regression, the drive design ``D`` and the rates
    ``(i, l', l'', sign)``; samples whose friction sign is unknown left out (a note)."""
    idx = np.flatnonzero(keep)
    if not np.array_equal(np.asarray(reg.t), motion.t[idx]):
        raise RuntimeError("the platform regression's samples differ from the kept samples")
    l_dot, l_ddot = _length_rates(lengths, sig.segments, sig.dt, differentiator, params)
    if lens is not None:
        v_fast, s_v = _fast_rate(lens[0], lens[1], motion.t)
        v_cur, _ = _fast_rate(lens[0], lens[1], ct)
    else:
        v_fast, s_v = l_dot, noise["length_m"] * np.sqrt(noise["C"][1, 1])
        v_cur = np.column_stack([np.interp(ct, motion.t, v) for v in l_dot.T])
    sign, still, noise["v_zone"] = _friction_sign(v_fast, s_v, params, sig.dt)
    sign_c = _expected_sign(v_cur, s_v)
    if pre is not None:
        sign_c = zero_phase_filter(sign_c, _period(ct), pre)
    sign = np.column_stack([np.interp(motion.t, ct, v) for v in sign_c.T])
    noise["sign"] = sign
    D = _drive_design(ds, motion, np.asarray(sig.tension), lengths, sign, wf, sig.dt,
                      params)[idx]
    rates = (np.asarray(sig.tension)[idx], l_dot[idx], l_ddot[idx], sign[idx])
    use = ~still[idx]
    notes.append(f"{100 * np.mean(~use):.1f} % of the samples left out: a winch's velocity "
                 "within 3 std of its noise from zero (the Coulomb friction's sign unknown), and "
                 f"the matched filter's reach around a winch below {1000 * noise['v_zone']:.2g} "
                 f"mm/s for more than {STILL_S:g} s (at rest: stiction)")
    return (idx[use], _SubRegression(reg, np.flatnonzero(use)), D[use],
            tuple(x[use] for x in rates))


def _lengths_on_pose_clock(ds, motion, lens, keep, notes: list):
    """Paid-out lengths at the pose times: the encoders interpolated, else the nominal
    geometry's cable lengths at the measured poses (a note)."""
    if lens is not None:
        return _interp_checked(lens[0], lens[1], motion.t, "lengths", keep, notes)
    import jax

    notes.append("no lengths.csv: the paid-out lengths are the nominal geometry's cable lengths "
                 "at the measured poses")
    L = jax.vmap(lambda p, R: cable_lengths(ds.robot, p, R))(motion.position, motion.B_R_P)
    return np.asarray(L), keep


def _noise(ds, sig, ct, cur, t, lengths, wf, differentiator, params, pre=None) -> dict:
    """Noise levels: currents per sample of their own stream (A), encoder lengths on the pose
    clock (m), pose; the filter gains ``g_i`` (currents through interpolation and F) and ``C``
    (:func:`cdprid.core._eiv.noise_gains`)."""
    s_cur = estimate_noise(np.asarray(cur, float))
    _, _, s_pos, s_rot = noise_levels(dataclasses.replace(ds, tension_t=ct, tension=cur), sig)
    C = noise_gains(differentiator, params, sig.dt, wf)
    return {"current_A": s_cur, "g_current": _filter_gain(ct, t, wf, pre),
            "length_m": estimate_noise(np.asarray(lengths, float)), "position_m": s_pos,
            "rotation_rad": s_rot, "C": C}


def _tension_noise(d: DriveParameters, noise: dict) -> np.ndarray:
    """Per cable, the std ``s`` with ``C00 s^2`` = the filtered residual tension variance of
    the drive model (current noise x k, encoder noise through J and f_v)."""
    C = noise["C"]
    var = (d.k ** 2 * noise["current_A"] ** 2 * noise["g_current"]
           + (d.J ** 2 * C[2, 2] + d.fv ** 2 * C[1, 1] + 2 * d.J * d.fv * C[1, 2])
           * noise["length_m"] ** 2)
    return np.sqrt(np.maximum(var, 0.0) / C[0, 0])


def _fit(ds, model, motion, idx, reg, D, ref, rates, noise, chunk, notes, prior=None):
    """OLS, EIV whitening, GLS with HAC and the corrected normal equations; the scaled
    estimate. Returns a dict (theta, cov, cov_iid, the GLS result, residual, names, p)."""
    p = len(PARAMETER_NAMES[model])
    m = ds.robot.n_cables
    names = PARAMETER_NAMES[model] + drive_names(m)
    r = ref.index(p)
    o = np.delete(np.arange(len(names)), r)
    n = len(idx)

    def full(i0, i1):
        return np.concatenate([reg.wrench_block(i0, i1)[0], -D[i0:i1]], axis=2)

    def rows(i0, i1, U=None):
        M = full(i0, i1) if U is None else np.matmul(U[i0:i1], full(i0, i1))
        return M[:, :, o], -M[:, :, r]

    ols = least_squares_blocks(rows, n, tuple(names[k] for k in o), covariance="iid",
                               chunk=chunk)
    theta0, _ = scaled_estimate(ols.x, ols.cov, ref, r)
    d0 = DriveParameters.from_vector(theta0[p:])
    sub, tau0 = _padded(_sub_motion(motion, idx), drive_tension(d0, *rates))
    U = whitening(ds.robot, model, sub, tau0, theta0[:p], _tension_noise(d0, noise),
                  max(noise["position_m"], 1e-12), noise["rotation_rad"], noise["C"],
                  chunk=chunk)[:n]
    gls = least_squares_blocks(lambda a, b: rows(a, b, U), n, tuple(names[k] for k in o),
                               covariance="hac", chunk=chunk)
    N, Q = normal_and_noise(full, U, n, m, p, noise, chunk)
    phi, Ai, Po, extra, mu = corrected(N, Q, o, r, n / max(float(gls.hac_bandwidth), 1.0),
                                       prior)
    notes.append(EIV_CURRENTS_NOTE)
    No = N[np.ix_(o, o)]

    def cov_of(C):
        return Ai @ (No @ C @ No + np.diag(Po)) @ Ai + np.outer(extra, extra)

    theta, cov = scaled_estimate(phi, cov_of(gls.cov), ref, r)
    _, cov_iid = scaled_estimate(phi, cov_of(gls.cov_iid), ref, r)
    noise["eiv_share"] = mu
    resid = np.concatenate([(full(i0, min(n, i0 + chunk)) @ theta).reshape(-1)
                            for i0 in range(0, n, chunk)])
    return {"theta": theta, "cov": cov, "cov_iid": cov_iid, "gls": gls, "resid": resid,
            "names": names, "p": p}


def _padded(sub, tau, bucket: int = 2048):
    """The samples repeated at the end up to a multiple of ``bucket`` (the whitening's
    compiled shapes then repeat across recordings; its extra rows are dropped)."""
    n = len(tau)
    k = (-n) % bucket
    if k == 0:
        return sub, tau
    pad = np.r_[np.arange(n), np.full(k, n - 1)]
    from types import SimpleNamespace

    return SimpleNamespace(**{a: v[pad] for a, v in vars(sub).items()}), tau[pad]


def _sub_motion(motion, idx):
    """The kept samples' motion (a namespace for :func:`cdprid.core._eiv.whitening`)."""
    from types import SimpleNamespace

    return SimpleNamespace(**{k: np.asarray(getattr(motion, k))[idx] for k in (
        "t", "position", "B_R_P", "velocity", "acceleration", "omega", "alpha")})


def _report(ds, model, ref, drives, fit, motion, idx, rates, noise, bound, fix,
            differentiator, params, notes, warns) -> CurrentsReport:
    """The report: datasheet checks, excitation guard and the bound."""
    p, theta, cov = fit["p"], fit["theta"], fit["cov"]
    gls = fit["gls"]
    warns = list(warns)
    d = DriveParameters.from_vector(theta[p:])
    sd = DriveParameters.from_vector(np.sqrt(np.clip(np.diag(cov), 0, None))[p:])
    nominal = None if drives is None else drives.k_nominal
    if nominal is not None:
        for j in range(len(d.k)):
            tol = drives.tolerance[j]
            dev = abs(d.k[j] / nominal[j] - 1.0)
            lim = (0.0 if np.isnan(tol) else tol) * nominal[j] + 1.96 * sd.k[j]
            if abs(d.k[j] - nominal[j]) > lim and not np.isnan(tol):
                warns.append(f"drive {j + 1}: k = {d.k[j]:.4g} +- {sd.k[j]:.2g} N/A is "
                             f"{100 * dev:.1f} % from its datasheet {nominal[j]:.4g} N/A, "
                             f"beyond the stated tolerance {tol:g}: check the drive data.")
    if not np.all(np.isfinite(cov)):
        warns.append(f"cannot tell: along one combination of the parameters the currents' noise "
                     f"makes {100 * noise['eiv_share']:.0f} % of the regressor's energy, so the "
                     "errors-in-variables correction does not determine the estimate (every std "
                     "is infinite): record longer, excite more, or lower the current noise.")
    elif noise.get("eiv_share", 0.0) > EIV_SHARE_WARN:
        warns.append(f"weak identification: along one combination of the parameters the "
                     f"currents' noise makes {100 * noise['eiv_share']:.0f} % of the regressor's "
                     "energy; the errors-in-variables correction's sensitivity is in the std.")
    if gls.cond_scaled > 1e3:
        warns.append(f"too little excitation: cond of the joint regressor (scaled) = "
                     f"{gls.cond_scaled:.3g} > 1e3; check the std (cdprid excite).")
    crb_std = None
    if bound:
        crb_std = _platform_bound(ds, model, theta, motion, idx, d, rates, noise, notes)
    sig = float(np.sqrt(np.mean(fit["resid"] ** 2)))
    if fix:
        notes.append("cutoff chosen from the data")
    return CurrentsReport(model, tuple(fit["names"]), theta, cov, fit["cov_iid"], ref, nominal,
                          len(idx), sig, float(gls.hac_bandwidth), crb_std, differentiator,
                          params, tuple(notes), tuple(warns))


def _platform_bound(ds, model, theta, motion, idx, d, rates, noise, notes):
    """The platform parameters' Cramer-Rao bound with the drives known (tension noise of the
    drive model): a lower bound of the joint problem's."""
    p = len(PARAMETER_NAMES[model])
    sub = _sub_motion(motion, idx)
    try:
        with np.errstate(all="ignore"):
            b = crb_bound(ds.robot, model, theta[:p], sub.t, sub.position, sub.B_R_P,
                          sub.acceleration, sub.omega, sub.alpha, drive_tension(d, *rates),
                          _tension_noise(d, noise),
                          max(noise["position_m"], 1e-12), noise["rotation_rad"])
    except (np.linalg.LinAlgError, ValueError, FloatingPointError) as e:
        notes.append(f"Cramer-Rao bound not computed ({e})")
        return None
    if not np.all(np.isfinite(b.std)) or not np.all(b.std > 0):
        notes.append("Cramer-Rao bound not computed (the information matrix is singular)")
        return None
    notes.append("crb_std: the platform parameters' Cramer-Rao bound with the drive "
                 "parameters known (a lower bound of this problem's)")
    return np.asarray(b.std)
