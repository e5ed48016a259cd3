"""Safety of an excitation trajectory: limits (with stated defaults), the platform's
uncertainty box, and the exact certificate of every limit on a dense grid.

Limits are robot.toml ``[limits]`` (spec 1.1). A limit that robot.toml does not give is
replaced by the default of :data:`DEFAULT_LIMITS` and listed in ``defaults_used`` (printed by
``cdprid excite`` and written to its JSON): never invented silently.

The platform's inertial parameters are uncertain: the box of robot.toml ``[platform]``
(``mass`` +- ``mass_uncertainty`` relative, ``com`` +- ``com_uncertainty`` per axis, principal
moments of ``inertia`` +- ``inertia_uncertainty`` relative), or the estimate +- 3 std of an
earlier ``cdprid identify --json`` (``--prior``). The wrench the cables must produce is
``w = A(motion) x`` (:func:`cdprid.model.regressor_full`), linear in the 10 parameters
``x = [m, m s_G, I_P]``; the feasible wrenches of a sample form a convex polytope, so a
sample that is feasible at every point of a finite set in x is feasible in its convex hull.
The certificate checks every point of a set whose hull holds every platform of the box
(:func:`corner_parameters`: 1024 points for the physical box with rotations, as ``m s_G`` and
the ``m s s^T`` term of the inertia about P are not linear in the physical quantities; 16
without rotation; the 2^p corners of the prior's box, which is a box in x); the optimiser uses
the interval hull of those points in x.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
from pathlib import Path

import numpy as np

from cdprid.base import UserError
from cdprid.model import PARAMETER_NAMES, CableRobot, InertialParameters

__all__ = [
    "DEFAULT_LIMITS",
    "DEFAULT_UNCERTAINTY",
    "SafetyLimits",
    "UncertaintyBox",
    "safety_limits",
    "uncertainty_from_robot",
    "uncertainty_from_prior",
    "corner_parameters",
]

#: Limits used when robot.toml does not give them (units: SI; stated in every output).
DEFAULT_LIMITS = {
    "tension_min": 1.0,  # N: cables kept taut
    "cable_speed_max": 1.0,  # m/s
    "acceleration_max": 2.0,  # m/s^2 (about 0.2 g)
    "jerk_max": 20.0,  # m/s^3
    "tilt_max": 0.26,  # rad (15 deg)
    "angular_velocity_max": 1.0,  # rad/s
    "angular_acceleration_max": 5.0,  # rad/s^2
    "cable_clearance": 0.01,  # m
}

#: Uncertainty used when robot.toml [platform] has a nominal value but not its uncertainty.
DEFAULT_UNCERTAINTY = {"mass_uncertainty": 0.1, "com_uncertainty": 0.01, "inertia_uncertainty": 0.3}


@dataclasses.dataclass(frozen=True)
class SafetyLimits:
    """Every limit a trajectory must respect (robot.toml or default; see ``defaults_used``)."""

    tension_min: float
    tension_max: float
    cable_speed_max: float
    acceleration_max: float
    jerk_max: float
    tilt_max: float
    angular_velocity_max: float
    angular_acceleration_max: float
    cable_clearance: float
    workspace_min: tuple
    workspace_max: tuple
    defaults_used: tuple

    def as_json(self) -> dict:
        """JSON ``limits``.

        Returns
        -------
        dict
            Every limit (SI units; the workspace as lists) and ``defaults_used``.
        """
        out = {k: (list(v) if isinstance(v, tuple) else v)
               for k, v in dataclasses.asdict(self).items() if k != "defaults_used"}
        out["defaults_used"] = list(self.defaults_used)
        return out


def _default_box(robot: CableRobot):
    """Without a workspace box: the exit points' bounding box shrunk by 25 %, its top 0.3 m
    below the highest exit. When the exits lie near one horizontal plane (a suspended robot:
    their height spread under half the horizontal half extent) the platform hangs below that
    plane: the box then spans from 0.3 m below the lowest exit down by 75 % of the larger
    horizontal half extent (the box on the exit plane itself left no gentle run)."""
    A = np.asarray(robot.B_A)
    lo, hi = A.min(axis=0), A.max(axis=0)
    c, h = 0.5 * (lo + hi), 0.5 * (hi - lo)
    lo2, hi2 = c - 0.75 * h, c + 0.75 * h
    reach = float(max(h[0], h[1]))
    if hi[2] - lo[2] < 0.5 * reach:
        hi2[2] = lo[2] - 0.3
        lo2[2] = hi2[2] - 0.75 * reach
    else:
        hi2[2] = max(hi2[2] - 0.3, lo2[2] + 0.1)
    return tuple(float(v) for v in lo2), tuple(float(v) for v in hi2)


def safety_limits(robot: CableRobot, mass_max: float) -> SafetyLimits:
    """The limits of robot.toml, completed by :data:`DEFAULT_LIMITS` (each default named).

    Parameters
    ----------
    robot : CableRobot
    mass_max : float
        The heaviest platform, kg; ``tension_max`` defaults to 20 times its weight.

    Returns
    -------
    SafetyLimits

    Raises
    ------
    UserError
        ``tension_max`` not above ``tension_min``.
    """
    lim = robot.limits
    used = []
    vals = {}
    for key, default in DEFAULT_LIMITS.items():
        v = getattr(lim, key)
        if v is None:
            used.append(key)
            v = default
        vals[key] = float(v)
    if lim.tension_max is None:
        used.append("tension_max")
        vals["tension_max"] = 20.0 * 9.81 * float(mass_max)
    else:
        vals["tension_max"] = float(lim.tension_max)
    if lim.workspace_min is None or lim.workspace_max is None:
        used.append("workspace")
        lo, hi = _default_box(robot)
    else:
        lo, hi = tuple(lim.workspace_min), tuple(lim.workspace_max)
    if not vals["tension_max"] > vals["tension_min"]:
        raise UserError(f"[limits] tension_max ({vals['tension_max']} N) must exceed tension_min "
                        f"({vals['tension_min']} N).")
    return SafetyLimits(workspace_min=lo, workspace_max=hi, defaults_used=tuple(used), **vals)


@dataclasses.dataclass(frozen=True)
class UncertaintyBox:
    """The platform's nominal parameters and the corners of its uncertainty box.

    Attributes
    ----------
    nominal : InertialParameters
    corners : ndarray (k, 10)
        Corner parameter vectors ``[m, m s_G, I_P]`` (full model, inertia about P).
    source : str
        ``robot.toml [platform]`` or the prior file.
    description : dict
        The half-widths used (JSON-ready), and ``defaults_used``.
    """

    nominal: InertialParameters
    corners: np.ndarray
    source: str
    description: dict

    @property
    def x_nominal(self) -> np.ndarray:
        """Nominal parameter vector (10,), full model (kg, kg m, kg m^2)."""
        return np.asarray(self.nominal.vector("full"))

    @property
    def x_lo(self) -> np.ndarray:
        """Lower corner of the interval hull of the corners in x (10,)."""
        return np.minimum(self.corners.min(axis=0), self.x_nominal)

    @property
    def x_hi(self) -> np.ndarray:
        """Upper corner of the interval hull of the corners in x (10,)."""
        return np.maximum(self.corners.max(axis=0), self.x_nominal)

    @property
    def mass_max(self) -> float:
        """The largest mass of the box, kg."""
        return float(self.corners[:, 0].max())


def corner_parameters(mass: float, com, inertia, mass_unc: float, com_unc: float,
                      inertia_unc: float, rotates: bool = True) -> np.ndarray:
    """Vectors ``x = [m, m s_G, I_P]`` whose convex hull holds every platform of the physical box.

    The box: mass, centre of mass per axis, principal moments of the inertia. ``x`` is not
    linear in the physical quantities: ``m s_G`` is bilinear and the inertia about
    P, ``I_P = I_G + m (|s|^2 1 - s s^T)``, holds the squares ``d_j^2`` of the centre-of-mass
    offsets ``d = s - s_nominal``. Replacing each ``d_j^2`` by an independent ``e_j`` in
    ``[0, com_unc^2]`` makes ``x`` multilinear in (m, d, e, principal moments): the image of
    that (larger) box is inside the convex hull of the images of its vertices, returned here
    (2^10 = 1024 vertices; the tensions are linear in x, so a sample feasible at every vertex
    is feasible for every platform of the physical box). Without rotation (``rotates=False``)
    the inertia does not enter the wrench: 16 corners (mass and centre of mass), inertia at
    its nominal principal moments.

    Parameters
    ----------
    mass : float
        Nominal mass, kg.
    com : array (3,)
        Nominal centre of mass, platform frame, m.
    inertia : array (3, 3)
        Nominal inertia about the centre of mass, kg m^2.
    mass_unc, inertia_unc : float
        Relative uncertainties of the mass and of each principal moment.
    com_unc : float
        Uncertainty of the centre of mass per axis, m.
    rotates : bool
        Whether the trajectory rotates.

    Returns
    -------
    ndarray (k, 10)
        Unique corner vectors (kg, kg m, kg m^2).
    """
    I = np.asarray(inertia, float)
    lam, V = np.linalg.eigh(0.5 * (I + I.T))
    s0 = np.asarray(com, float)
    c = float(com_unc)
    relax = rotates and c > 0.0
    iu = (-inertia_unc, inertia_unc) if rotates else (0.0,)
    ev = (0.0, c * c) if relax else (None,)
    out = []
    for sm, *rest in itertools.product((-1, 1), (-1, 1), (-1, 1), (-1, 1), ev, ev, ev, iu, iu, iu):
        m = mass * (1.0 + sm * mass_unc)
        d = c * np.asarray(rest[:3], float)
        e = d * d if not relax else np.asarray(rest[3:6], float)
        D = np.outer(d, d)
        D[np.diag_indices(3)] = e
        SS = np.outer(s0, s0) + np.outer(s0, d) + np.outer(d, s0) + D
        I_P = V @ np.diag(lam * (1.0 + np.asarray(rest[6:]))) @ V.T \
            + m * (np.trace(SS) * np.eye(3) - SS)
        out.append(np.r_[m, m * (s0 + d), I_P[0, 0], I_P[0, 1], I_P[0, 2], I_P[1, 1],
                         I_P[1, 2], I_P[2, 2]])
    return np.unique(np.round(np.array(out), 15), axis=0)


def uncertainty_from_robot(robot: CableRobot, rotates: bool = True) -> UncertaintyBox:
    """The uncertainty box of robot.toml ``[platform]`` (defaults named in ``defaults_used``).

    Parameters
    ----------
    robot : CableRobot
    rotates : bool
        Whether the trajectory rotates (the inertia matters).

    Returns
    -------
    UncertaintyBox

    Raises
    ------
    UserError
        robot.toml has no ``[platform]`` mass.
    """
    pl = robot.platform
    if pl.mass is None:
        raise UserError(
            "robot.toml has no [platform] mass: excite needs the platform's nominal mass, centre "
            "of mass and inertia with their uncertainty (spec 1.1 [platform]), or --prior "
            "identify.json from an earlier `cdprid identify --json`.")
    used = []
    com = pl.com
    if com is None:
        used.append("com = [0, 0, 0]")
        com = (0.0, 0.0, 0.0)
    inertia = pl.inertia
    if inertia is None:
        inertia = _box_inertia(pl)
        used.append("inertia = " + ("a uniform body box" if pl.body_min is not None
                                    else "0.01 m^2 x mass per axis"))
    unc = {}
    for key, default in DEFAULT_UNCERTAINTY.items():
        v = getattr(pl, key)
        if v is None:
            used.append(f"{key} = {default}")
            v = default
        unc[key] = float(v)
    nominal = InertialParameters(pl.mass, com, np.asarray(inertia))
    corners = corner_parameters(pl.mass, com, inertia, unc["mass_uncertainty"],
                                unc["com_uncertainty"], unc["inertia_uncertainty"], rotates)
    desc = dict(unc, mass=pl.mass, com=list(com), defaults_used=used, n_corners=len(corners))
    return UncertaintyBox(nominal, corners, "robot.toml [platform]", desc)


def _box_inertia(pl) -> np.ndarray:
    if pl.body_min is not None:
        e = np.asarray(pl.body_max) - np.asarray(pl.body_min)
        return pl.mass / 12.0 * np.diag([e[1] ** 2 + e[2] ** 2, e[0] ** 2 + e[2] ** 2,
                                         e[0] ** 2 + e[1] ** 2])
    return pl.mass * 0.01 * np.eye(3)


def _prior_parameters(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"--prior {path}: file not found.") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise UserError(f"--prior {path}: not valid JSON ({exc}).") from None
    params = data.get("parameters") if isinstance(data, dict) else None
    if not isinstance(params, dict) or "m" not in params:
        raise UserError(f"--prior {path}: no 'parameters' object with 'm' (expected the output "
                        "of `cdprid identify --json`).")
    out = {}
    for name, entry in params.items():
        try:
            v = float(entry["value"])
            s = max(float(entry["std"]), float(entry.get("std_iid", 0.0)))
        except (KeyError, TypeError, ValueError):
            raise UserError(f"--prior {path}: parameter {name!r} needs numeric 'value' and "
                            "'std'.") from None
        if not (np.isfinite(v) and np.isfinite(s) and s >= 0):
            raise UserError(f"--prior {path}: parameter {name!r} has a non-finite value or std.")
        out[name] = (v, s)
    if out["m"][0] - 3 * out["m"][1] <= 0:
        raise UserError(f"--prior {path}: the mass estimate minus 3 std is not positive; the "
                        "prior is too uncertain to certify tensions.")
    return out


def uncertainty_from_prior(path, robot: CableRobot, rotates: bool = True) -> UncertaintyBox:
    """The box estimate +- 3 std of ``cdprid identify --json`` (corners in x).

    Parameters the prior does not hold (the inertia after a translation-only identification)
    come from robot.toml ``[platform]`` with its uncertainty (corners of the physical box
    there, nominal mass), or from a uniform-box guess stated in ``defaults_used``.

    Parameters
    ----------
    path : path-like
        The ``identify --json`` file.
    robot : CableRobot
    rotates : bool
        Whether the trajectory rotates (the inertia matters).

    Returns
    -------
    UncertaintyBox

    Raises
    ------
    UserError
        Missing or malformed file, a parameter without numeric value and std, or a mass
        estimate minus 3 std that is not positive.
    """
    path = Path(path)
    prior = _prior_parameters(path)
    names = PARAMETER_NAMES["full"]
    x = np.array([prior.get(n, (np.nan, 0.0))[0] for n in names])
    h = np.array([3.0 * prior.get(n, (np.nan, 0.0))[1] for n in names])
    used = []
    if np.isnan(x[4]):
        m, s = x[0], x[1:4] / x[0]
        pl = robot.platform
        if pl.inertia is not None:
            I_G = np.asarray(pl.inertia)
            iu = pl.inertia_uncertainty if pl.inertia_uncertainty is not None else \
                DEFAULT_UNCERTAINTY["inertia_uncertainty"]
            if pl.inertia_uncertainty is None:
                used.append(f"inertia_uncertainty = {iu}")
        else:
            I_G = _box_inertia(dataclasses.replace(pl, mass=m))
            iu = 0.5
            used.append("inertia = uniform body box guess +- 50 %")
        I_P = np.asarray(InertialParameters(m, s, I_G).vector("full"))[4:]
        x[4:] = I_P
        h[4:] = iu * np.abs(I_P) if rotates else 0.0
    if not rotates:
        h[4:] = 0.0
    signs = itertools.product(*[(-1.0, 1.0) if hk > 0 else (0.0,) for hk in h])
    corners = np.array([x + np.array(sg) * h for sg in signs])
    nominal = InertialParameters.from_vector(x, "full")
    desc = {"estimate": dict(zip(names, x.tolist(), strict=True)),
            "half_width_3std": dict(zip(names, h.tolist(), strict=True)),
            "defaults_used": used, "n_corners": len(corners)}
    return UncertaintyBox(nominal, corners, str(path), desc)
