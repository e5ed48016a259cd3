"""The test robots: a large suspended 8-cable robot with floor winches, and 4- and 6-cable ones.

``floor8``: a 6 x 4 x 3 m frame; the winches stand on the floor at the four columns and
each cable runs up its column (``pulley_axis = [0, 0, 1]``) to one of two swivel pulleys at
the top corner (radii 5.5-6.5 cm), over which it wraps 100-130 deg down to the platform;
the attachments are crossed (a cable from the +x side holds the platform's -x side); a
24.6 kg platform whose robot.toml says 23.8 kg (3 % less).
``four_point``: 4 cables from above to one point (a point mass, no rotation), pulleys fed
from above. ``six_suspended``: 6 cables from above, pulleys fed from below, rotating.
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class Robot:
    """A test robot: geometry (truth), platform (truth and nominal), workspace."""

    name: str
    A: np.ndarray  # (m, 3) exit points, base frame
    k: np.ndarray  # (m, 3) swivel axes (the way the cable runs in)
    r: np.ndarray  # (m,) pulley radii
    b: np.ndarray  # (m, 3) attachments, platform frame
    mass: float
    com: np.ndarray  # s_G, platform frame
    inertia_G: np.ndarray  # about G, platform frame
    nominal_mass: float
    center: np.ndarray  # workspace centre of P
    half_range: np.ndarray  # amplitude budget per axis
    max_angle_rad: float  # 0: no rotation (point mass)
    tension_ref: float  # the tension every cable is distributed about, N
    gravity: np.ndarray = dataclasses.field(default_factory=lambda: np.array([0, 0, -9.81]))

    @property
    def m(self) -> int:
        """Number of cables."""
        return len(self.r)

    def toml(self, A=None) -> dict:
        """robot.toml as a dict (nominal: ``A`` may replace the true exit points)."""
        A = self.A if A is None else A
        cables = [{"exit": [float(z) for z in A[i]], "anchor": [float(z) for z in self.b[i]],
                   "pulley_radius": float(self.r[i]),
                   "pulley_axis": [float(z) for z in self.k[i]]} for i in range(self.m)]
        return {"name": self.name, "gravity": [float(z) for z in self.gravity],
                "limits": {"tension_min": 1.0, "tension_max": 2000.0},
                "platform": {"mass": self.nominal_mass, "mass_uncertainty": 0.1},
                "cable": cables}


def floor8() -> Robot:
    """The large suspended 8-cable robot with floor winches (module docstring)."""
    A, b, r = [], [], []
    radii = [0.055, 0.060, 0.065, 0.058, 0.062, 0.056, 0.064, 0.059]
    corners = [(1, 1), (-1, 1), (-1, -1), (1, -1)]
    for c, (sx, sy) in enumerate(corners):
        # two pulleys per top corner, 15 cm apart along the long edge
        A += [[sx * 2.95, sy * 1.95, 2.90], [sx * 2.80, sy * 1.95, 2.90]]
        # crossed attachments: the outer pulley holds the platform's far x side at the top,
        # the inner one the far y side at the bottom
        b += [[-sx * 0.25, sy * 0.18, 0.12], [sx * 0.22, -sy * 0.16, -0.12]]
        r += radii[2 * c:2 * c + 2]
    I = np.diag([0.9, 1.2, 1.5]) + 0.05 * (np.ones((3, 3)) - np.eye(3))
    return Robot("floor8", np.array(A), np.tile([0.0, 0.0, 1.0], (8, 1)), np.array(r),
                 np.array(b), 24.6, np.array([0.012, -0.008, -0.07]), I, 23.8,
                 np.array([0.0, 0.0, 1.25]), np.array([1.2, 0.75, 0.4]), np.deg2rad(5.0),
                 100.0)


def four_point() -> Robot:
    """4 cables from above to one point: a suspended point mass (redundant in 3 DOF)."""
    A = np.array([[1.5, 1.2, 2.2], [-1.5, 1.2, 2.2], [-1.5, -1.2, 2.2], [1.5, -1.2, 2.2]])
    return Robot("four_point", A, np.tile([0.0, 0.0, -1.0], (4, 1)), np.full(4, 0.03),
                 np.zeros((4, 3)), 8.0, np.zeros(3), 0.01 * np.eye(3), 8.2,
                 np.array([0.0, 0.0, 1.0]), np.array([0.9, 0.7, 0.3]), 0.0, 22.0)


def six_suspended() -> Robot:
    """6 cables from three top pairs, pulleys fed from below, rotating platform."""
    A, b = [], []
    for j in range(3):
        th = 2 * np.pi * j / 3
        c, s = np.cos(th), np.sin(th)
        t = np.array([-s, c])
        for sg in (1, -1):
            xy = 2.0 * np.array([c, s]) + sg * 0.12 * t
            A.append([xy[0], xy[1], 2.5])
            b.append([0.2 * np.cos(th + sg * 0.6), 0.2 * np.sin(th + sg * 0.6), 0.1])
    return Robot("six_suspended", np.array(A), np.tile([0.0, 0.0, 1.0], (6, 1)),
                 np.full(6, 0.04), np.array(b), 12.0, np.array([0.005, 0.0, -0.08]),
                 np.diag([0.3, 0.3, 0.4]), 12.3, np.array([0.0, 0.0, 1.1]),
                 np.array([0.5, 0.5, 0.25]), np.deg2rad(4.0), 0.0)


ROBOTS = {"floor8": floor8, "four_point": four_point, "six_suspended": six_suspended}


def robot(name: str) -> Robot:
    """A test robot by name (see :data:`ROBOTS`)."""
    return ROBOTS[name]()
