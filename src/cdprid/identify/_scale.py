"""The scale reference of a homogeneous identification (``identify --reference``).

From poses, lengths and currents alone (or from free motion), the equations
``Z x - D d = 0`` hold for ``c (x, d)`` with any factor ``c``: the motion equations and the
drive model scale together, the mass included (gravity does not fix it: it multiplies the
mass). One parameter must be given. With the reference parameter ``theta_r = v +- s_v`` and
``phi`` the fit with ``phi_r = 1``, ``theta = v phi`` and, to first order,

    Cov(theta) = v^2 Cov(phi) + s_v^2 phi phi^T,

so the reference's uncertainty reaches every std. A tolerance (a datasheet's +-, robot.toml's
``torque_constant_tolerance`` or ``[platform] mass_uncertainty``) is read as the half-width of
an interval the truth lies in, uniformly: ``s_v = tol v / sqrt(3)``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdprid.base import InputError

__all__ = ["ScaleReference", "choose_reference", "scaled_estimate"]


@dataclasses.dataclass(frozen=True)
class ScaleReference:
    """The parameter that fixes the scale.

    Attributes
    ----------
    kind : {"drive", "mass", "payload"}
    value : float
        The reference's value (N/A for a drive's current-to-force constant, kg for a mass).
    std : float
        Its standard deviation (same unit).
    cable : int or None
        The reference drive (1-based) for ``kind == "drive"``.
    source : str
        One sentence: where the value and its uncertainty come from.
    """

    kind: str
    value: float
    std: float
    cable: int | None
    source: str

    def index(self, p: int) -> int:
        """Position of the reference in ``theta = (x (p), k_1..k_m, ...)``.

        Parameters
        ----------
        p : int
            Number of platform parameters.

        Returns
        -------
        int
            ``p + cable - 1`` for a drive; 0 (the mass) otherwise.
        """
        return p + self.cable - 1 if self.kind == "drive" else 0  # payload: via the mass

    def as_json(self) -> dict:
        """JSON ``scale_reference``.

        Returns
        -------
        dict
            ``kind``, ``cable``, ``value``, ``std``, ``relative_std`` and ``source``.
        """
        return {"kind": self.kind, "cable": self.cable, "value": self.value, "std": self.std,
                "relative_std": self.std / self.value, "source": self.source}


def _uniform_std(value: float, tol: float) -> float:
    return abs(value) * tol / math.sqrt(3.0)


def _drive_reference(drives, cable: int, m: int, why: str) -> ScaleReference:
    if drives is None:
        raise InputError("--reference drive:K needs the drive fields (drum_radius, gear_ratio, "
                         "torque_constant) in robot.toml's [[cable]] tables.")
    if not 1 <= cable <= m:
        raise InputError(f"--reference drive:{cable}: the robot has cables 1..{m}.")
    k = float(drives.k_nominal[cable - 1])
    tol = float(drives.tolerance[cable - 1])
    tol_txt = "no tolerance stated: taken as exact" if math.isnan(tol) else f"tolerance {tol:g}"
    tol = 0.0 if math.isnan(tol) else tol
    return ScaleReference("drive", k, _uniform_std(k, tol), cable,
                          f"drive {cable} taken as calibrated ({why}): k = torque_constant x "
                          f"gear_ratio / drum_radius = {k:.6g} N/A from robot.toml, {tol_txt} "
                          "(relative half-width, uniform)")


def _mass_reference(robot, spec: str) -> ScaleReference:
    parts = spec.split(":")
    if len(parts) == 1:
        plat = robot.platform
        if plat.mass is None:
            raise InputError("--reference mass needs [platform] mass in robot.toml (or give "
                             "--reference mass:KG[:STD_KG]).")
        if plat.mass_uncertainty is None:
            raise InputError("--reference mass needs [platform] mass_uncertainty in robot.toml "
                             "(how well the platform was weighed), or give "
                             "--reference mass:KG:STD_KG.")
        return ScaleReference("mass", float(plat.mass),
                              _uniform_std(plat.mass, plat.mass_uncertainty), None,
                              f"weighed platform mass {plat.mass:g} kg from robot.toml, "
                              f"mass_uncertainty {plat.mass_uncertainty:g} (relative "
                              "half-width, uniform)")
    try:
        vals = [float(v) for v in parts[1:]]
    except ValueError:
        raise InputError(f"--reference {spec}: expected mass:KG or mass:KG:STD_KG.") from None
    if len(vals) > 2 or not all(math.isfinite(v) for v in vals) or vals[0] <= 0 or (
            len(vals) == 2 and vals[1] < 0):
        raise InputError(f"--reference {spec}: expected mass:KG or mass:KG:STD_KG with "
                         "KG > 0 and STD_KG >= 0.")
    std = vals[1] if len(vals) == 2 else 0.0
    return ScaleReference("mass", vals[0], std, None,
                          f"stated platform mass {vals[0]:g} kg, std {std:g} kg (--reference)")


def choose_reference(spec: str | None, robot, drives, allow_drive: bool = True) -> ScaleReference:
    """The scale reference named by ``spec`` (or chosen: ``None`` / ``"auto"``).

    Parameters
    ----------
    spec : str or None
        ``drive:K`` (drive K's nominal constant, its tolerance from robot.toml), ``mass``
        (robot.toml's ``[platform] mass`` and ``mass_uncertainty``), ``mass:KG[:STD_KG]``, or
        ``auto``/None: the drive marked ``drive_reference = true``, else among the drives with
        a stated tolerance and the weighed mass, the one of smallest relative std.
    robot : CableRobot
    drives : DriveData or None
    allow_drive : bool
        False for free motion (no drive in the equations).

    Returns
    -------
    ScaleReference

    Raises
    ------
    InputError
        One sentence when the reference is malformed or there is none.
    """
    m = robot.n_cables
    if spec not in (None, "auto"):
        if spec.startswith("drive:") and allow_drive:
            try:
                cable = int(spec.split(":", 1)[1])
            except ValueError:
                raise InputError(f"--reference {spec}: expected drive:K with K a cable "
                                 "number.") from None
            return _drive_reference(drives, cable, m, "--reference")
        if spec == "mass" or spec.startswith("mass:"):
            return _mass_reference(robot, spec)
        kinds = "drive:K, mass or mass:KG[:STD_KG]" if allow_drive else "mass or mass:KG[:STD_KG]"
        raise InputError(f"--reference {spec!r} is not understood; use {kinds}.")
    if allow_drive and drives is not None and drives.reference.any():
        return _drive_reference(drives, int(np.flatnonzero(drives.reference)[0]) + 1, m,
                                "drive_reference = true in robot.toml")
    cands = []
    if allow_drive and drives is not None:
        cands += [(float(tol), "drive", j + 1) for j, tol in enumerate(drives.tolerance)
                  if not math.isnan(tol)]
    plat = robot.platform
    if plat.mass is not None and plat.mass_uncertainty is not None:
        cands.append((float(plat.mass_uncertainty), "mass", None))
    if not cands:
        what = ("a calibrated drive (--reference drive:K, or drive_reference = true / "
                "torque_constant_tolerance in robot.toml), " if allow_drive else "")
        raise InputError("no scale reference: poses" + (", lengths and currents" if allow_drive
                         else "") + " fix the parameters only up to a common factor; give "
                         f"{what}a weighed mass ([platform] mass and mass_uncertainty, or "
                         "--reference mass:KG[:STD_KG]).")
    tol, kind, cable = min(cands, key=lambda c: c[0])
    if kind == "drive":
        return _drive_reference(drives, cable, m, "the smallest stated tolerance")
    return _mass_reference(robot, "mass")


def scaled_estimate(phi, cov_phi, ref: ScaleReference, r: int) -> tuple[np.ndarray, np.ndarray]:
    """``theta = v phi`` and its covariance, the reference's uncertainty propagated.

    Parameters
    ----------
    phi : (q - 1,) the fit without the reference parameter (``phi_r = 1``)
    cov_phi : (q - 1, q - 1) its covariance
    ref : ScaleReference
    r : int
        Index of the reference in the full vector.

    Returns
    -------
    theta (q,), cov (q, q)
    """
    full = np.insert(np.asarray(phi, float), r, 1.0)
    q = full.size
    C = np.zeros((q, q))
    o = np.delete(np.arange(q), r)
    C[np.ix_(o, o)] = cov_phi
    return ref.value * full, ref.value ** 2 * C + ref.std ** 2 * np.outer(full, full)
