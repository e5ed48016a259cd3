"""Identification from free motion with locked winches (``identify --source free-motion``).

A robot with fewer than six cables, its winches locked, swings freely: the cable tensions are
unknown but act only along ``range(W)``. Projected on the free directions (an orthonormal
basis ``N_n`` of the null space of ``W_n^T``, forces and moments scaled alike by the platform
radius) the Newton-Euler equations lose the tensions,

    N_n^T Z_n x = 0,

homogeneous in the platform parameters: the mass (a weighed mass or a stated static weight,
:mod:`cdprid.identify._scale`) fixes the scale. ``Z`` is the matched-filter regressor of the
tension path (zero tensions); the projection is exact for the instantaneous equations and
second order in the pose change within the filter's window. HAC covariance, the reference's
uncertainty propagated. Where load cells are present, each is calibrated against the
identified dynamics (:mod:`cdprid.identify._cells`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import TRIM_S, InputError
from cdprid.core import (
    CHUNK,
    estimate_motion,
    least_squares_blocks,
    platform_radius,
    wrench_matrices,
)
from cdprid.identify._auto import cutoff_from_data, resolve_params
from cdprid.identify._batch import _choose_model, _regression, _wrench_filter
from cdprid.identify._cells import CellCalibration, calibrate_cells
from cdprid.identify._episodes import _trimmed
from cdprid.identify._scale import ScaleReference, choose_reference, scaled_estimate
from cdprid.io import align
from cdprid.model import PARAMETER_NAMES

__all__ = ["FreeMotionReport", "identify_free_motion"]


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

    @property
    def std(self) -> np.ndarray:
        """HAC standard deviations (reference propagated)."""
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

    def table(self) -> str:
        """Plain-text table, the load cells' calibration after it."""
        from cdprid.identify._currents_json import result_table

        text = result_table(f"source: free-motion   model: {self.model}   samples: "
                            f"{self.n_samples}", self.names, self.theta, self.std,
                            self.reference, self.notes, self.warnings)
        return text if self.cells is None else text + "\n" + self.cells.table()

    def as_json(self) -> dict:
        """JSON of ``identify --source free-motion`` (keys of ``identify --json``, plus
        ``scale_reference`` and ``load_cells``)."""
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
                "warnings": list(self.warnings), "notes": list(self.notes)}


def _placeholder_tensions(ds):
    """A dataset whose tension stream, when absent, is ones on the pose clock: the alignment
    needs a stream; the projected equations never use it."""
    if ds.tension is not None:
        return ds
    return dataclasses.replace(ds, tension_t=ds.pose_t,
                               tension=np.ones((len(ds.pose_t), ds.robot.n_cables)))


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


def identify_free_motion(ds, reference: str | None = None, model: str = "auto",
                         params: dict | None = None, t_start: float | None = None,
                         t_end: float | None = None, trim: float = TRIM_S,
                         chunk: int = CHUNK, check_cutoff: bool = True) -> FreeMotionReport:
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

    Returns
    -------
    FreeMotionReport
    """
    m = ds.robot.n_cables
    if m >= 6:
        raise InputError(f"--source free-motion needs fewer than 6 cables (this robot has {m}): "
                         "locked cables leave the platform no free direction to swing in.")
    ref = choose_reference(reference, ds.robot, None, allow_drive=False)
    dsa = _placeholder_tensions(ds)
    sig = align(dsa, t_start, t_end)
    notes = list(sig.notes) if ds.tension is not None else []
    diff = "euler-filtfilt"
    fix = cutoff_from_data(diff, params)
    params, w0 = resolve_params(dsa, sig, diff, params, notes)
    model, _, warns = _choose_model(model, sig, ds.path, w0)
    motion = estimate_motion(sig, diff, params, angular=(model == "full"))
    wf, note, _ = _wrench_filter(ds.robot, diff, params, sig.dt, "matched")
    keep = _trimmed(motion.t, trim, ds.path)
    sig0 = dataclasses.replace(sig, tension=np.zeros_like(sig.tension))
    reg, wf, keep = _regression(dsa, sig0, motion, model, diff, "matched", wf, keep, trim,
                                int(chunk), notes, warns)
    idx = np.flatnonzero(keep)
    rho = platform_radius(ds.robot)
    W = np.asarray(wrench_matrices(ds.robot, motion.position[idx], motion.B_R_P[idx]))
    ref_i = ref.index(len(PARAMETER_NAMES[model]))
    names = PARAMETER_NAMES[model]
    o = np.delete(np.arange(len(names)), ref_i)

    def rows(i0, i1):
        Z = projected_regressor(reg.wrench_block(i0, i1)[0], W[i0:i1], rho)
        return Z[:, :, o], -Z[:, :, ref_i]

    res = least_squares_blocks(rows, len(idx), tuple(names[k] for k in o), covariance="hac",
                               chunk=int(chunk))
    theta, cov = scaled_estimate(res.x, res.cov, ref, ref_i)
    _, cov_iid = scaled_estimate(res.x, res.cov_iid, ref, ref_i)
    notes += [note, f"free motion: the Newton-Euler equations projected on the {6 - m} free "
              "directions of the locked cables at each pose (null space of W^T); ordinary "
              "least squares with HAC std (the pose noise inside the regressor is not "
              "corrected)"] + (["cutoff chosen from the data"] if fix else [])
    cells = None
    if ds.tension is not None:
        cells = calibrate_cells(reg, W, sig, wf, idx, theta, cov, int(chunk), rho)
        warns += list(cells.warnings)
    rep = FreeMotionReport(model, tuple(names), theta, cov, cov_iid, ref, len(idx),
                           float(ref.value * res.sigma_rho), float(res.hac_bandwidth), cells,
                           diff, params, tuple(notes), tuple(warns))
    if not check_cutoff:
        return rep
    c2 = min(2.0 * float(params["cutoff_hz"]), 0.4 / sig.dt)
    other = identify_free_motion(ds, reference, model, dict(params, cutoff_hz=c2), t_start,
                                 t_end, trim, chunk, check_cutoff=False)
    return dataclasses.replace(rep, warnings=rep.warnings + tuple(_cutoff_warning(rep, other,
                                                                                 c2)))


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
