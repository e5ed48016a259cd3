"""Sample robots: the 8-cable CRAFT-like geometry and its default inertial truth.

The numbers are those of the shared synthetic dataset ``craft-sim-orbits/robot.toml``
(a CRAFT-like, synthetic geometry), written here so that nothing is read at runtime.
"""

from __future__ import annotations

from .dynamics import InertialParameters
from .geometry import CableRobot, robot_from_dict

__all__ = ["CRAFT_LIKE", "craft_like_robot", "craft_like_truth"]

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
