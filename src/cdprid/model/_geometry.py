"""Robot geometry: :class:`CableRobot` and its robot.toml (spec v1).

Notation (paper section 3, names carry their frame):

- ``B_A`` (m, 3): exit points A_i, base frame. With a swivel pulley, A_i is the fixed
  point where the cable enters the pulley, on the swivel axis.
- ``P_b`` (m, 3): attachment points b_i on the platform, platform frame (origin P).
- ``B_p`` (3,): position of P in the base frame; ``B_R_P`` (3, 3): rotation platform -> base.
- ``u_i``: unit vector of cable i from its attachment B_i towards its leave point, base frame.
- ``W`` (6, m): wrench matrix (eq. 2), columns ``[u_i; (B_R_P b_i) x u_i]``: force and
  moment about P, base frame, of unit tensions. The paper writes ``b_i x u_i`` with b_i
  "expressed in the platform frame"; the moment needs b_i rotated into the base frame,
  which is what is implemented (identical when ``B_R_P = I``).

The per-pose geometry (cable vectors, lengths, W) is in :mod:`cdprid.model._cables`.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import tomllib

from cdprid.base import InputError

__all__ = [
    "CableRobot",
    "Limits",
    "NominalPlatform",
    "load_robot",
    "robot_from_dict",
    "robot_to_dict",
    "RobotFileError",
]


class RobotFileError(InputError):
    """A robot.toml that cannot be used; the message is one sentence naming file and field."""


@dataclasses.dataclass(frozen=True)
class Limits:
    """Optional limits of robot.toml ``[limits]`` (None when absent)."""

    tension_min: float | None = None
    tension_max: float | None = None
    cable_speed_max: float | None = None
    workspace_min: tuple[float, float, float] | None = None
    workspace_max: tuple[float, float, float] | None = None
    acceleration_max: float | None = None  # m/s^2, |a| of P (spec 1.1)
    jerk_max: float | None = None  # m/s^3, |j| of P (spec 1.1)
    tilt_max: float | None = None  # rad, rotation angle from the identity (spec 1.1)
    angular_velocity_max: float | None = None  # rad/s (spec 1.1)
    angular_acceleration_max: float | None = None  # rad/s^2 (spec 1.1)
    cable_clearance: float | None = None  # m, cable-cable and cable-body (spec 1.1)


@dataclasses.dataclass(frozen=True)
class NominalPlatform:
    """Nominal platform of robot.toml ``[platform]``; never used as an identification answer.

    The spec 1.1 uncertainty fields say how far the truth may be from the nominal values:
    ``mass_uncertainty`` (relative), ``com_uncertainty`` (m, per axis), ``inertia_uncertainty``
    (relative, per principal moment); ``body_min``/``body_max`` a box (platform frame, m) that
    holds the platform body.
    """

    mass: float | None = None
    com: tuple[float, float, float] | None = None
    inertia: tuple[tuple[float, ...], ...] | None = None
    mass_uncertainty: float | None = None
    com_uncertainty: float | None = None
    inertia_uncertainty: float | None = None
    body_min: tuple[float, float, float] | None = None
    body_max: tuple[float, float, float] | None = None


class CableRobot(eqx.Module):
    """Geometry of a cable-driven parallel robot (an immutable pytree).

    Attributes
    ----------
    B_A : array (m, 3)
        Exit points (pulley entry points when a pulley is present), base frame, m.
    P_b : array (m, 3)
        Attachment points, platform frame, m.
    pulley_radius : array (m,)
        Swivel pulley radius, m (0 = no pulley).
    pulley_axis : array (m, 3)
        Unit swivel axes, base frame.
    pulley_reference : array (m, 3)
        Unit vectors (base frame, perpendicular to the axis) of swivel angle 0.
    gravity : array (3,)
        Gravity acceleration, base frame, m/s^2.
    name, limits, platform, survey_tolerance_m
        Static metadata (``survey_tolerance_m``: robot.toml's ``survey_tolerance``, m, or
        None when not stated).
    """

    B_A: jnp.ndarray
    P_b: jnp.ndarray
    pulley_radius: jnp.ndarray
    pulley_axis: jnp.ndarray
    pulley_reference: jnp.ndarray
    gravity: jnp.ndarray
    name: str = eqx.field(static=True, default="robot")
    limits: Limits = eqx.field(static=True, default=Limits())
    platform: NominalPlatform = eqx.field(static=True, default=NominalPlatform())
    #: how far the surveyed exit and attachment points may be from the truth, m (robot.toml
    #: top-level ``survey_tolerance``; ``None``: not stated, the diagnosis assumes 0.02 m)
    survey_tolerance_m: float | None = eqx.field(static=True, default=None)

    @property
    def n_cables(self) -> int:
        """Number of cables m."""
        return int(self.B_A.shape[0])

    @property
    def has_pulleys(self) -> bool:
        """True when any cable has a swivel pulley of positive radius."""
        return bool(np.any(np.asarray(self.pulley_radius) > 0))

    def replace(self, **changes) -> CableRobot:
        """A copy with some array fields replaced (e.g. ``B_A=...``).

        Parameters
        ----------
        **changes : array-like
            New values of array fields by name (converted to float arrays; units as the fields).

        Returns
        -------
        CableRobot
            The copy; ``self`` is unchanged.
        """
        out = self
        for key, value in changes.items():
            out = eqx.tree_at(lambda r, k=key: getattr(r, k), out, jnp.asarray(value, float))
        return out


def _default_reference(axis: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to ``axis``: base x projected, else base y."""
    for cand in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])):
        v = cand - (cand @ axis) * axis
        if np.linalg.norm(v) > 1e-6:
            return v / np.linalg.norm(v)
    raise AssertionError("unreachable")


def _vec(src: str, table: dict, key: str, where: str, n: int = 3, default=None):
    if key not in table:
        if default is not None:
            return np.asarray(default, float)
        raise RobotFileError(f"{src}: {where} is missing the required field '{key}'.")
    val = table[key]
    try:
        arr = np.asarray(val, dtype=float)
    except (TypeError, ValueError):
        raise RobotFileError(
            f"{src}: {where} field '{key}' must be a list of {n} numbers, got {val!r}."
        ) from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise RobotFileError(
            f"{src}: {where} field '{key}' must be a list of {n} finite numbers, got {val!r}."
        )
    return arr


def _num(src: str, table: dict, key: str, where: str):
    if key not in table:
        return None
    val = table[key]
    if isinstance(val, bool) or not isinstance(val, (int, float)) or not np.isfinite(val):
        raise RobotFileError(f"{src}: {where} field '{key}' must be a finite number, got {val!r}.")
    return float(val)


_LIMITS_11 = ("acceleration_max", "jerk_max", "tilt_max", "angular_velocity_max",
              "angular_acceleration_max", "cable_clearance")


def _positive(src: str, table: dict, key: str, where: str):
    v = _num(src, table, key, where)
    if v is not None and not v > 0:
        raise RobotFileError(f"{src}: {where} field '{key}' must be > 0, got {v}.")
    return v


def _platform(source: str, plat: dict, inertia) -> NominalPlatform:
    """The ``[platform]`` table (spec 1.1 fields validated, one sentence per problem)."""
    where = "[platform]"
    com = _vec(source, plat, "com", where) if "com" in plat else None
    mass = _positive(source, plat, "mass", where)
    unc = {}
    for key in ("mass_uncertainty", "com_uncertainty", "inertia_uncertainty"):
        v = _num(source, plat, key, where)
        if v is not None and v < 0:
            raise RobotFileError(f"{source}: {where} field '{key}' must be >= 0, got {v}.")
        unc[key] = v
    for key in ("mass_uncertainty", "inertia_uncertainty"):
        if unc[key] is not None and unc[key] >= 1:
            raise RobotFileError(f"{source}: {where} field '{key}' is relative and must be "
                                 f"below 1, got {unc[key]}.")
    bmin = _vec(source, plat, "body_min", where) if "body_min" in plat else None
    bmax = _vec(source, plat, "body_max", where) if "body_max" in plat else None
    if (bmin is None) != (bmax is None):
        raise RobotFileError(f"{source}: {where} fields 'body_min' and 'body_max' must be given "
                             "together.")
    if bmin is not None and not np.all(bmax > bmin):
        raise RobotFileError(f"{source}: {where} field 'body_max' must exceed 'body_min' on "
                             "every axis.")
    if inertia is not None:
        I = np.asarray(inertia)
        if not np.allclose(I, I.T, atol=1e-9) or np.linalg.eigvalsh(0.5 * (I + I.T))[0] <= 0:
            raise RobotFileError(f"{source}: {where} field 'inertia' must be symmetric positive "
                                 "definite.")
    return NominalPlatform(
        mass=mass,
        com=None if com is None else tuple(float(v) for v in com),
        inertia=inertia,
        body_min=None if bmin is None else tuple(float(v) for v in bmin),
        body_max=None if bmax is None else tuple(float(v) for v in bmax),
        **unc,
    )


_KNOWN_KEYS = {
    "the top level": ("name", "gravity", "limits", "cable", "platform", "survey_tolerance"),
    "[limits]": ("tension_min", "tension_max", "cable_speed_max", "workspace_min",
                 "workspace_max", *_LIMITS_11),
    "[[cable]]": ("exit", "anchor", "pulley_radius", "pulley_axis", "pulley_reference",
                  # drive fields of format 1.2 (parsed by cdprid.io._drives)
                  "drum_radius", "gear_ratio", "torque_constant", "torque_constant_tolerance",
                  "drive_reference"),
    "[platform]": ("mass", "com", "inertia", "mass_uncertainty", "com_uncertainty",
                   "inertia_uncertainty", "body_min", "body_max"),
}


def _check_typos(source: str, data: dict) -> None:
    """Refuse a field that is a near miss of a spec field (``tension_mx``): silently ignoring it
    would drop the user's limit. Fields unlike any spec field are left alone (extensions)."""
    import difflib

    tables = [("the top level", data)]
    if isinstance(data.get("limits"), dict):
        tables.append(("[limits]", data["limits"]))
    if isinstance(data.get("platform"), dict):
        tables.append(("[platform]", data["platform"]))
    tables += [("[[cable]]", c) for c in data.get("cable") or [] if isinstance(c, dict)]
    for where, table in tables:
        known = _KNOWN_KEYS[where]
        for key in table:
            if key in known:
                continue
            near = difflib.get_close_matches(key, known, n=1, cutoff=0.8)
            if near:
                raise RobotFileError(f"{source}: {where} has an unknown field '{key}'; did you "
                                     f"mean '{near[0]}'?")


def robot_from_dict(data: dict, source: str = "robot.toml") -> CableRobot:
    """Build a :class:`CableRobot` from the parsed robot.toml mapping (spec v1).

    Parameters
    ----------
    data : dict
        The parsed TOML (lengths in m, masses in kg, inertia in kg m^2).
    source : str
        The file name used in messages.

    Returns
    -------
    CableRobot

    Raises
    ------
    RobotFileError
        One sentence naming ``source``, the table and field, and what is wrong.
    """
    _check_typos(source, data)
    cables = data.get("cable")
    if not isinstance(cables, list) or len(cables) == 0:
        raise RobotFileError(f"{source}: no [[cable]] tables found; at least one cable is "
                             "required.")
    B_A, P_b, radius, axis, ref = _cable_arrays(source, cables)
    gravity = _vec(source, data, "gravity", "the top level", default=[0.0, 0.0, -9.81])
    limits = _limits_from_dict(source, data)
    plat = data.get("platform", {}) or {}
    if not isinstance(plat, dict):
        raise RobotFileError(f"{source}: [platform] must be a table.")
    platform = _platform(source, plat, _platform_inertia(source, plat))
    name = data.get("name", "robot")
    return CableRobot(
        # device_put: jnp.asarray of a NumPy array compiles a conversion per shape (3 of
        # them, ~40 ms of a command's start)
        B_A=jax.device_put(np.array(B_A)),
        P_b=jax.device_put(np.array(P_b)),
        pulley_radius=jax.device_put(np.array(radius)),
        pulley_axis=jax.device_put(np.array(axis)),
        pulley_reference=jax.device_put(np.array(ref)),
        gravity=jax.device_put(np.array(gravity)),
        name=str(name),
        limits=limits,
        platform=platform,
        survey_tolerance_m=_positive(source, data, "survey_tolerance", "the top level"),
    )


def _cable_arrays(source: str, cables: list) -> tuple[list, list, list, list, list]:
    """Exit points, anchors, pulley radii, unit pulley axes and unit pulley references of the
    ``[[cable]]`` tables (lists, one entry per cable); :class:`RobotFileError` if invalid."""
    B_A, P_b, radius, axis, ref = [], [], [], [], []
    for i, c in enumerate(cables, start=1):
        where = f"[[cable]] number {i}"
        if not isinstance(c, dict):
            raise RobotFileError(f"{source}: {where} is not a table.")
        B_A.append(_vec(source, c, "exit", where))
        P_b.append(_vec(source, c, "anchor", where))
        r = _num(source, c, "pulley_radius", where)
        if r is not None and r < 0:
            raise RobotFileError(f"{source}: {where} field 'pulley_radius' must be >= 0, got {r}.")
        radius.append(0.0 if r is None else r)
        k = _vec(source, c, "pulley_axis", where, default=[0.0, 0.0, -1.0])
        if np.linalg.norm(k) < 1e-9:
            raise RobotFileError(f"{source}: {where} field 'pulley_axis' must not be zero.")
        k = k / np.linalg.norm(k)
        axis.append(k)
        if "pulley_reference" in c:
            e = _vec(source, c, "pulley_reference", where)
            e = e - (e @ k) * k
            if np.linalg.norm(e) < 1e-9:
                raise RobotFileError(
                    f"{source}: {where} field 'pulley_reference' must not be parallel to the axis."
                )
            ref.append(e / np.linalg.norm(e))
        else:
            ref.append(_default_reference(k))
    return B_A, P_b, radius, axis, ref


def _limits_from_dict(source: str, data: dict) -> Limits:
    """The :class:`Limits` of the ``[limits]`` table (all optional); :class:`RobotFileError`
    if invalid."""
    lim = data.get("limits", {}) or {}
    if not isinstance(lim, dict):
        raise RobotFileError(f"{source}: [limits] must be a table.")
    wmin = _vec(source, lim, "workspace_min", "[limits]") if "workspace_min" in lim else None
    wmax = _vec(source, lim, "workspace_max", "[limits]") if "workspace_max" in lim else None
    if wmin is not None and wmax is not None and not np.all(wmax > wmin):
        raise RobotFileError(f"{source}: [limits] field 'workspace_max' must exceed "
                             "'workspace_min' on every axis.")
    tmin = _num(source, lim, "tension_min", "[limits]")
    tmax = _num(source, lim, "tension_max", "[limits]")
    if tmin is not None and tmin < 0:
        raise RobotFileError(f"{source}: [limits] field 'tension_min' must be >= 0, got {tmin}.")
    if tmin is not None and tmax is not None and not tmax > tmin:
        raise RobotFileError(f"{source}: [limits] field 'tension_max' ({tmax}) must exceed "
                             f"'tension_min' ({tmin}).")
    return Limits(
        tension_min=tmin,
        tension_max=tmax,
        cable_speed_max=_positive(source, lim, "cable_speed_max", "[limits]"),
        workspace_min=None if wmin is None else tuple(float(v) for v in wmin),
        workspace_max=None if wmax is None else tuple(float(v) for v in wmax),
        **{k: _positive(source, lim, k, "[limits]") for k in _LIMITS_11},
    )


def _platform_inertia(source: str, plat: dict) -> tuple | None:
    """The ``[platform]`` table's ``inertia`` as a 3x3 tuple of floats, or None if absent;
    :class:`RobotFileError` if it is not a finite 3x3 numeric matrix."""
    if "inertia" not in plat:
        return None
    try:
        I = np.asarray(plat["inertia"], float)
    except (TypeError, ValueError):
        I = np.zeros(0)
    if I.shape != (3, 3) or not np.all(np.isfinite(I)):
        raise RobotFileError(f"{source}: [platform] field 'inertia' must be a 3x3 numeric "
                             "matrix.")
    return tuple(tuple(float(v) for v in row) for row in I)


def load_robot(path: str | Path) -> CableRobot:
    """Read a spec-v1 ``robot.toml``.

    Parameters
    ----------
    path : path-like
        The file (UTF-8, a byte-order mark allowed).

    Returns
    -------
    CableRobot

    Raises
    ------
    RobotFileError
        Missing file, broken TOML or an invalid field (one sentence).
    """
    path = Path(path)
    if not path.is_file():
        raise RobotFileError(f"{path}: required file is missing.")
    try:
        raw = path.read_bytes()
        data = tomllib.loads(raw.removeprefix(b"\xef\xbb\xbf").decode("utf-8"))  # BOM allowed
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path}: not valid TOML ({exc}).") from None
    except UnicodeDecodeError:
        raise RobotFileError(f"{path}: not valid UTF-8 text.") from None
    except (ValueError, RecursionError) as exc:  # a 5000-digit integer, arrays nested 3000 deep
        raise RobotFileError(f"{path}: cannot be read as a robot description ("
                             f"{_hostile_toml(exc)}).") from None
    return robot_from_dict(data, source=str(path))


def _hostile_toml(exc: BaseException) -> str:
    """What a TOML file beyond the parser's limits holds (a huge integer, deep nesting)."""
    if isinstance(exc, RecursionError):
        return "arrays or tables nested too deeply"
    return f"a value beyond the parser's limits: {str(exc).split(';')[0]}"



def robot_to_dict(robot: CableRobot) -> dict:
    """The spec-v1 robot.toml mapping of a robot (inverse of :func:`robot_from_dict`).

    Parameters
    ----------
    robot : CableRobot

    Returns
    -------
    dict
        TOML-able mapping; absent limits, platform fields and pulleys are left out.
    """
    out: dict = {"name": robot.name, "gravity": [float(v) for v in np.asarray(robot.gravity)]}
    lim = {k: (list(v) if isinstance(v, tuple) else v)
           for k, v in dataclasses.asdict(robot.limits).items() if v is not None}
    if lim:
        out["limits"] = lim
    if robot.survey_tolerance_m is not None:
        out["survey_tolerance"] = float(robot.survey_tolerance_m)
    cables = []
    for i in range(robot.n_cables):
        c = {
            "exit": [float(v) for v in np.asarray(robot.B_A[i])],
            "anchor": [float(v) for v in np.asarray(robot.P_b[i])],
        }
        r = float(robot.pulley_radius[i])
        if r > 0:
            c["pulley_radius"] = r
            c["pulley_axis"] = [float(v) for v in np.asarray(robot.pulley_axis[i])]
            c["pulley_reference"] = [float(v) for v in np.asarray(robot.pulley_reference[i])]
        cables.append(c)
    out["cable"] = cables
    plat = {}
    for key, v in dataclasses.asdict(robot.platform).items():
        if v is not None:
            plat[key] = [list(r) for r in v] if key == "inertia" else (
                list(v) if isinstance(v, tuple) else v)
    if plat:
        out["platform"] = plat
    return out
