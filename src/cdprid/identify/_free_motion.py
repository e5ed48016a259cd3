"""Identification from free motion with locked winches (``identify --source free-motion``).

A robot with fewer than six cables, its winches locked, swings freely: the cable tensions are
unknown but act only along ``range(W)``. Projected on the free directions (an orthonormal
basis ``N_n`` of the null space of ``W_n^T``, forces and moments scaled alike by the platform
radius) the Newton-Euler equations lose the tensions,

    N_n^T S Z_n x = 0,

homogeneous in the platform parameters: the mass (a weighed mass or a stated static weight,
:mod:`cdprid.identify._scale`) fixes the scale. The rows are projected at the measured poses
and then filtered (:mod:`cdprid.identify._free_rows`: exact for any cutoff); pushes by hand
are located and left out (:mod:`cdprid.identify._free_pushes`); the fit is checked on its
time thirds and at twice the cutoff. The pose noise inside the rows (errors in variables) is
corrected (:mod:`cdprid.identify._free_eiv`). HAC covariance, the reference's uncertainty
propagated.
Where load cells are present, each is calibrated against the identified dynamics in the
wrench space (:func:`cdprid.identify._cells.calibrate_cells_wrench`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import TRIM_S, InputError
from cdprid.core import (
    CHUNK,
    estimate_motion,
    platform_radius,
    segment_mask,
    wrench_matrices,
)
from cdprid.episodes import FAR_PER_HOUR
from cdprid.identify._auto import cutoff_from_data, resolve_params
from cdprid.identify._batch import _choose_model, _regression, _wrench_filter
from cdprid.identify._cells import CellCalibration, calibrate_cells_wrench
from cdprid.identify._episodes import _trimmed
from cdprid.identify._free_eiv import pose_noise_bias
from cdprid.identify._free_pushes import left_out
from cdprid.identify._free_rows import (
    com_over_thirds,
    fit_rows,
    free_directions,
    projected_filtered_rows,
    projected_regressor,
    widen_cutoff,
    window_disagreement,
)
from cdprid.identify._scale import ScaleReference, choose_reference, scaled_estimate
from cdprid.io import align
from cdprid.model import PARAMETER_NAMES

__all__ = ["FreeMotionReport", "free_directions", "identify_free_motion", "projected_regressor"]


@dataclasses.dataclass(frozen=True)
class FreeMotionReport:
    """What :func:`identify_free_motion` produced.

    Attributes
    ----------
    model : str
    names : tuple of str
    theta, cov, cov_iid : the estimate and its HAC and i.i.d. covariances (reference included)
    reference : ScaleReference
    n_samples : int
    sigma_rho : float
        RMS of the projected residual (scaled wrench units: N).
    hac_bandwidth : float
    cells : CellCalibration or None
        The load cells' gains and offsets against the identified dynamics.
    notes, warnings : tuple of str
    episodes : tuple of Episode
        The pushes the energy balance located (left out unless kept).
    """

    model: str
    names: tuple
    theta: np.ndarray
    cov: np.ndarray
    cov_iid: np.ndarray
    reference: ScaleReference
    n_samples: int
    sigma_rho: float
    hac_bandwidth: float
    cells: CellCalibration | None
    differentiator: str
    params: dict
    notes: tuple = ()
    warnings: tuple = ()
    episodes: tuple = ()

    @property
    def std(self) -> np.ndarray:
        """HAC standard deviations (reference propagated)."""
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

    def table(self) -> str:
        """Plain-text table, the load cells' calibration after it.

        Returns
        -------
        str
            Lines without a trailing newline.
        """
        from cdprid.identify._currents_json import result_table

        text = result_table(f"source: free-motion   model: {self.model}   samples: "
                            f"{self.n_samples}", self.names, self.theta, self.std,
                            self.reference, self.notes, self.warnings)
        return text if self.cells is None else text + "\n" + self.cells.table()

    def as_json(self) -> dict:
        """JSON of ``identify --source free-motion``.

        Returns
        -------
        dict
            The keys of ``identify --json``, plus ``scale_reference`` and ``load_cells``.
        """
        from cdprid.identify._currents_json import parameter_entry

        s = self.std
        si = np.sqrt(np.clip(np.diag(self.cov_iid), 0, None))
        params = {n: parameter_entry(v, a, b) for n, v, a, b in zip(
            self.names, self.theta, s, si, strict=True)}
        return {"source": "free-motion", "model": self.model, "parameters": params,
                "sigma_rho": self.sigma_rho, "n_samples": self.n_samples,
                "differentiator": self.differentiator, "differentiator_params": self.params,
                "weighting": "none", "covariance": "hac",
                "hac_bandwidth_samples": self.hac_bandwidth, "wrench_filter": "matched",
                "scale_reference": self.reference.as_json(),
                "load_cells": None if self.cells is None else self.cells.as_json(),
                "episodes": [e.as_json() for e in self.episodes],
                "warnings": list(self.warnings), "notes": list(self.notes)}


def _placeholder_tensions(ds):
    """A dataset whose tension stream, when absent, is ones on the pose clock: the alignment
    needs a stream; the projected equations never use it."""
    if ds.tension is not None:
        return ds
    return dataclasses.replace(ds, tension_t=ds.pose_t,
                               tension=np.ones((len(ds.pose_t), ds.robot.n_cables)))


def _lagged(ds, tension_lag: float):
    """The dataset with its tension clock shifted by ``tension_lag`` s, and the same with
    placeholder tensions when it has none (:func:`_placeholder_tensions`)."""
    if ds.tension is not None and tension_lag:
        ds = dataclasses.replace(ds, tension_t=np.asarray(ds.tension_t) + float(tension_lag))
    return ds, _placeholder_tensions(ds)


def identify_free_motion(ds, reference: str | None = None, model: str = "auto",
                         params: dict | None = None, t_start: float | None = None,
                         t_end: float | None = None, trim: float = TRIM_S,
                         chunk: int = CHUNK, check_cutoff: bool = True,
                         keep_episodes: bool | None = False,
                         far_per_hour: float = FAR_PER_HOUR,
                         tension_lag: float = 0.0, eiv: bool = True) -> FreeMotionReport:
    """Identify the platform from its free motion with locked winches (poses alone).

    Parameters
    ----------
    ds : Dataset
        Fewer than six cables; tensions optional (calibrated against the result when given).
    reference : str, optional
        ``mass`` or ``mass:KG[:STD_KG]`` (:func:`cdprid.identify._scale.choose_reference`).
    model : {"auto", "translation", "full"}
    params : dict, optional
        Parameters of the euler-filtfilt differentiator (cutoff from the data when absent).
    t_start, t_end : float, optional
        Time window, s.
    trim : float
        Seconds dropped at each end after differentiation.
    chunk : int
        Samples per block.
    check_cutoff : bool
        Fit again at twice the cutoff; warn when an estimate moves by > 3 combined std.
    keep_episodes : bool or None
        Report the episodes (pushes) located but keep their samples; None: do not locate.
    far_per_hour : float
        False-alarm rate of the episodes stage, episodes per hour of push-free recording.
    tension_lag : float
        Seconds added to the tension clock before the load cells are calibrated (their clock
        offset: positive when the tension log leads the poses; UACDPR: about 0.025 s).
    eiv : bool
        Correct the pose noise's errors in variables (:mod:`cdprid.identify._free_eiv`).

    Returns
    -------
    FreeMotionReport
    """
    if (m := ds.robot.n_cables) >= 6:
        raise InputError(f"--source free-motion needs fewer than 6 cables (this robot has {m}): "
                         "locked cables leave the platform no free direction to swing in.")
    ref = choose_reference(reference, ds.robot, None, allow_drive=False)
    (ds, dsa), diff = _lagged(ds, tension_lag), "euler-filtfilt"
    sig, fix = align(dsa, t_start, t_end), cutoff_from_data(diff, params)
    notes = list(sig.notes) if ds.tension is not None else []
    params, w0 = resolve_params(dsa, sig, diff, params, notes)
    params = widen_cutoff(dsa, sig, params, notes) if fix else params
    model, _, warns = _choose_model(model, sig, ds.path, w0)
    motion = estimate_motion(sig, diff, params, angular=(model == "full"))
    rho, names = platform_radius(ds.robot), PARAMETER_NAMES[model]
    P = projected_filtered_rows(ds.robot, sig, motion, model, params, rho, int(chunk))
    ref_i = ref.index(len(names))
    use = segment_mask(motion.t, motion.segments, trim) & _trimmed(motion.t, trim, ds.path)
    excl, eps, extra = _left_out(ds, sig, P, ref, ref_i, names, params, trim, far_per_hour,
                                 keep_episodes, use, chunk)
    res = _fit(P, idx := np.flatnonzero(use & ~excl), ref_i, names, chunk, ds.path)
    notes += [_METHOD_NOTE.format(6 - m, diff)] + (["cutoff chosen from the data"] if fix
                                                    else []) + extra[0]
    warns += extra[1]
    res = _eiv_corrected(ds.robot, dsa, sig, motion, model, params, rho, chunk, idx, ref_i,
                         res, (notes, warns), P) if eiv else res
    res = _window_scaled(P, idx, ref_i, names, chunk, sig.t, ref.value, res, notes, warns)
    theta, cov = scaled_estimate(res.x, res.cov, ref, ref_i)
    _, cov_iid = scaled_estimate(res.x, res.cov_iid, ref, ref_i)
    notes += [f"tension clock shifted by {float(tension_lag):+g} s before the load cells' "
              "calibration (tension_lag)"] if tension_lag and ds.tension is not None else []
    cells = None if ds.tension is None else _cells(ds, sig, motion, model, diff, params, idx,
                                                   theta, cov, chunk, rho, notes, warns, eiv)
    rep = FreeMotionReport(model, tuple(names), theta, cov, cov_iid, ref, len(idx),
                           float(ref.value * res.sigma_rho), float(res.hac_bandwidth), cells,
                           diff, params, tuple(notes), tuple(warns), tuple(eps))
    if not check_cutoff:
        return rep
    c2 = min(2.0 * float(params["cutoff_hz"]), 0.4 / sig.dt)  # the same fit at twice the cutoff
    other = identify_free_motion(ds, reference, model, dict(params, cutoff_hz=c2), t_start,
                                 t_end, trim, chunk, False, keep_episodes, far_per_hour, 0.0, eiv)
    return dataclasses.replace(rep, warnings=rep.warnings + tuple(_cutoff_warning(rep, other, c2)))


_METHOD_NOTE = ("free motion: the Newton-Euler equations projected on the {} free directions of "
                "the locked cables at each measured pose (null space of W^T), then through the "
                "{} zero-phase low-pass (projected, then filtered: exact for any cutoff); "
                "ordinary least squares with HAC std")


def _fit(P, idx, ref_i, names, chunk, path):
    """:func:`cdprid.identify._free_rows.fit_rows`, refused in one sentence when too few
    samples are left."""
    if len(idx) < 2 * P.shape[2]:
        raise InputError(f"{path}: only {len(idx)} samples of free motion are left after the "
                         "trimmed edges and the pushes located (at least "
                         f"{2 * P.shape[2]} needed): record a longer release or pass "
                         "--keep-episodes.")
    return fit_rows(P, idx, ref_i, names, chunk)


def _eiv_corrected(robot, dsa, sig, motion, model, params, rho, chunk, idx, ref_i, res, said,
                   P):
    """The fit with the pose noise's second-order bias removed and its covariance inflated by
    the correction's own (:func:`cdprid.identify._free_eiv.pose_noise_bias`); a note says by
    how much, a warning when the correction exceeds the least-squares std (``said``: the notes
    and warnings lists)."""
    notes, warns = said
    def rows(s, mo):
        return projected_filtered_rows(robot, s, mo, model, params, rho, int(chunk))

    pb = pose_noise_bias(dsa, sig, motion, rows, idx, ref_i, P, res.hac_bandwidth)
    s = np.sqrt(np.clip(np.diag(res.cov), 1e-300, None))
    k = int(np.argmax(np.abs(pb.bias) / s))
    ratio = np.sqrt(np.clip(np.diag(pb.cov_boot), 0, None)) / s
    rot = "" if pb.s_rot is None else f", {1e3 * pb.s_rot:.2g} mrad"
    notes.append(f"errors in variables: the pose noise's second-order bias ({1e3 * pb.s_pos:.2g} "
                 f"mm{rot}, from the poses' 4th differences) removed from the normal matrix "
                 f"({pb.pairs} antithetic pairs of re-noised poses); largest shift "
                 f"{res.names[k]} by {pb.bias[k] / s[k]:+.2f} std; the pose noise's bootstrap "
                 f"std is {np.min(ratio):.2f}-{np.max(ratio):.2f} times the HAC std")
    if pb.share > 0.5:
        warns.append(f"the pose noise makes up {100 * pb.share:.0f} % of the free-motion rows' "
                     "power in one combination of the parameters: the corrected estimate is "
                     f"{1 / (1 - pb.share):.1f} times noisier there than least squares (whose "
                     "bias it removes); a lower --params cutoff_hz or larger swings help")
    if abs(pb.bias[k]) > s[k]:
        warns.append(f"the pose noise's bias correction moved {res.names[k]} by "
                     f"{pb.bias[k] / s[k]:+.1f} std: it rests on white pose noise at the levels "
                     "the 4th differences measure; coloured noise (a marker fit, a Kalman "
                     "filter) or a motion with power near the Nyquist frequency leaves part of "
                     "the bias (the load cells' intervals inherit it): larger swings shrink it")
    f = np.sqrt(np.maximum(1.0, pb.inflation))  # the correction's own variance, when it adds

    def cov(c):
        return f[:, None] * (pb.bread @ c @ pb.bread.T) * f[None, :] + pb.cov_mc

    return dataclasses.replace(res, x=res.x - pb.bias, cov=cov(res.cov), cov_iid=cov(res.cov_iid))


def _window_scaled(P, idx, ref_i, names, chunk, t, value, res, notes, warns):
    """The fit with its covariances multiplied by the time thirds' Birge ratio when above 1
    (:func:`cdprid.identify._free_rows.window_disagreement`; its warning and a note added)."""
    w2, r2 = window_disagreement(P, idx, ref_i, names, chunk, t, value)
    thirds = com_over_thirds(P, idx, ref_i, names, chunk, t)
    if thirds and w2:  # the data do not decide z_G beyond the thirds' spread: say by how much
        w2 = [w2[0] + " " + thirds[0].upper() + thirds[1:] + "."]
    elif thirds:
        notes.append(thirds)
    warns += w2
    if r2 <= 1.0:
        return res
    notes.append(f"covariance scaled by {r2:.3g}: the time thirds' spread (Birge ratio)")
    return dataclasses.replace(res, cov=r2 * res.cov, cov_iid=r2 * res.cov_iid)


def _left_out(ds, sig, P, ref, ref_i, names, params, trim, far_per_hour, keep_episodes, use,
              chunk):
    """The pushes located (:func:`cdprid.identify._free_pushes.left_out`) and the samples
    left out: ``(excluded, episodes, (notes, warnings))``."""
    if keep_episodes is None:
        return np.zeros(len(sig.t), bool), (), (["pushes not located (keep_episodes=None)"], [])
    excl, eps, caveat, margin_s = left_out(ds, sig, P, ref_i, ref.value, names,
                                           float(params["cutoff_hz"]), trim, far_per_hour, use,
                                           chunk)
    notes = _episode_notes(eps, excl, keep_episodes, ds.tension is not None, margin_s)
    if keep_episodes:
        excl = np.zeros_like(excl)
    warns = [caveat] if caveat else []
    if ds.tension is None:
        warns.append("no load cells: pushes were located in the free directions' residual "
                     "alone (the energy balance and the cable wrench residual need tensions); "
                     "a push that the scan misses biases every parameter (on simulated "
                     "recordings z_G by up to a factor 2)")
    return excl, eps, (notes, warns)


def _episode_notes(eps, excl, keep_episodes, has_tension: bool, margin_s: float) -> list:
    """The sentence on the pushes located (or none)."""
    how = ("the episodes stage (cable wrench residual, energy balance) and the free "
           "directions' residual scan" if has_tension else "the free directions' residual scan")
    if not eps:
        return [f"{how} located no push"]
    spans = ", ".join(f"{e.kind} {e.start_s:.2f}-{e.end_s:.2f} s" for e in eps)
    if keep_episodes:
        return [f"{len(eps)} episode(s) located by {how} and kept (--keep-episodes): {spans}"]
    return [f"{len(eps)} episode(s) located by {how} and left out: {spans}; "
            f"{int(excl.sum())} samples, {margin_s:.2g} s of filter transient on each side"]


#: Said with a load-cell calibration from free motion fitted without the errors-in-variables
#: correction (``eiv=False``): what its intervals do not hold.
CELLS_CAVEAT = ("load cells: their intervals hold the free-motion estimate's HAC covariance, "
                "which does not hold the pose noise inside the regressor (uncorrected errors in "
                "variables: on small simulated swings the platform estimate sat up to 4 std "
                "off, and the cells' 95 % intervals covered 18 of 32 gains and offsets); read "
                "them as lower bounds and prefer a static calibration against known weights")


def _cells(ds, sig, motion, model, diff, params, idx, theta, cov, chunk, rho, notes, warns,
           eiv=True):
    """The load cells against the identified dynamics on the kept samples (with
    :data:`CELLS_CAVEAT` when the pose noise was not corrected)."""
    wf, _, _ = _wrench_filter(ds.robot, diff, params, sig.dt, "matched")
    keep = np.zeros(len(sig.t), bool)
    keep[idx] = True
    reg, wf, keep2 = _regression(ds, sig, motion, model, diff, "matched", wf, keep, 0.0,
                                 int(chunk), [""], [])
    W = np.asarray(wrench_matrices(ds.robot, motion.position, motion.B_R_P))
    cells = calibrate_cells_wrench(reg, W, sig, wf, np.flatnonzero(keep2), theta, cov,
                                   int(chunk), rho)
    warns += list(cells.warnings)
    if not eiv:
        warns.append(CELLS_CAVEAT)
    return cells


def _cutoff_warning(rep: FreeMotionReport, other: FreeMotionReport, c2: float) -> list:
    """One sentence when the estimates at twice the cutoff differ by more than 3 combined std."""
    z = np.abs(other.theta - rep.theta) / np.sqrt(rep.std ** 2 + other.std ** 2 + 1e-300)
    k = int(np.argmax(z))
    if z[k] <= 3.0:
        return []
    return [f"the estimate depends on the filter: at a cutoff of {c2:.3g} Hz {rep.names[k]} is "
            f"{other.theta[k]:.4g} instead of {rep.theta[k]:.4g} ({z[k]:.1f} combined std): "
            "forces the free-motion model lacks (pushes, geometry errors leaking the weight into "
            "the free directions) bias it; check the geometry and use a push-free release."]
