"""End-to-end identification of a dataset: the data path in one call.

dataset -> :func:`~cdprid.io.align` -> :func:`~cdprid.motion.estimate_motion` ->
:func:`~cdprid.regression.build_regression` -> :func:`~cdprid.identification.least_squares`.
"""

from __future__ import annotations

import dataclasses
import functools

from .differentiators import METHODS, zero_phase_filter
from .dynamics import PARAMETER_NAMES
from .identification import LSResult, least_squares
from .io.dataset import AlignedSignals, Dataset, align
from .motion import Motion, estimate_motion
from .regression import Regression, build_regression

__all__ = ["IdentificationReport", "identify_dataset", "DEFAULT_TRIM_S"]

DEFAULT_TRIM_S = 1.0
"""Seconds dropped at both ends after differentiation (filter and observer transients)."""


@dataclasses.dataclass(frozen=True)
class IdentificationReport:
    """Everything an identification produced.

    Attributes
    ----------
    result : LSResult
    model : str
    differentiator : str
    params : dict
    n_samples : int
        Time samples used (each gives 6 equations).
    signals : AlignedSignals
    motion : Motion
    regression : Regression
        The samples used (after trimming).
    notes : tuple of str
    """

    result: LSResult
    model: str
    differentiator: str
    params: dict
    n_samples: int
    signals: AlignedSignals
    motion: Motion
    regression: Regression
    notes: tuple = ()

    def as_json(self) -> dict:
        """The JSON contract of ``cdprid identify --json``."""
        r = self.result
        return {
            "model": self.model,
            "parameters": r.as_dict(),
            "sigma_rho": r.sigma_rho,
            "cond": r.cond,
            "cond_scaled": r.cond_scaled,
            "n_samples": self.n_samples,
            "differentiator": self.differentiator,
            "differentiator_params": self.params,
            "weighting": "groups" if r.weights is not None else "none",
            "covariance": r.covariance,
            "hac_bandwidth_samples": r.hac_bandwidth if r.covariance == "hac" else None,
            "notes": list(self.notes),
        }


def identify_dataset(
    ds: Dataset,
    model: str = "translation",
    differentiator: str = "euler-filtfilt",
    params: dict | None = None,
    t_start: float | None = None,
    t_end: float | None = None,
    trim: float = DEFAULT_TRIM_S,
    weighting: str = "none",
    matched_filter: bool | None = None,
    covariance: str = "hac",
) -> IdentificationReport:
    """Identify the platform's dynamic parameters from a dataset.

    Parameters
    ----------
    ds : Dataset
    model : {"translation", "full"}
        The paper's 4-parameter model or the 10-parameter model with inertia.
    differentiator : str
        Method of :func:`cdprid.differentiate` for velocities and accelerations.
    params : dict, optional
        The differentiator's parameters.
    t_start, t_end : float, optional
        Time window (s) of the data used.
    trim : float
        Seconds dropped at each end of the window after differentiation.
    weighting : {"none", "groups"}
        ``groups``: two-step weighted LS with separate force and moment row weights.
    matched_filter : bool, optional
        Apply the differentiator's zero-phase filter to ``W tau`` too. Default: on for
        ``euler-filtfilt`` (whose accelerations carry that filter), off otherwise.
    covariance : {"hac", "iid"}
        Which standard deviation is ``std``: HAC (default, honest on correlated residuals) or
        the paper's eq. 20. Both are in the JSON (``std`` and ``std_iid``).

    Returns
    -------
    IdentificationReport
    """
    if model not in PARAMETER_NAMES:
        raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")
    if differentiator not in METHODS:
        raise ValueError(
            f"unknown differentiator {differentiator!r}; choose one of {', '.join(METHODS)}."
        )
    if weighting not in ("none", "groups"):
        raise ValueError(f"unknown weighting {weighting!r}; use 'none' or 'groups'.")
    params = dict(params or {})
    sig = align(ds, t_start, t_end)
    notes = list(sig.notes)
    if model == "full" and not sig.has_rotation:
        raise ValueError(
            f"{ds.path}: the full model needs orientations (qw, qx, qy, qz in pose.csv) "
            "to identify the inertia; this dataset has none."
        )
    motion = estimate_motion(sig, differentiator, params, angular=(model == "full"))
    if matched_filter is None:
        matched_filter = differentiator == "euler-filtfilt"
    wf = None
    if matched_filter:
        cutoff = params.get("cutoff_hz", METHODS["euler-filtfilt"].params.get("cutoff_hz", 4.0))
        order = params.get("order", METHODS["euler-filtfilt"].params.get("order", None))
        kw = {"cutoff_hz": cutoff}
        if order is not None:
            kw["order"] = order
        wf = functools.partial(zero_phase_filter, dt=sig.dt, **kw)
        notes.append(f"matched filtering: W tau low-passed with the same zero-phase "
                     f"{cutoff:g} Hz filter as the positions")
    reg = build_regression(ds.robot, motion, sig.tension, model, wf)
    keep = (reg.t >= reg.t[0] + trim) & (reg.t <= reg.t[-1] - trim)
    if keep.sum() < 10:
        raise ValueError(
            f"{ds.path}: fewer than 10 samples remain after trimming {trim:g} s at each end."
        )
    reg = reg.select(keep)
    res = least_squares(reg.W_ID, reg.Y_ID, PARAMETER_NAMES[model],
                        groups=reg.groups if weighting == "groups" else None,
                        rows_per_sample=6, covariance=covariance)
    return IdentificationReport(res, model, differentiator, params, int(keep.sum()), sig, motion,
                                reg, tuple(notes))


def format_table(rep: IdentificationReport) -> str:
    """A plain-text table like the paper's Table 1."""
    r = rep.result
    lines = [
        f"model: {rep.model}   differentiator: {rep.differentiator}   samples: {rep.n_samples}",
        f"{'parameter':<10} {'estimate':>14} {'sigma':>12} {'%sigma':>9}",
    ]
    for n, v, s, p in zip(r.names, r.x, r.std, r.rel_std_percent):
        lines.append(f"{n:<10} {v:>14.6g} {s:>12.4g} {p:>9.3g}")
    lines.append(f"sigma_rho = {r.sigma_rho:.4g}   cond(W_ID) = {r.cond:.4g}   "
                 f"cond scaled = {r.cond_scaled:.4g}")
    for note in rep.notes:
        lines.append(f"note: {note}")
    return "\n".join(lines)
