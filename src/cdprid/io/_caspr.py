"""CASPR robot models (``*_bodies.xml`` + ``*_cables.xml``) -> robot.toml mapping (spec 1.1).

CASPR (Lau et al., https://github.com/darwinlau/CASPR) describes a robot as rigid links and
cables. A cable-driven parallel robot is one link with a ``SPATIAL_*`` joint to the ground
(link 0); each ideal cable runs from a point on link 0 (or over a ``base_rotating_pulley``)
to a point on link 1. The mapping to spec 1.1:

- the platform reference point P is the joint frame's origin of link 1; the base frame is
  CASPR's frame 0 (a joint whose ``parent/location`` is not zero puts P at that location
  plus the joint's translation: the geometry is unchanged, the workspace box is shifted);
- ``exit`` = the link-0 attachment; ``anchor`` = the link-1 attachment in the joint frame
  (``attachment_reference="com"`` adds the centre of mass ``com_location``);
- ``base_rotating_pulley``: ``exit`` = ``fixed_location`` (where the cable enters),
  ``pulley_radius`` = ``pulley_radius``, ``pulley_axis`` = unit ``cable_entry_vector``: CASPR's
  pulley centre is ``r_F + R e`` with e the direction of the attachment perpendicular to the
  entry vector (``BaseRotatingPulleyAttachment.ComputePulleyLeavingLocation``), which is the
  spec's swivel pulley with the cable running into it along that vector;
- ``[limits]``: ``tension_min`` / ``tension_max`` the largest ``force_min`` and the smallest
  ``force_max`` of the cables (one pair in spec 1.1; a note says when they differ), the
  workspace box from the joint's translation bounds ``q_min`` / ``q_max``;
- ``[platform]``: ``mass``, ``com`` = ``com_location``, ``inertia`` about the centre of mass
  (``ref="joint"`` is moved there by the parallel-axis theorem).

What spec 1.1 cannot hold is refused in one sentence naming the file: several links, a joint
that is not spatial, elastic or variable-stiffness cables, screw-drive pulleys, cables with
more than two attachments.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cdprid.base import InputError

__all__ = ["CasprImport", "read_caspr"]


@dataclass(frozen=True)
class CasprImport:
    """A CASPR model mapped to spec 1.1.

    Attributes
    ----------
    robot : dict
        The robot.toml mapping (``cdprid.model.robot_from_dict`` reads it).
    cable_set : str
        The CASPR cable set used.
    notes : tuple of str
        What the mapping assumed or dropped (one sentence each).
    """

    robot: dict
    cable_set: str
    notes: tuple[str, ...] = field(default_factory=tuple)


def _parse(path: Path) -> ET.Element:
    if not path.is_file():
        raise InputError(f"{path}: the file does not exist.")
    try:
        return ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise InputError(f"{path}: not valid XML ({exc}).") from None


def _vector(src: Path, node: ET.Element | None, what: str, n: int = 3) -> np.ndarray:
    text = None if node is None else node.text
    try:
        v = np.array([float(x) for x in (text or "").split()])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise InputError(f"{src}: {what} must be {n} numbers, got {text!r}.")
    return v


def _number(src: Path, node: ET.Element, tag: str, what: str) -> float:
    child = node.find(tag)
    try:
        v = float((child.text if child is not None else "").strip())
    except ValueError:
        v = float("nan")
    if not np.isfinite(v):
        raise InputError(f"{src}: {what} <{tag}> must be a number.")
    return v


def _link(src: Path, root: ET.Element) -> ET.Element:
    """The single rigid link of a bodies file (refusing several links or a non-spatial joint)."""
    links = root.find("links")
    items = [] if links is None else list(links)
    if len(items) != 1 or items[0].tag != "link_rigid":
        kinds = ", ".join(sorted({i.tag for i in items})) or "none"
        raise InputError(f"{src}: cdprid models one rigid platform, but this CASPR model has "
                         f"{len(items)} links ({kinds}): a multi-link (or empty) model cannot "
                         "be mapped to robot.toml.")
    link = items[0]
    joint = link.find("joint")
    jtype = "" if joint is None else joint.get("type", "")
    if not jtype.startswith("SPATIAL"):
        raise InputError(f"{src}: the link's joint is {jtype or 'missing'}, not a SPATIAL "
                         "joint: only a platform free in six degrees of freedom maps to "
                         "robot.toml.")
    parent = link.findtext("parent/num")
    if parent is not None and parent.strip() != "0":
        raise InputError(f"{src}: the link's parent is link {parent.strip()}, not the ground "
                         "(link 0).")
    return link


def _platform(src: Path, link: ET.Element) -> tuple[dict, np.ndarray, list[str]]:
    """The ``[platform]`` table, the centre of mass (joint frame) and notes."""
    phys = link.find("physical")
    if phys is None:
        raise InputError(f"{src}: the link has no <physical> block (mass, com_location).")
    mass = _number(src, phys, "mass", "<physical>")
    if mass <= 0:
        raise InputError(f"{src}: <physical> <mass> must be positive, got {mass}.")
    com = _vector(src, phys.find("com_location"), "<physical> <com_location>")
    plat: dict = {"mass": mass, "com": com.tolist()}
    notes = []
    inertia = phys.find("inertia")
    if inertia is not None:
        I = np.zeros((3, 3))
        for (i, j), tag in {(0, 0): "Ixx", (1, 1): "Iyy", (2, 2): "Izz", (0, 1): "Ixy",
                            (0, 2): "Ixz", (1, 2): "Iyz"}.items():
            I[i, j] = I[j, i] = _number(src, inertia, tag, "<inertia>")
        ref = inertia.get("ref", "com")
        if ref == "joint":  # parallel-axis theorem: about the joint origin -> about G
            I = I - mass * (float(com @ com) * np.eye(3) - np.outer(com, com))
            notes.append("inertia given about the joint origin, moved to the centre of mass.")
        elif ref != "com":
            raise InputError(f"{src}: <inertia ref={ref!r}> is neither 'com' nor 'joint'.")
        if np.linalg.eigvalsh(I)[0] <= 0:
            raise InputError(f"{src}: the inertia about the centre of mass is not positive "
                             "definite, so it cannot be a rigid body's.")
        plat["inertia"] = I.tolist()
    return plat, com, notes


def _workspace(link: ET.Element) -> dict:
    """The workspace box of P from the joint's translation bounds (empty when absent)."""
    joint = link.find("joint")
    lo, hi = joint.get("q_min"), joint.get("q_max")
    origin = link.findtext("parent/location")
    try:
        shift = np.array([float(x) for x in (origin or "0 0 0").split()])
        lo_v = np.array([float(x) for x in (lo or "").split()][:3])
        hi_v = np.array([float(x) for x in (hi or "").split()][:3])
    except ValueError:
        return {}
    if lo_v.shape != (3,) or hi_v.shape != (3,) or shift.shape != (3,) \
            or not np.all(hi_v > lo_v):
        return {}
    return {"workspace_min": (shift + lo_v).tolist(), "workspace_max": (shift + hi_v).tolist()}


def _cable_set(src: Path, root: ET.Element, cable_set: str | None) -> ET.Element:
    sets = {s.get("id"): s for s in root.findall("cable_set")}
    want = cable_set or root.get("default_cable_set")
    if want not in sets:
        raise InputError(f"{src}: no cable set {want!r}; the file has "
                         f"{', '.join(repr(k) for k in sets) or 'none'} (choose with "
                         "--cable-set).")
    return sets[want]


def _cable(src: Path, cab: ET.Element, com: np.ndarray) -> tuple[dict, float, float]:
    """One ``[[cable]]`` table and the cable's force limits."""
    name = cab.get("name", "?")
    if cab.tag != "cable_ideal":
        raise InputError(f"{src}: cable {name!r} is a <{cab.tag}> (elastic, spring or "
                         "variable-stiffness cable); cdprid models ideal cables only.")
    props = cab.find("properties")
    if props is None:
        raise InputError(f"{src}: cable {name!r} has no <properties> (force_min, force_max).")
    fmin = _number(src, props, "force_min", f"cable {name!r}")
    fmax = _number(src, props, "force_max", f"cable {name!r}")
    ref = cab.get("attachment_reference", "joint")
    if ref not in ("joint", "com"):
        raise InputError(f"{src}: cable {name!r} has attachment_reference={ref!r}, neither "
                         "'joint' nor 'com'.")
    atts = list(cab.find("attachments") if cab.find("attachments") is not None else [])
    if len(atts) != 2:
        raise InputError(f"{src}: cable {name!r} has {len(atts)} attachments; cdprid maps "
                         "cables from one base point (or pulley) to one platform point.")
    out: dict = {}
    for a in atts:
        if a.tag == "base_rotating_pulley":
            out["exit"] = _vector(src, a.find("fixed_location"),
                                  f"cable {name!r} <fixed_location>").tolist()
            r = _number(src, a, "pulley_radius", f"cable {name!r} pulley")
            k = _vector(src, a.find("cable_entry_vector"), f"cable {name!r} <cable_entry_vector>")
            if r < 0 or np.linalg.norm(k) == 0:
                raise InputError(f"{src}: cable {name!r}: the pulley needs a radius >= 0 and a "
                                 "non-zero cable_entry_vector.")
            if r > 0:
                out["pulley_radius"] = r
                out["pulley_axis"] = (k / np.linalg.norm(k)).tolist()
        elif a.tag == "attachment":
            link = (a.findtext("link") or "").strip()
            loc = _vector(src, a.find("location"), f"cable {name!r} attachment <location>")
            if link == "0":
                out["exit"] = loc.tolist()
            elif link == "1":
                out["anchor"] = (loc + com if ref == "com" else loc).tolist()
            else:
                raise InputError(f"{src}: cable {name!r} is attached to link {link!r}; only "
                                 "the ground (0) and the platform (1) exist.")
        else:
            raise InputError(f"{src}: cable {name!r} has a <{a.tag}> attachment (e.g. a "
                             "screw-drive pulley) that robot.toml cannot hold.")
    if "exit" not in out or "anchor" not in out:
        raise InputError(f"{src}: cable {name!r} must run from the ground (link 0 or a base "
                         "pulley) to the platform (link 1).")
    return {"exit": out.pop("exit"), "anchor": out.pop("anchor"), **out}, fmin, fmax


def read_caspr(bodies: str | Path, cables: str | Path, cable_set: str | None = None
               ) -> CasprImport:
    """Map a single-link spatial CASPR model to a robot.toml mapping (spec 1.1).

    Parameters
    ----------
    bodies : path
        CASPR ``*_bodies.xml`` (one ``link_rigid`` with a ``SPATIAL_*`` joint).
    cables : path
        CASPR ``*_cables.xml``.
    cable_set : str, optional
        The ``cable_set`` id; default the file's ``default_cable_set``.

    Returns
    -------
    CasprImport
        ``robot`` (the mapping; lengths in m, masses in kg, forces in N), the cable set and notes.

    Raises
    ------
    InputError
        One sentence naming the file and what cannot be mapped.
    """
    bodies, cables = Path(bodies), Path(cables)
    link = _link(bodies, _parse(bodies))
    plat, com, notes = _platform(bodies, link)
    root = _parse(cables)
    cset = _cable_set(cables, root, cable_set)
    rows = [_cable(cables, c, com) for c in cset]
    if len(rows) < 1:
        raise InputError(f"{cables}: cable set {cset.get('id')!r} has no cables.")
    fmins, fmaxs = [r[1] for r in rows], [r[2] for r in rows]
    limits: dict = {}
    tmin, tmax = max(fmins), min(fmaxs)
    if tmin >= 0 and tmax > tmin:
        limits = {"tension_min": tmin, "tension_max": tmax}
        if len(set(fmins)) > 1 or len(set(fmaxs)) > 1:
            notes.append(f"cables have different force limits; robot.toml holds one pair: the "
                         f"tightest, [{tmin:g}, {tmax:g}] N.")
    else:
        notes.append(f"force limits [{tmin:g}, {tmax:g}] N are not a valid tension range and "
                     "were dropped.")
    limits.update(_workspace(link))
    name = f"{link.get('name', bodies.stem)} (CASPR, cable set {cset.get('id')})"
    robot = {"name": name, "gravity": [0.0, 0.0, -9.81]}
    if limits:
        robot["limits"] = limits
    robot["cable"] = [r[0] for r in rows]
    robot["platform"] = plat
    return CasprImport(robot=robot, cable_set=str(cset.get("id")), notes=tuple(notes))
