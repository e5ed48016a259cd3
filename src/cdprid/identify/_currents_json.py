"""JSON of ``identify --source currents`` (the keys of ``identify --json`` plus ``drives`` and
``scale_reference``)."""

from __future__ import annotations

import numpy as np

from cdprid.core import DRIVE_PARAMETER_NAMES, DRIVE_UNITS
from cdprid.model import PARAMETER_NAMES

__all__ = ["currents_json", "parameter_entry"]


def parameter_entry(value: float, std: float, std_iid: float | None = None,
                    crb_std: float | None = None) -> dict:
    """``{"value", "std", "rel_std_percent", "std_iid", "crb_std", "efficiency",
    "interval95"}`` of one parameter."""
    if not np.isfinite(std):  # not determined ("cannot tell"): null in the JSON
        return {"value": float(value), "std": None, "rel_std_percent": None, "std_iid": None,
                "crb_std": None if crb_std is None else float(crb_std), "efficiency": None,
                "interval95": None}
    with np.errstate(divide="ignore"):
        rel = float(100.0 * std / abs(value)) if value != 0 else float("inf")
    return {"value": float(value), "std": float(std), "rel_std_percent": rel,
            "std_iid": None if std_iid is None else float(std_iid),
            "crb_std": None if crb_std is None else float(crb_std),
            "efficiency": None if not crb_std else float(std / crb_std),
            "interval95": [float(value - 1.96 * std), float(value + 1.96 * std)]}


def currents_json(rep) -> dict:
    """The JSON mapping of a :class:`cdprid.identify._currents.CurrentsReport`."""
    p = len(PARAMETER_NAMES[rep.model])
    s = rep.std
    si = np.sqrt(np.clip(np.diag(rep.cov_iid), 0, None))
    params = {}
    for k, name in enumerate(rep.names[:p]):
        cs = None if rep.crb_std is None else rep.crb_std[k]
        params[name] = parameter_entry(rep.theta[k], s[k], si[k], cs)
    m = (len(rep.names) - p) // 5
    drives = []
    for j in range(m):
        entry = {"cable": j + 1}
        for a, kind in enumerate(DRIVE_PARAMETER_NAMES):
            i = p + a * m + j
            entry[kind] = {**parameter_entry(rep.theta[i], s[i], si[i]),
                           "unit": DRIVE_UNITS[kind]}
        entry["k"]["nominal"] = (None if rep.nominal_k is None else float(rep.nominal_k[j]))
        ik, ic = p + j, p + 4 * m + j
        k, c = rep.theta[ik], rep.theta[ic]
        g = np.zeros(len(rep.theta))
        g[ic], g[ik] = 1.0 / k, -c / k ** 2  # i_0 = c / k, delta method
        with np.errstate(invalid="ignore"):
            s_i0 = float(np.sqrt(g @ rep.cov @ g))
        entry["current_offset_A"] = parameter_entry(c / k, s_i0 if np.isfinite(s_i0) else np.inf)
        entry["reference"] = rep.reference.kind == "drive" and rep.reference.cable == j + 1
        drives.append(entry)
    return {
        "source": "currents",
        "estimator": getattr(rep, "estimator", "cls"),
        "model": rep.model,
        "parameters": params,
        "sigma_rho": rep.sigma_rho,
        "cond": rep.cond,
        "cond_scaled": rep.cond_scaled,
        "n_samples": rep.n_samples,
        "differentiator": rep.differentiator,
        "differentiator_params": rep.params,
        "weighting": "eiv",
        "covariance": "hac",
        "hac_bandwidth_samples": rep.hac_bandwidth,
        "wrench_filter": "matched",
        "rotation_deg": rep.rotation_deg,
        "crb_std": {k: v["crb_std"] for k, v in params.items()},
        "efficiency": {k: v["efficiency"] for k, v in params.items()},
        "crb": None if rep.crb_std is None else {
            "note": "the platform parameters' bound with the drive parameters known (a lower "
                    "bound of this problem's)"},
        "drives": drives,
        "scale_reference": rep.reference.as_json(),
        "load_cells": None if rep.cells is None else rep.cells.as_json(),
        "pose_noise_correction": _pose_json(rep),
        "warnings": list(rep.warnings),
        "notes": list(rep.notes),
    }


def _pose_json(rep):
    """The output error's pose-noise bias that was subtracted (``shift``), its Monte-Carlo
    std (``shift_std``) and the pose noise's first-order share of each std, in the floor of
    the reported std (``first_order_std``) per parameter, or None (``cls``, or no
    correction)."""
    c = rep.compared or {}
    if "pose_shift" not in c:
        return None
    sd = np.sqrt(np.clip(np.diag(c["pose_shift_cov"]), 0, None))
    out = {"shift": {n: float(v) for n, v in zip(rep.names, c["pose_shift"], strict=True)},
           "shift_std": {n: float(v) for n, v in zip(rep.names, sd, strict=True)}}
    if c.get("pose_first_cov") is not None:
        sf = np.sqrt(np.clip(np.diag(c["pose_first_cov"]), 0, None))
        out["first_order_std"] = {n: float(v) for n, v in zip(rep.names, sf, strict=True)}
    return out


def result_table(title: str, names, theta, std, reference, notes=(), warnings=(),
                 crb_std=None) -> str:
    """Plain-text table of a homogeneous identification (value, HAC std, %, 95 % interval).

    Parameters
    ----------
    title : str
        First line.
    names : sequence of str
    theta, std : (q,) arrays
    reference : ScaleReference
    notes, warnings : sequence of str
    crb_std : (p,) array or None
        The bound of the first p parameters.
    """
    lines = [title, f"scale reference: {reference.source}",
             f"{'parameter':<10} {'estimate':>13} {'sigma':>11} {'%sigma':>8} "
             f"{'95 % interval':>27} {'CRB':>10}   (sigma: HAC, the reference's uncertainty "
             "included)"]
    for k, (n, v, s) in enumerate(zip(names, theta, std, strict=True)):
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = 100.0 * s / abs(v)
        b = (f"{crb_std[k]:>10.4g}" if crb_std is not None and k < len(crb_std)
             else f"{'-':>10}")
        lines.append(f"{n:<10} {v:>13.6g} {s:>11.4g} {rel:>8.3g} "
                     f"[{v - 1.96 * s:>12.5g}, {v + 1.96 * s:>12.5g}] {b}")
    lines += [f"note: {x}" for x in notes] + [f"warning: {x}" for x in warnings]
    return "\n".join(lines)
