"""Preset trajectories sized to a robot's workspace, and the workspace check."""

from __future__ import annotations

import numpy as np

from cdprid.base import InputError
from cdprid.model._trajectories import PRESETS, Orbit, Trajectory, TrajectoryState, orbit_sequence


def _centre_of(robot) -> np.ndarray:
    if robot is None or robot.limits.workspace_min is None or robot.limits.workspace_max is None:
        return np.array([0.0, 0.0, 1.2])
    lo = np.asarray(robot.limits.workspace_min)
    hi = np.asarray(robot.limits.workspace_max)
    c = 0.5 * (lo + hi)
    c[2] = float(np.clip(1.2, lo[2], hi[2]))
    return c


def _half_extent(robot, centre) -> float:
    if robot is None or robot.limits.workspace_min is None or robot.limits.workspace_max is None:
        return np.inf
    lo = np.asarray(robot.limits.workspace_min)
    hi = np.asarray(robot.limits.workspace_max)
    return float(np.min(np.minimum(centre - lo, hi - centre)))


def preset(
    name: str, robot=None, duration: float | None = None, rotation_amplitude: float = 0.0
) -> Trajectory:
    """A named trajectory, centred in the robot's workspace box.

    Parameters
    ----------
    name : {'paper-orbits', 'rich'}
        ``paper-orbits``: four ramped 0.25 Hz orbits in the xy, xz, yz and again xy planes
        (radii 0.4, 0.35, 0.35, 0.3 m), 52 s in total (paper section 7).
        ``rich``: six orbits at 0.2-0.6 Hz in six planes (radius decreasing with frequency),
        52 s, for diagnosis and identification of more parameters.
    robot : CableRobot, optional
        Its workspace box gives the centre (box centre in x, y; z = 1.2 m clipped into
        the box) and caps the radii at 90 % of the smallest half-extent, so the
        trajectory stays in the box.
    duration : float, optional
        Total time, s (default 52); segment durations are scaled to fit.
    rotation_amplitude : float
        Small rotation amplitude, rad (0: pure translation).

    Returns
    -------
    Trajectory
    """
    if name == "paper-orbits":
        spec = [  # (radius, freq, azimuth, tilt, phase)
            (0.40, 0.25, 0.0, 0.0, 0.0),
            (0.35, 0.25, 0.0, np.pi / 2, 0.0),
            (0.35, 0.25, np.pi / 2, np.pi / 2, 0.0),
            (0.30, 0.25, np.pi / 4, 0.0, np.pi / 2),
        ]
    elif name == "rich":
        spec = [
            (0.40, 0.20, 0.0, 0.0, 0.0),
            (0.30, 0.30, 0.0, np.pi / 2, 0.5),
            (0.25, 0.40, np.pi / 2, np.pi / 2, 1.0),
            (0.18, 0.50, np.pi / 4, np.pi / 3, 1.5),
            (0.12, 0.60, -np.pi / 4, 2 * np.pi / 3, 2.0),
            (0.20, 0.35, np.pi / 3, np.pi / 6, 2.5),
        ]
    else:
        raise InputError(
            f"unknown trajectory preset {name!r}; valid presets: {', '.join(PRESETS)}."
        )
    total = 52.0 if duration is None else float(duration)
    rests = 0.5
    n = len(spec)
    seg = (total - (n + 1) * rests) / n
    if not np.isfinite(seg) or seg < 2.0:
        raise InputError(
            f"duration {total:g} s is too short for the {name!r} preset (needs at least "
            f"{n * 2.0 + (n + 1) * rests:g} s)."
        )
    ramp = min(2.0, seg / 2)
    centre = _centre_of(robot)
    cap = 0.9 * _half_extent(robot, centre)
    orbits = [
        Orbit(min(r, cap), f, seg, azimuth=az, tilt=tl, phase=ph, ramp=ramp)
        for r, f, az, tl, ph in spec
    ]
    # |P - centre| <= radius <= 0.9 x the smallest half-extent: inside the box by construction
    return orbit_sequence(orbits, centre, rests, rests, rests, rotation_amplitude, name=name)


def check_workspace(
    traj, robot, rate_hz: float = 50.0, state: TrajectoryState | None = None
) -> None:
    """Raise ``ValueError`` (one sentence) if P leaves the robot's workspace box.

    Parameters
    ----------
    traj : Trajectory or SampledTrajectory
    robot : CableRobot
        Nothing is checked when its limits give no workspace box.
    rate_hz : float
        Checking rate.
    state : TrajectoryState, optional
        An evaluation to check instead of sampling ``traj`` at ``rate_hz``.
    """
    lo, hi = robot.limits.workspace_min, robot.limits.workspace_max
    if lo is None or hi is None:
        return
    if state is None:
        state = traj.evaluate(np.arange(traj.t_start, traj.t_end + 0.5 / rate_hz, 1.0 / rate_hz))
    t = np.asarray(state.t)
    p = np.asarray(state.p)
    bad = np.nonzero(np.any((p < np.asarray(lo) - 1e-9) | (p > np.asarray(hi) + 1e-9), axis=1))[0]
    if bad.size:
        k = int(bad[0])
        raise InputError(
            f"the trajectory leaves the workspace box {list(lo)}..{list(hi)} m at t = {t[k]:.3g} s "
            f"(P = [{p[k, 0]:.3f}, {p[k, 1]:.3f}, {p[k, 2]:.3f}] m)."
        )
