"""What a batch identification produced (:class:`IdentificationReport`) and its table.

The report and its parts are frozen dataclasses: the estimates are
:class:`cdprid.core.Estimates` (value, std, 95 % interval, unit, Cramer-Rao bound per
parameter); :meth:`IdentificationReport.as_json` is the JSON contract of ``cdprid identify
--json`` (its keys and values are checked against a capture, tests/cli/data/).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.core import (
    EIV_NOTE,
    CRBResult,
    Estimates,
    LSResult,
    Motion,
    Regression,
    StreamedRegression,
    inertia_about_com,
)
from cdprid.episodes import Episodes
from cdprid.io import AlignedSignals

__all__ = ["IdentificationReport", "format_table"]


@dataclasses.dataclass(frozen=True)
class IdentificationReport:
    """Everything an identification produced.

    Attributes
    ----------
    result : LSResult
        The least-squares fit (inertia about P).
    model : str
        The model used ("translation" or "full"; "auto" resolved).
    differentiator : str
        Method of :func:`cdprid.differentiate` used for the motion.
    params : dict
        The differentiator's parameters (its cutoff resolved).
    n_samples : int
        Time samples used (each gives 6 equations).
    signals : AlignedSignals
        The aligned recording.
    motion : Motion
        Velocities and accelerations of the platform.
    regression : Regression or StreamedRegression
        The samples used (after trimming); the pipeline's regressor is streamed (evaluated
        block by block, ``.A`` / ``.W_ID`` materialise it on demand).
    notes : tuple of str
        What was done, one sentence each.
    warnings : tuple of str
        One sentence per guard that fired (model mismatch, lag, physics, excitation).
    inertia_about : {"P", "G"}
        Reference point of the inertia in the output (platform frame either way).
    wrench_filter : str
        ``matched`` or ``none``.
    rotation_deg : float
        99th percentile of the rotation angle from the mean orientation, deg (0 without
        quaternions).
    crb : CRBResult or None
        The Cramer-Rao bound of this recording (:func:`cdprid.core.crb`), None when not
        computed or not computable.
    episodes : Episodes or None
        What :func:`cdprid.episodes.find_episodes` located (None when not run).
    """

    result: LSResult
    model: str
    differentiator: str
    params: dict
    n_samples: int
    signals: AlignedSignals
    motion: Motion
    regression: Regression | StreamedRegression
    notes: tuple = ()
    warnings: tuple = ()
    inertia_about: str = "P"
    wrench_filter: str = "matched"
    rotation_deg: float = 0.0
    crb: CRBResult | None = None
    episodes: Episodes | None = None

    @property
    def inertia_about_text(self) -> str:
        """``"P, platform frame"`` or ``"G (centre of mass), platform frame"``."""
        return ("P, platform frame" if self.inertia_about == "P"
                else "G (centre of mass), platform frame")

    def estimates(self) -> tuple[tuple, np.ndarray, np.ndarray, np.ndarray]:
        """The untyped view of the estimates (:meth:`parameters` gives the typed one).

        Returns
        -------
        names : tuple of str
        x : ndarray (p,)
            Estimates, SI units, the inertia about the chosen point.
        cov, cov_iid : ndarray (p, p)
            Covariance as chosen (HAC or eq. 20) and the i.i.d. one, moved the same way.
        """
        r = self.result
        cov_iid = r.cov if r.cov_iid is None else r.cov_iid
        if self.model != "full" or self.inertia_about == "P":
            return r.names, r.x, r.cov, cov_iid
        x, J = inertia_about_com(r.x)
        return r.names, x, J @ r.cov @ J.T, J @ cov_iid @ J.T

    def crb_std(self) -> np.ndarray | None:
        """The Cramer-Rao bound's std per parameter (inertia about the chosen point).

        Returns
        -------
        ndarray (p,) or None
            SI units of each parameter; None when the bound was not computed.
        """
        if self.crb is None:
            return None
        cov = self.crb.cov
        if self.model == "full" and self.inertia_about == "G":
            _, J = inertia_about_com(self.result.x)
            cov = J @ cov @ J.T
        return np.sqrt(np.clip(np.diag(cov), 0, None))

    def parameters(self) -> Estimates:
        """The estimates, typed: per parameter its value, std (as chosen), ``std_iid``, unit,
        95 % interval, Cramer-Rao bound and efficiency, with the inertia about the chosen
        point; ``.as_json()`` is the JSON ``parameters`` object.

        Returns
        -------
        cdprid.core.Estimates
        """
        names, x, cov, cov_iid = self.estimates()
        return Estimates.from_covariance(names, x, cov, cov_iid, self.crb_std())

    @property
    def weighting(self) -> str:
        """The row weighting used: ``groups``, ``eiv`` or ``none``."""
        return ("groups" if self.result.weights is not None
                else "eiv" if EIV_NOTE in self.notes else "none")

    def as_json(self) -> dict:
        """The JSON contract of ``cdprid identify --json``.

        Returns
        -------
        dict
            ``model``, ``parameters`` (:meth:`cdprid.core.Estimates.as_json`), ``sigma_rho``,
            ``cond``, ``cond_scaled``, ``n_samples``, ``differentiator``,
            ``differentiator_params``, ``weighting``, ``covariance``,
            ``hac_bandwidth_samples``, ``wrench_filter``, ``rotation_deg``, ``crb_std``,
            ``efficiency``, ``crb``, ``warnings``, ``notes``, ``episodes`` and, for the full
            model, ``inertia_about`` (docs/formats.md).
        """
        r = self.result
        est = self.parameters()
        out = {
            "model": self.model,
            "parameters": est.as_json(),
            "sigma_rho": r.sigma_rho,
            "cond": r.cond,
            "cond_scaled": r.cond_scaled,
            "n_samples": self.n_samples,
            "differentiator": self.differentiator,
            "differentiator_params": self.params,
            "weighting": self.weighting,
            "covariance": r.covariance,
            "hac_bandwidth_samples": r.hac_bandwidth if r.covariance == "hac" else None,
            "wrench_filter": self.wrench_filter,
            "rotation_deg": self.rotation_deg,
            "crb_std": {e.name: e.crb_std for e in est},
            "efficiency": {e.name: e.efficiency for e in est},
            "crb": None if self.crb is None else {
                "note": self.crb.note, "knot_spacing_s": self.crb.knot_spacing_s,
                "noise": self.crb.noise},
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "episodes": [] if self.episodes is None else self.episodes.as_json(),
        }
        if self.model == "full":
            out["inertia_about"] = self.inertia_about_text
        return out


def format_table(rep: IdentificationReport) -> str:
    """A plain-text table like the paper's Table 1 (std as chosen: HAC or eq. 20).

    Parameters
    ----------
    rep : IdentificationReport

    Returns
    -------
    str
        The table, then ``sigma_rho`` and the condition numbers, the inertia's reference
        point, and one line per note and per warning.
    """
    r = rep.result
    kind = "HAC" if r.covariance == "hac" else "iid, eq. 20"
    lines = [
        f"model: {rep.model}   differentiator: {rep.differentiator}   samples: {rep.n_samples}",
        f"{'parameter':<10} {'estimate':>14} {'sigma':>12} {'%sigma':>9} {'CRB':>11} "
        f"{'sigma/CRB':>9}   (sigma: {kind}; CRB: the recording's Cramer-Rao bound)",
    ]
    for e in rep.parameters():
        b = (f" {e.crb_std:>11.4g} {e.efficiency:>9.3g}" if e.crb_std is not None
             else f" {'-':>11} {'-':>9}")
        lines.append(f"{e.name:<10} {e.value:>14.6g} {e.std:>12.4g} {e.rel_std_percent:>9.3g}{b}")
    lines.append(f"sigma_rho = {r.sigma_rho:.4g}   cond(W_ID) = {r.cond:.4g}   "
                 f"cond scaled = {r.cond_scaled:.4g}")
    if rep.model == "full":
        lines.append(f"inertia about {rep.inertia_about_text}")
    for note in rep.notes:
        lines.append(f"note: {note}")
    for w in rep.warnings:
        lines.append(f"warning: {w}")
    return "\n".join(lines)
