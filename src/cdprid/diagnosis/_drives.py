"""The diagnosis on the winch drives' currents (``diagnose --source currents``, issue 41 item 4).

Without load cells the force stream is each drive's **datasheet tension** ``k_nom i``
(``currents.csv`` times ``k_nom = torque_constant gear_ratio / drum_radius`` of robot.toml,
format 1.2), on the currents' own clock. What the datasheet model misses on the drive side is
the vocabulary's drive-side effects, ``torque_constant_error`` (``k / k_nom``),
``current_offset`` (``i_0``), ``drive_friction`` (``f_c``, ``f_v``; with the pulleys' own) and
``drive_inertia`` (``J``), the terms of the drive model (docs/drives.md)
``tau = k i + J l'' + f_v l' + f_c sign(l') - k i_0``.

**How they are found.** Not by the greedy search on the datasheet tension: its torque-constant
columns carry the current noise (``k i``: errors in variables), and with the scale pinned by
one drive alone (the motion equations and the drive model scale together) least squares there
is biased like the issue's "outside plain least squares" (measured: mass -4.9 %, every torque
constant 4-10 % low on a six-cable recording at 0.03 A; exact to 1e-3 without current noise).
The drive model is fitted by ``identify --source currents`` (:func:`cdprid.identify.
identify_currents`: output error, the currents as the response, the pose noise's bias removed,
HAC std at the Cramer-Rao bound; its coverage checked by Monte Carlo, results/currents-*.md),
with the same scale reference. Each drive's effect is **named** when its HAC Wald test against
the datasheet model (``k = k_nom``, ``i_0 = f_c = f_v = J = 0``; friction's two coefficients
jointly) passes the search's first-step threshold (Bonferroni over every test); its value and
95 % interval are identify's. The fitted drive model then stays in every fit of the search
(its theta blocks held at identify's values: the load cell's gain, offset and pulley-friction
blocks, whose hooks act on the reading as the drive does, and the inertia's), which looks for
the platform-side effects (clock offset of the currents, geometry, drag, cable mass, tilt) on
top of it; the load cell's own effects are not candidates.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import InputError, chi2_sf
from cdprid.io import Dataset, read_drives, read_stream

__all__ = ["DriveSource", "SOURCES", "drive_dataset"]

#: the force streams ``diagnose --source`` takes
SOURCES = ("tensions", "currents")

#: the drive model's parameters per drive, in identify's order (``k_j``, ``J_j``, ...)
_KEYS = ("k", "J", "fv", "fc", "c")


@dataclasses.dataclass(frozen=True)
class DriveSource:
    """How a current stream became the diagnosis's force stream, and the drive model.

    Attributes
    ----------
    k_nominal : numpy.ndarray (m,)
        The datasheet current-to-force constants, N/A.
    reference : ScaleReference
        identify's scale reference (a drive, or a mass).
    values : dict
        ``{"k", "J", "fv", "fc", "c"}`` -> ``(m,)`` identify's estimates (N/A, kg, N s/m, N, N).
    cov : numpy.ndarray (5m, 5m)
        Their covariance, in the order ``k_1..k_m, J_1..J_m, ..., c_1..c_m``.
    notes : tuple of str
        identify's warnings worth carrying (its notes stay in its own output).
    """

    k_nominal: np.ndarray
    reference: object
    values: dict
    cov: np.ndarray
    notes: tuple = ()

    @property
    def reference_cable(self) -> int | None:
        """The scale reference drive (1-based), None for a mass reference."""
        return self.reference.cable if self.reference.kind == "drive" else None

    @property
    def m(self) -> int:
        """Number of drives."""
        return int(self.k_nominal.size)

    def index(self, key: str, cable: int) -> int:
        """Position of drive ``cable``'s parameter ``key`` in :attr:`cov`."""
        return _KEYS.index(key) * self.m + cable - 1

    def note(self) -> str:
        """The note every diagnosis on currents carries.

        Returns
        -------
        str
        """
        ks = ", ".join(f"{k:.4g}" for k in self.k_nominal)
        return ("source currents: the force stream is each drive's datasheet tension k i "
                f"(currents.csv; k = torque_constant gear_ratio / drum_radius = {ks} N/A); the "
                "drive model (k, J, f_v, f_c, c per drive) is identify --source currents' "
                "output-error fit, the drive-side effects named where it departs from the "
                "datasheet model beyond the search's threshold, and it stays in every fit "
                "of the search for the platform-side effects; scale reference: "
                f"{self.reference.source}")

    def as_json(self) -> dict:
        """``info["source_currents"]`` of the diagnosis JSON.

        Returns
        -------
        dict
            ``k_nominal_N_per_A``, ``reference`` (identify's ``scale_reference``) and
            ``drives``: per drive ``{cable, k, J, fv, fc, c}`` each ``{value, std}``.
        """
        std = np.sqrt(np.clip(np.diag(self.cov), 0, None))
        drives = [{"cable": j, **{key: {"value": float(self.values[key][j - 1]),
                                        "std": float(std[self.index(key, j)])}
                                  for key in _KEYS}} for j in range(1, self.m + 1)]
        return {"k_nominal_N_per_A": [float(k) for k in self.k_nominal],
                "reference": self.reference.as_json(), "drives": drives}


def drive_dataset(ds: Dataset, reference: str | None = None,
                  progress=None) -> tuple[Dataset, DriveSource]:
    """The dataset with its current stream as the force stream (the datasheet's ``k i``) and
    the drive model identify fits.

    Parameters
    ----------
    ds : Dataset
        Read with ``require_tensions=False`` from a folder with ``currents.csv`` and
        robot.toml's drive fields (format 1.2); a tensions.csv beside them is not used.
    reference : str, optional
        identify's ``--reference`` (``drive:K``, ``mass``, ``mass:KG[:STD_KG]``; default its
        automatic choice).
    progress : callable, optional
        Told identify's stages.

    Returns
    -------
    (Dataset, DriveSource)

    Raises
    ------
    InputError
        One sentence naming the file or option: no dataset folder, no drive fields, no
        currents.csv, a malformed one, no scale reference.
    """
    from cdprid.identify import identify_currents

    if ds.path is None:
        raise InputError("diagnose --source currents reads currents.csv from a dataset folder.")
    m = ds.robot.n_cables
    drives = read_drives(ds.path)
    if drives is None:
        raise InputError(f"{ds.path / 'robot.toml'}: --source currents needs the drive fields "
                         "drum_radius, gear_ratio and torque_constant on every [[cable]] "
                         "(docs/drives.md).")
    cur = read_stream(ds.path, "currents", "i", m)
    if cur is None:
        raise InputError(f"{ds.path}: --source currents needs currents.csv (t,i_1..i_{m}, A).")
    rep = identify_currents(ds, reference=reference, bound=False, progress=progress)
    p = len(rep.names) - 5 * m
    values = {key: np.asarray(rep.theta[p + i * m:p + (i + 1) * m], float)
              for i, key in enumerate(_KEYS)}
    t, i = cur
    k = np.asarray(drives.k_nominal, float)
    out = dataclasses.replace(ds, tension_t=np.asarray(t, float),
                              tension=np.asarray(i, float) * k[None, :])
    notes = tuple(f"identify --source currents: {w}" for w in rep.warnings)
    return out, DriveSource(k, rep.reference, values, np.asarray(rep.cov)[p:, p:], notes)


def drive_theta(src: DriveSource, layout, named=None) -> np.ndarray:
    """Theta with the drive model in the blocks whose hooks undo the datasheet reading
    ``r = k_nom i``: ``tau = (r - q_offset) / (1 + q_gain) + f_c s + f_v l' + J l''`` equals
    ``k i - c + ...`` for ``q_gain = k_nom / k - 1`` and ``q_offset = c k_nom / k``.

    Parameters
    ----------
    src : DriveSource
    layout : ThetaLayout
    named : iterable of (effect, cable), optional
        Only these drive-side effects depart from the datasheet model (``k = k_nom``, the
        others 0): the diagnosis's model is the datasheet's plus what it names. Default: all.

    Returns
    -------
    numpy.ndarray (layout.size,)
    """
    v, kn, m = src.values, src.k_nominal, src.m
    keep = None if named is None else set(named)

    def on(effect):
        return np.array([keep is None or (effect, j) in keep for j in range(1, m + 1)])

    k = np.where(on("torque_constant_error"), v["k"], kn)
    th = np.zeros(layout.size)
    th[layout.slices["gain"]] = kn / k - 1.0
    th[layout.slices["offset"]] = np.where(on("current_offset"), v["c"] * kn / k, 0.0)
    th[layout.slices["coulomb"]] = np.where(on("drive_friction"), v["fc"], 0.0)
    th[layout.slices["pvisc"]] = np.where(on("drive_friction"), v["fv"], 0.0)
    th[layout.slices["inertia"]] = np.where(on("drive_inertia"), v["J"], 0.0)
    return th


def _test(src: DriveSource, keys: tuple, cable: int, null: np.ndarray):
    """HAC Wald statistic and p-value of drive ``cable``'s parameters ``keys`` against
    ``null`` (nan when their covariance is not finite: cannot tell)."""
    ix = [src.index(k, cable) for k in keys]
    d = np.array([src.values[k][cable - 1] for k in keys]) - null
    V = src.cov[np.ix_(ix, ix)]
    if not np.all(np.isfinite(V)):
        return float("nan"), float("nan")
    try:
        stat = float(d @ np.linalg.solve(V, d))
    except np.linalg.LinAlgError:
        return float("nan"), float("nan")
    return stat, float(chi2_sf(stat, len(keys)))


def drive_tests(src: DriveSource) -> list:
    """Every drive-side effect's test against the datasheet model:
    ``[(effect, cable, parameters, interval, statistic, p)]`` (p nan: cannot tell).

    Returns
    -------
    list of tuple
    """
    z = 1.959963984540054
    std = np.sqrt(np.clip(np.diag(src.cov), 0, None))
    out = []
    for j in range(1, src.m + 1):
        v = {key: float(src.values[key][j - 1]) for key in _KEYS}
        s = {key: float(std[src.index(key, j)]) for key in _KEYS}
        kn = float(src.k_nominal[j - 1])
        if j != src.reference_cable:
            out.append(("torque_constant_error", j, {"ratio": v["k"] / kn},
                        {"ratio": [(v["k"] - z * s["k"]) / kn, (v["k"] + z * s["k"]) / kn]},
                        *_test(src, ("k",), j, np.array([kn]))))
        out.append(("current_offset", j, {"offset_A": v["c"] / v["k"]},
                    {"offset_A": [(v["c"] - z * s["c"]) / v["k"], (v["c"] + z * s["c"]) / v["k"]]},
                    *_test(src, ("c",), j, np.zeros(1))))
        out.append(("drive_friction", j, {"coulomb_N": v["fc"], "viscous_Ns_per_m": v["fv"]},
                    {"coulomb_N": [v["fc"] - z * s["fc"], v["fc"] + z * s["fc"]],
                     "viscous_Ns_per_m": [v["fv"] - z * s["fv"], v["fv"] + z * s["fv"]]},
                    *_test(src, ("fc", "fv"), j, np.zeros(2))))
        out.append(("drive_inertia", j, {"J_kg": v["J"]},
                    {"J_kg": [v["J"] - z * s["J"], v["J"] + z * s["J"]]},
                    *_test(src, ("J",), j, np.zeros(1))))
    return out


def drive_named(src: DriveSource, alpha: float) -> list:
    """Every drive-side effect's test against the datasheet model, as ``info`` records
    (``effect``, ``cable``, ``parameters``, ``interval``, ``statistic``, ``p_value``
    Bonferroni-adjusted over the drive tests, ``named``): named when the p-value is below
    ``alpha`` over every drive test (their own family; ``p_value`` None: cannot tell).

    Parameters
    ----------
    src : DriveSource
    alpha : float
        Family-wise level.

    Returns
    -------
    list of dict
    """
    tests = drive_tests(src)
    n = len(tests)
    return [{"effect": effect, "cable": cable, "parameters": params, "interval": interval,
             "statistic": stat, "p_value": None if not np.isfinite(p) else float(min(1.0, p * n)),
             "named": bool(np.isfinite(p) and p * n < alpha)}
            for effect, cable, params, interval, stat, p in tests]


def drive_findings(prob, s, tests: list, alpha: float) -> tuple:
    """The named drive-side effects as findings (``tests`` from :func:`drive_named`: identify's
    values, intervals and tests), each with its held-out rms without and with it in the final
    model's linearisation (the others refitted; weighted units,
    :func:`cdprid.diagnosis._problem.heldout_rms`): an effect whose blocks the search refits
    (offset, friction, inertia: :func:`drive_start`) without its columns, a torque constant
    (held at identify's value) with its columns added.

    Parameters
    ----------
    prob : Problem
    s : Selection
        The final model.
    tests : list of dict
    alpha : float
        Family-wise level (the threshold is ``alpha`` over the number of tests).

    Returns
    -------
    tuple of Finding
    """
    from cdprid.diagnosis._problem import heldout_rms
    from cdprid.diagnosis._result import Finding
    from cdprid.diagnosis._selection import linear_model

    Z, y, nm, C = linear_model(prob, s)
    w = prob.wrow[None, :, None]
    pos = {i: nm + k for k, i in enumerate(s.active_idx)}
    found = []
    for t in tests:  # the torque constants (the others are the search's, drive_start)
        if not t["named"] or t["effect"] != "torque_constant_error":
            continue
        idx = prob.layout.candidate_indices(t["effect"], t["cable"])
        own = [pos[i] for i in idx if i in pos]
        if own:  # refitted in the search: its columns are part of Z
            rest = [k for k in range(Z.shape[2]) if k not in own]
            before, after = heldout_rms(prob, Z[:, :, rest], y), heldout_rms(prob, Z, y)
        else:  # held at identify's value: put it back as free columns
            cols = C[:, :, idx] * w
            y_wo = y + np.einsum("nij,j->ni", cols, s.theta[idx])
            before = heldout_rms(prob, Z, y_wo)
            after = heldout_rms(prob, np.concatenate([Z, cols], axis=2), y_wo)
        found.append(Finding(
            effect=t["effect"], parameters={"cable": t["cable"], **t["parameters"]},
            interval=t["interval"], aliases=[], heldout_rms_before=before,
            heldout_rms_after=after, p_value=t["p_value"], statistic=float(t["statistic"]),
            threshold=alpha / len(tests)))
    return tuple(found)


def drive_start(prob, s, tests: list, alpha: float, extra) -> object:
    """``s`` with the named drive-side effects other than the torque constants accepted and
    refitted with the platform (their columns are constants and the poses' rates, without the
    current noise; the torque constants stay at identify's values in ``prob.theta0``).

    Each finding's value and interval are the diagnosis's refit's, its p-value identify's test
    (Bonferroni over the drive tests), its held-out rms without and with it from one set of
    per-fold Gram matrices of this model's linearisation.

    Parameters
    ----------
    prob : Problem
    s : Selection
        The base model (:func:`cdprid.diagnosis._selection.start`; its theta the drive model).
    tests : list of dict
        :func:`drive_named`'s records.
    alpha : float
        Family-wise level (the threshold is ``alpha`` over the number of tests).
    extra : DiagnosisContext

    Returns
    -------
    Selection
    """
    from cdprid.diagnosis._candidates import Candidate, vocab_interval, vocab_params
    from cdprid.diagnosis._problem import subset_heldout_rms
    from cdprid.diagnosis._result import Finding
    from cdprid.diagnosis._selection import linear_model, refit

    named = [t for t in tests if t["named"] and t["effect"] != "torque_constant_error"]
    if not named:
        return s
    cands = [Candidate(t["effect"], t["cable"]) for t in named]
    idx = sorted(set(s.active_idx).union(*(prob.layout.candidate_indices(c.effect, c.cable)
                                           for c in cands)))
    t = refit(prob, s, active_idx=idx)
    Z, y, nm, _ = linear_model(prob, t)
    pos = {i: nm + k for k, i in enumerate(t.active_idx)}
    every = list(range(Z.shape[2]))
    own = [{pos[i] for i in prob.layout.candidate_indices(c.effect, c.cable) if i in pos}
           for c in cands]
    rms = subset_heldout_rms(prob, Z, y, [[k for k in every if k not in o] for o in own]
                             + [every])
    std = np.sqrt(np.clip(np.diag(t.th_cov), 0, None))
    fs = tuple(Finding(effect=c.effect,
                       parameters=vocab_params(c, t.theta, prob.layout, extra, t.th_cov),
                       interval=vocab_interval(c, t.theta, std, prob.layout, extra),
                       aliases=[], heldout_rms_before=float(rms[k]),
                       heldout_rms_after=float(rms[-1]), p_value=rec["p_value"],
                       statistic=float(rec["statistic"]), threshold=alpha / len(tests))
               for k, (c, rec) in enumerate(zip(cands, named, strict=True)))
    return dataclasses.replace(t, accepted=s.accepted + tuple(cands), findings=s.findings + fs)


def platform_candidates(candidates) -> list:
    """The candidates that are not drive-side (their forms of any stream but ``currents``)."""
    from cdprid.effects import DIAGNOSIS

    return [c for c in candidates if DIAGNOSIS[c.effect].stream != "currents"]


def set_aside(s) -> tuple:
    """``(s without its drive-side findings, ((candidate, finding), ...))``: the drive side's
    findings leave the accepted list (the platform's backward, stability and geometry checks
    do not weigh them: the drive side is decided by identify's tests and the drive phase's)
    while their theta blocks stay active, refitted in every later fit."""
    from cdprid.effects import DIAGNOSIS

    keep = [k for k, c in enumerate(s.accepted) if DIAGNOSIS[c.effect].stream != "currents"]
    aside = tuple((c, f) for k, (c, f) in enumerate(zip(s.accepted, s.findings, strict=True))
                  if k not in keep)
    return dataclasses.replace(s, accepted=tuple(s.accepted[k] for k in keep),
                               findings=tuple(s.findings[k] for k in keep)), aside


def drive_final(prob, s, aside, tests: list, extra) -> tuple:
    """The findings set aside by :func:`set_aside`, final: an effect identify's tests named
    keeps identify's value and interval (output error, its coverage checked by Monte Carlo);
    one the drive phase named gets the final model's (which holds the torque constants at
    identify's values, so its interval leaves out their uncertainty: a note says so). One whose
    every parameter ended at its bound 0 (out of the fit) is dropped.

    Parameters
    ----------
    prob : Problem
    s : Selection
        The final model.
    aside : tuple of (Candidate, Finding)
    tests : list of dict
        :func:`drive_named`'s records.
    extra : DiagnosisContext

    Returns
    -------
    tuple of Finding
    """
    from cdprid.diagnosis._candidates import vocab_interval, vocab_params

    std = np.sqrt(np.clip(np.diag(s.th_cov), 0, None))
    active = set(s.active_idx)
    named = {(t["effect"], t["cable"]): t for t in tests if t["named"]}
    out = []
    for c, f in aside:
        if not active & set(prob.layout.candidate_indices(c.effect, c.cable)):
            continue
        rec = named.get((c.effect, c.cable))
        if rec is not None:
            out.append(dataclasses.replace(f, parameters={"cable": c.cable, **rec["parameters"]},
                                           interval=rec["interval"]))
            continue
        out.append(dataclasses.replace(
            f, parameters=vocab_params(c, s.theta, prob.layout, extra, s.th_cov),
            interval=vocab_interval(c, s.theta, std, prob.layout, extra)))
    return tuple(out)
