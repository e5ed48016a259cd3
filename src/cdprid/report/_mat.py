"""The variables of ``identify --mat`` and ``diagnose --mat`` (MATLAB files; docs/formats.md).

Both files hold the command's whole JSON as the struct ``json`` (every number of ``--json``,
field names made valid MATLAB names) and, for direct use, flat arrays: the estimates, their
std, covariance and Cramer-Rao bound, the residuals with their time, the findings and the
episodes (when the result has any).
"""

from __future__ import annotations

import numpy as np

__all__ = ["diagnosis_variables", "episodes_of", "identify_variables"]


def episodes_of(result) -> list[dict]:
    """The result's episodes as dicts (``start_s``, ``end_s``, ``kind``, ...), [] when none.

    Reads an ``episodes`` attribute or key holding objects (with ``as_json()`` or attributes)
    or dicts, or a container whose ``as_json()`` is that list (:class:`cdprid.episodes.Episodes`,
    an identify report's); anything without ``start_s`` and ``end_s`` is skipped.

    Parameters
    ----------
    result : object or dict
        A diagnosis or identify result, or its JSON.

    Returns
    -------
    list of dict
        Copies; times in s.
    """
    eps = getattr(result, "episodes", None)
    if eps is None and isinstance(result, dict):
        eps = result.get("episodes")
    if eps is not None and not isinstance(eps, (list, tuple)) and hasattr(eps, "as_json"):
        eps = eps.as_json()
    out = []
    for e in eps or []:
        if hasattr(e, "as_json"):
            e = e.as_json()
        elif not isinstance(e, dict):
            e = {k: getattr(e, k) for k in ("start_s", "end_s", "kind") if hasattr(e, k)}
        if "start_s" in e and "end_s" in e:
            out.append(dict(e))
    return out


def _episode_arrays(eps: list[dict]) -> dict:
    return {"start_s": [float(e["start_s"]) for e in eps],
            "end_s": [float(e["end_s"]) for e in eps],
            "kind": [str(e.get("kind", "")) for e in eps]}


def identify_variables(rep, data: dict, made_by: dict) -> dict:
    """Variables of ``identify --mat``.

    Parameters
    ----------
    rep : cdprid.identify.IdentificationReport
    data : dict
        ``rep.as_json()`` (after the CLI's guards), stored whole as ``json``.
    made_by : dict
        ``command`` and ``version``.

    Returns
    -------
    dict
        ``parameter_names`` (cell), ``estimates``, ``std``, ``std_iid``, ``crb_std`` (p x 1;
        NaN where no bound), ``covariance``, ``covariance_iid``, ``crb_covariance`` (p x p,
        [] without a bound), ``t`` (n x 1, s), ``residual`` (n x 6: N, N m; ``Y_ID - W_ID x``
        unweighted), ``episodes``, ``json``, ``made_by``.
    """
    est = rep.parameters()
    names, cov, cov_iid = est.names, est.cov, est.cov_iid
    crb = rep.crb_std()
    crb_cov = None
    if rep.crb is not None:
        crb_cov = np.asarray(rep.crb.cov, float)
        if crb is not None and rep.model == "full" and rep.inertia_about == "G":
            crb_cov = np.diag(crb**2)  # the moved bound's diagonal (as its std)
    t = np.asarray(rep.regression.t, float)
    r = np.asarray(rep.result.residual, float)
    resid = r.reshape(len(t), -1) if r.size % max(len(t), 1) == 0 else r.reshape(-1, 1)
    eps = episodes_of(rep) or episodes_of(data)
    return {
        "parameter_names": list(names),
        "estimates": est.values.reshape(-1, 1),
        "std": est.std.reshape(-1, 1),
        "std_iid": np.array([e.std_iid for e in est], float).reshape(-1, 1),
        "crb_std": (np.full(len(names), np.nan) if crb is None else crb).reshape(-1, 1),
        "covariance": np.asarray(cov, float),
        "covariance_iid": np.asarray(cov_iid, float),
        "crb_covariance": crb_cov,
        "t": t.reshape(-1, 1),
        "residual": resid,
        "episodes": _episode_arrays(eps),
        "json": data,
        "made_by": made_by,
    }


def diagnosis_variables(result, data: dict, made_by: dict) -> dict:
    """Variables of ``diagnose --mat``.

    Parameters
    ----------
    result : cdprid.diagnosis.DiagnosisResult
    data : dict
        ``result.as_json()``, stored whole as ``json``.
    made_by : dict
        ``command`` and ``version``.

    Returns
    -------
    dict
        ``parameter_names``, ``estimates``, ``std`` (base model), ``extended_parameter_names``,
        ``extended_estimates``, ``extended_std``, ``t`` (n x 1, s), ``residual_base``,
        ``residual_extended`` (n x 6, N and N m, matched-filtered), ``used`` (n x 1 logical),
        ``train`` (n x 1 logical), ``findings`` (cell of structs), ``episodes``, ``json``,
        ``made_by``. The diagnosis computes no Cramer-Rao bound (``identify --mat`` has it).
    """
    A = result.arrays
    bp, ep = result.base_parameters, result.extended_parameters
    eps = episodes_of(result) or episodes_of(data)
    out = {
        "parameter_names": list(bp),
        "estimates": [float(v.value) for v in bp.values()],
        "std": [float(v.std) for v in bp.values()],
        "extended_parameter_names": list(ep),
        "extended_estimates": [float(v.value) for v in ep.values()],
        "extended_std": [float(v.std) for v in ep.values()],
        "findings": [f.as_json() for f in result.findings],
        "episodes": _episode_arrays(eps),
        "json": data,
        "made_by": made_by,
    }
    if "t" in A:
        out["t"] = np.asarray(A["t"], float).reshape(-1, 1)
        out["residual_base"] = np.asarray(A["residual_base"], float)
        out["residual_extended"] = np.asarray(A["residual_extended"], float)
        for k, name in (("use", "used"), ("train", "train")):
            if k in A:
                out[name] = np.asarray(A[k], bool).reshape(-1, 1)
    return out
