"""Sample robots: the 8-cable CRAFT-like geometry and its default inertial truth.

The numbers are those of the shared synthetic dataset ``craft-sim-orbits/robot.toml``
(a CRAFT-like, synthetic geometry), written here so that nothing is read at runtime.
"""

from __future__ import annotations

import math

from cdprid.model._dynamics import InertialParameters
from cdprid.model._geometry import CableRobot, robot_from_dict

__all__ = [
    "CRAFT_LIKE", "EIGHT_REDUNDANT", "FOUR_POINT", "SIX_SUSPENDED", "SIX_TIGHT", "SMALL_EIGHT",
    "craft_like_robot",
    "craft_like_truth",
]

#: robot.toml mapping (spec v1) of the CRAFT-like robot.
CRAFT_LIKE: dict = {
    "name": "craft-like",
    "gravity": [0.0, 0.0, -9.81],
    "limits": {
        "tension_min": 1.0,
        "tension_max": 150.0,
        "cable_speed_max": 5.9,
        "workspace_min": [-1.4, -1.2, 0.4],
        "workspace_max": [1.4, 1.2, 2.2],
    },
    "cable": [
        {"exit": [-1.90, -1.70, 2.60], "anchor": [0.14, -0.14, -0.10]},
        {"exit": [-1.95, -1.62, 2.60], "anchor": [-0.14, 0.10, 0.10]},
        {"exit": [-1.95, 1.62, 2.60], "anchor": [-0.14, -0.08, -0.10]},
        {"exit": [-1.90, 1.70, 2.60], "anchor": [0.14, 0.10, 0.10]},
        {"exit": [1.90, 1.70, 2.60], "anchor": [-0.14, 0.14, -0.10]},
        {"exit": [1.95, 1.62, 2.60], "anchor": [0.14, -0.10, 0.10]},
        {"exit": [1.95, -1.62, 2.60], "anchor": [0.14, 0.08, -0.10]},
        {"exit": [1.90, -1.70, 2.60], "anchor": [-0.14, -0.10, 0.10]},
    ],
    "platform": {
        "mass": 9.88,
        "com": [-0.00647773, 0.00192308, -0.107186],
        "inertia": [[0.12, 0.0, 0.0], [0.0, 0.12, 0.0], [0.0, 0.0, 0.10]],
    },
}

SMALL_EIGHT: dict = {
    "name": "small-8",
    "limits": {"tension_min": 2.0, "tension_max": 80.0, "cable_speed_max": 1.0,
               "workspace_min": [-0.4, -0.35, 0.6], "workspace_max": [0.4, 0.35, 1.05],
               "acceleration_max": 1.5, "jerk_max": 8.0, "tilt_max": 0.15,
               "angular_velocity_max": 0.6, "angular_acceleration_max": 2.0,
               "cable_clearance": 0.01},
    "cable": [
        {"exit": [-1.14, -1.02, 1.82], "anchor": [0.098, -0.098, -0.07]},
        {"exit": [-1.17, -0.97, 1.82], "anchor": [-0.098, 0.07, 0.07]},
        {"exit": [-1.17, 0.97, 1.82], "anchor": [-0.098, -0.056, -0.07]},
        {"exit": [-1.14, 1.02, 1.82], "anchor": [0.098, 0.07, 0.07]},
        {"exit": [1.14, 1.02, 1.82], "anchor": [-0.098, 0.098, -0.07]},
        {"exit": [1.17, 0.97, 1.82], "anchor": [0.098, -0.07, 0.07]},
        {"exit": [1.17, -0.97, 1.82], "anchor": [0.098, 0.056, -0.07]},
        {"exit": [1.14, -1.02, 1.82], "anchor": [-0.098, -0.07, 0.07]},
    ],
    "platform": {"mass": 4.3, "com": [0.0, 0.0, -0.02],
                 "inertia": [[0.03, 0.0, 0.0], [0.0, 0.03, 0.0], [0.0, 0.0, 0.04]],
                 "mass_uncertainty": 0.2, "com_uncertainty": 0.02, "inertia_uncertainty": 0.3,
                 "body_min": [-0.11, -0.11, -0.08], "body_max": [0.11, 0.11, 0.08]},
}
"""An 8-cable robot (the CRAFT-like layout scaled by 0.6) with a small workspace, tight spec 1.1
limits and an uncertain 4.3 kg platform with a body box: the sample robot of the excitation
tests and benchmark (``cdprid.model.robot_from_dict(SMALL_EIGHT)``)."""


def _hexa(R: float, z: float) -> list:
    """Six points on a circle of radius R at height z, 60 degrees apart."""
    return [[R * math.cos(k * math.pi / 3), R * math.sin(k * math.pi / 3), z] for k in range(6)]


_EX, _AN = _hexa(2.0, 3.0), _hexa(0.15, 0.1)
SIX_SUSPENDED = {  # 6 cables, no redundancy, suspended (gravity keeps the cables taut)
    "name": "six-suspended", "gravity": [0.0, 0.0, -9.81],
    "limits": {"tension_min": 1.0, "tension_max": 300.0},
    "cable": [{"exit": _EX[k], "anchor": _AN[(k + 1) % 6 if k % 2 == 0 else (k - 1) % 6]}
              for k in range(6)],
}
_BOX = ((1, 1), (-1, 1), (-1, -1), (1, -1))
EIGHT_REDUNDANT = {  # 8 cables, fully constrained, crossed anchors
    "name": "eight-redundant", "gravity": [0.0, 0.0, -9.81],
    "limits": {"tension_min": 1.0, "tension_max": 5000.0},
    "cable": [{"exit": [1.6 * sx, 1.3 * sy, 2.8],
               "anchor": [0.12 * _BOX[(k + 1) % 4][0], 0.1 * _BOX[(k + 1) % 4][1], 0.08]}
              for k, (sx, sy) in enumerate(_BOX)]
    + [{"exit": [1.6 * sx, 1.3 * sy, 0.0],
        "anchor": [0.12 * _BOX[(k + 3) % 4][0], 0.1 * _BOX[(k + 3) % 4][1], -0.08]}
       for k, (sx, sy) in enumerate(_BOX)],
}
"""Sample robots other than the CRAFT-like one (robot.toml dicts): a 6-cable suspended robot
without redundancy and an 8-cable fully constrained one (coverage tests and benchmark)."""


def craft_like_robot() -> CableRobot:
    """The 8-cable CRAFT-like robot (synthetic geometry, no pulleys).

    Returns
    -------
    CableRobot
        Exit points on a 3.8 m x 3.4 m frame at z = 2.6 m, attachments on a
        0.28 m x 0.28 m x 0.2 m platform, limits 1-150 N, workspace box
        [-1.4, 1.4] x [-1.2, 1.2] x [0.4, 2.2] m.

    Examples
    --------
    >>> craft_like_robot().n_cables
    8
    """
    return robot_from_dict(CRAFT_LIKE, source="craft_like_robot()")


def craft_like_truth() -> InertialParameters:
    """Default inertial truth of the CRAFT-like platform used by the simulator.

    Returns
    -------
    InertialParameters
        mass 9.88 kg, com [-0.00647773, 0.00192308, -0.107186] m (platform frame),
        inertia about the centre of mass diag(0.12, 0.12, 0.10) kg m^2.
    """
    p = CRAFT_LIKE["platform"]
    return InertialParameters(p["mass"], p["com"], p["inertia"])

FOUR_POINT: dict = {  # suspended point-mass robot: 4 cables meeting at P, com at P
    "name": "four-point",
    "limits": {"tension_min": 2.0, "tension_max": 60.0, "cable_speed_max": 0.8,
               "workspace_min": [-0.35, -0.3, 0.5], "workspace_max": [0.35, 0.3, 0.9],
               "acceleration_max": 1.2, "jerk_max": 6.0, "cable_clearance": 0.01},
    "cable": [{"exit": [x, y, 1.8], "anchor": [0.0, 0.0, 0.0]}
              for x, y in ((1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0))],
    "platform": {"mass": 3.0, "com": [0.0, 0.0, 0.0], "inertia": [[1.0, 0.0, 0.0],
                                                                  [0.0, 1.0, 0.0],
                                                                  [0.0, 0.0, 1.0]],
                 "mass_uncertainty": 0.2, "com_uncertainty": 0.0},
}
"""A 4-cable suspended point-mass robot (all cables meet at P, the centre of mass is at P and
known: with 4 cables no moment can be balanced), tight limits, mass +- 20 %: translation only."""

_EX6 = [[1.1 * math.cos(math.radians(a)), 1.1 * math.sin(math.radians(a)), 2.0]
        for a in (-15, 15, 105, 135, 225, 255)]
_AN6 = [[0.2 * math.cos(math.radians(a)), 0.2 * math.sin(math.radians(a)), 0.06]
        for a in (-45, 45, 75, 165, 195, 285)]
SIX_TIGHT: dict = {
    "name": "six-tight",
    "limits": {"tension_min": 1.0, "tension_max": 120.0, "cable_speed_max": 1.0,
               "workspace_min": [-0.4, -0.35, 0.5], "workspace_max": [0.4, 0.35, 0.95],
               "acceleration_max": 1.5, "jerk_max": 10.0, "tilt_max": 0.2,
               "angular_velocity_max": 0.8, "angular_acceleration_max": 3.0,
               "cable_clearance": 0.01},
    "cable": [{"exit": _EX6[k], "anchor": _AN6[k]} for k in range(6)],
    "platform": {"mass": 6.0, "com": [0.0, 0.0, -0.03],
                 "inertia": [[0.03, 0.0, 0.0], [0.0, 0.03, 0.0], [0.0, 0.0, 0.04]],
                 "mass_uncertainty": 0.2, "com_uncertainty": 0.01, "inertia_uncertainty": 0.3,
                 "body_min": [-0.12, -0.12, -0.1], "body_max": [0.12, 0.12, 0.04]},
}
"""A 6-cable suspended robot (no redundancy) with the issue's small workspace (0.8 x 0.7 x
0.45 m), 1 m/s cable speed, tight spec 1.1 limits and an uncertain 6 kg platform with a body
box: an excitation test robot with 6 cables."""

FOUR_SUSPENDED = {  # 4 cables meeting at one point of the platform (a point mass), suspended
    "name": "four-suspended", "gravity": [0.0, 0.0, -9.81],
    "limits": {"tension_min": 1.0, "tension_max": 300.0,
               "workspace_min": [-0.6, -0.5, 0.8], "workspace_max": [0.6, 0.5, 1.8]},
    "cable": [{"exit": [1.6 * sx, 1.4 * sy, 2.8], "anchor": [0.0, 0.0, 0.0]}
              for sx, sy in _BOX],
    "platform": {"mass": 6.0, "com": [0.0, 0.0, 0.0],
                 "inertia": [[0.05, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 0.05]]},
}
"""A 4-cable suspended robot (robot.toml dict): exits at the corners of a 3.2 m x 2.8 m frame at
z = 2.8 m, every cable attached at the platform's centre of mass (no moments: a point mass that
gravity keeps taut; translation only): like FOUR_POINT but with a workspace and tension range
that the 52 s `rich` diagnosis trajectory fits in. Diagnosis benchmark and tests."""
__all__ += ["FOUR_SUSPENDED"]
