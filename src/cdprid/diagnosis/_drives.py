"""The diagnosis on the winch drives' currents (``diagnose --source currents``, issue 41 item 4).

Without load cells the force stream is each drive's **datasheet tension** ``k_nom i``
(``currents.csv`` times ``k_nom = torque_constant gear_ratio / drum_radius`` of robot.toml,
format 1.2), on the currents' own clock. What the datasheet model misses on the drive side is
the vocabulary's drive-side effects, ``torque_constant_error`` (``k / k_nom``),
``current_offset`` (``i_0``), ``drive_friction`` (``f_c``, ``f_v``; with the pulleys' own) and
``drive_inertia`` (``J``), the terms of the drive model (docs/drives.md)
``tau = k i + J l'' + f_v l' + f_c sign(l') - k i_0``.

**How they are found.** By ``identify --source currents``'s drive model
(:func:`cdprid.identify.identify_currents`: output error, the currents as the response, the
pose noise's bias removed, HAC std at the Cramer-Rao bound, its coverage checked by Monte
Carlo in results/currents-*.md), with the same scale reference: a drive's effect is **named**
when its HAC Wald test against the datasheet model (``k = k_nom``, ``i_0 = f_c = f_v = J =
0``; friction's two coefficients jointly) passes ``alpha`` over the number of drive tests
(their own Bonferroni family); its value and 95 % interval are identify's. The whole fitted
drive model then stays in every fit of the search (its theta blocks held at identify's values:
the load cell's gain, offset and pulley-friction blocks, whose hooks act on the reading as the
drive does, and the inertia's), which looks for the platform-side effects (a clock offset of
the currents, geometry, drag, cable mass, tilt) on top of it; the load cell's own effects are
not candidates. The platform's std in the diagnosis holds the drive model fixed: its scale is
identify's torque constants' (a note gives identify's mass and std).

What was tried and measured on a six-cable recording with every drive off in every way
(inertia 0.7-4 kg, friction 3-10 N and 3-7 N s/m, offsets up to 0.05 A, torque constants up to
9 % off): the greedy search on the datasheet tension named a 27 ms clock offset and 12 cm
attachment errors (mass +13 %); refitting the torque constants inside the diagnosis is least
squares with the current noise in the regressor (errors in variables: mass -4.9 % with every
drive free, -10 % with four; exact to 1e-3 without current noise); holding only identify's
named effects and searching the rest named compensating current offsets (0.3 N of one
torque constant's estimation error). Holding identify's whole drive model: nothing spurious,
the mass within identify's own error (1.3 %).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import InputError, chi2_sf
from cdprid.io import Dataset, read_drives, read_stream

__all__ = ["DriveSource", "SOURCES", "datasheet_dataset", "fit_drives", "gauge_cable"]

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
    mass : tuple of float
        identify's mass and its std (kg), with the drives' uncertainty.
    """

    k_nominal: np.ndarray
    reference: object
    values: dict
    cov: np.ndarray
    notes: tuple = ()
    #: identify's mass and its std, kg
    mass: tuple = (float("nan"), float("nan"))

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

    def scale_rel_std(self) -> float:
        """The relative std of the scale the drive model sets (identify's mass's, which holds
        the torque constants' uncertainty), 0 when not finite.

        Returns
        -------
        float
        """
        r = self.mass[1] / abs(self.mass[0]) if self.mass[0] else float("nan")
        return float(r) if np.isfinite(r) else 0.0

    def scale_note(self) -> str:
        """How the platform's std holds the drive model's scale.

        Returns
        -------
        str
        """
        return ("the extended model's platform parameters hold identify's drive model fixed; "
                f"its scale's relative std ({100 * self.scale_rel_std():.2g} %, that of "
                f"identify --source currents' m = {self.mass[0]:.5g} +- {self.mass[1]:.2g} kg) "
                "is added to each of their std (the base model's std leaves it out)")

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


def datasheet_dataset(ds: Dataset) -> Dataset:
    """The dataset with its current stream as the force stream (the datasheet's ``k i``).

    Parameters
    ----------
    ds : Dataset
        Read with ``require_tensions=False`` from a folder with ``currents.csv`` and
        robot.toml's drive fields (format 1.2); a tensions.csv beside them is not used.

    Returns
    -------
    Dataset

    Raises
    ------
    InputError
        One sentence naming the file: no dataset folder, no drive fields, no currents.csv,
        a malformed one.
    """
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
    t, i = cur
    k = np.asarray(drives.k_nominal, float)
    return dataclasses.replace(ds, tension_t=np.asarray(t, float),
                               tension=np.asarray(i, float) * k[None, :])


def gauge_cable(ds: Dataset) -> int:
    """A drive whose torque constant the clock's profile holds (the homogeneous equations need
    one; which one does not move the profile's minimum): robot.toml's ``drive_reference``,
    else the one of least stated tolerance (1-based)."""
    drives = read_drives(ds.path)
    if drives.reference.any():
        return int(np.flatnonzero(drives.reference)[0]) + 1
    return int(np.argmin(np.where(np.isfinite(drives.tolerance), drives.tolerance, np.inf))) + 1


def fit_drives(ds: Dataset, reference: str | None, drive_fit, late_s: float = 0.0,
               progress=None) -> DriveSource:
    """The recording's drive model by ``drive_fit`` (``identify --source currents``: output
    error).

    Parameters
    ----------
    ds : Dataset
        As read (``require_tensions=False``).
    reference : str, optional
        identify's ``--reference``.
    drive_fit : callable
        :func:`cdprid.identify.identify_currents` or a function with its arguments and report
        (``names``, ``theta``, ``cov``, ``reference``, ``warnings``).
    late_s : float
        The drive streams' clock offset (s) to take out first (the diagnosis's clock stage on
        currents, :mod:`cdprid.diagnosis._drives_clock`).
    progress : callable, optional
        Told identify's stages.

    Returns
    -------
    DriveSource

    Raises
    ------
    InputError
        ``drive_fit`` not given.
    """
    if drive_fit is None:
        raise InputError("diagnose --source currents needs the drive model's fit: pass "
                         "drive_fit=cdprid.identify.identify_currents (the command line does).")
    m = ds.robot.n_cables
    rep = drive_fit(ds, reference=reference, bound=False, progress=progress,
                    clock_offset_s=late_s)
    p = len(rep.names) - 5 * m
    values = {key: np.asarray(rep.theta[p + i * m:p + (i + 1) * m], float)
              for i, key in enumerate(_KEYS)}
    notes = tuple(f"identify --source currents: {w}" for w in rep.warnings)
    mass = (float(rep.theta[0]), float(np.sqrt(max(float(rep.cov[0, 0]), 0.0))))
    return DriveSource(np.asarray(read_drives(ds.path).k_nominal, float), rep.reference, values,
                       np.asarray(rep.cov)[p:, p:], notes, mass)


def drive_theta(src: DriveSource, layout) -> np.ndarray:
    """Theta with identify's drive model in the blocks whose hooks undo the datasheet reading
    ``r = k_nom i``: ``tau = (r - q_offset) / (1 + q_gain) + f_c s + f_v l' + J l''`` equals
    ``k i - c + ...`` for ``q_gain = k_nom / k - 1`` and ``q_offset = c k_nom / k``.

    Parameters
    ----------
    src : DriveSource
    layout : ThetaLayout

    Returns
    -------
    numpy.ndarray (layout.size,)
    """
    v, kn = src.values, src.k_nominal
    th = np.zeros(layout.size)
    th[layout.slices["gain"]] = kn / v["k"] - 1.0
    th[layout.slices["offset"]] = v["c"] * kn / v["k"]
    th[layout.slices["coulomb"]] = v["fc"]
    th[layout.slices["pvisc"]] = v["fv"]
    th[layout.slices["inertia"]] = v["J"]
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
    """Every drive-side effect's test against the datasheet model (the forms of
    :data:`cdprid.effects.DIAGNOSIS` that name drive parameters, ``DiagnosisForm.drive``):
    ``[(effect, cable, parameters, interval, statistic, p)]`` (p nan: cannot tell).

    Returns
    -------
    list of tuple
    """
    from cdprid.effects import DIAGNOSIS

    std = np.sqrt(np.clip(np.diag(src.cov), 0, None))
    out = []
    for j in range(1, src.m + 1):
        v = {key: float(src.values[key][j - 1]) for key in _KEYS}
        s = {key: float(std[src.index(key, j)]) for key in _KEYS}
        kn = float(src.k_nominal[j - 1])
        for name, form in DIAGNOSIS.items():
            if not form.drive or (form.not_on_reference and j == src.reference_cable):
                continue
            null = np.array([kn if key == "k" else 0.0 for key in form.drive])
            out.append((name, j, *form.drive_report(v, s, kn), *_test(src, form.drive, j, null)))
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
    model's linearisation (weighted units, :func:`cdprid.diagnosis._problem.heldout_rms`): the
    effect taken out of the drive model with the rest refitted, then its columns added free.

    Parameters
    ----------
    prob : Problem
    s : Selection
        The final model (identify's drive model held in its theta).
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

    Z, y, _, C = linear_model(prob, s)
    w = prob.wrow[None, :, None]
    found = []
    for t in tests:
        if not t["named"]:
            continue
        idx = prob.layout.candidate_indices(t["effect"], t["cable"])
        cols = C[:, :, idx] * w
        y_wo = y + np.einsum("nij,j->ni", cols, s.theta[idx])
        found.append(Finding(
            effect=t["effect"], parameters={"cable": t["cable"], **t["parameters"]},
            interval=t["interval"], aliases=[], heldout_rms_before=heldout_rms(prob, Z, y_wo),
            heldout_rms_after=heldout_rms(prob, np.concatenate([Z, cols], axis=2), y_wo),
            p_value=t["p_value"], statistic=float(t["statistic"]),
            threshold=alpha / len(tests)))
    return tuple(found)


def platform_candidates(candidates) -> list:
    """The candidates that are not drive-side (their forms of any stream but ``currents``)."""
    from cdprid.effects import DIAGNOSIS

    return [c for c in candidates if DIAGNOSIS[c.effect].stream != "currents"]
