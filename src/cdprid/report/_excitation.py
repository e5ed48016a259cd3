"""Figures of ``cdprid excite``: the 3-D path and the time series a robot owner checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_trajectory", "plot_safety_series"]


def _box_edges(ax, lo, hi):
    for i in range(8):
        for j in range(i + 1, 8):
            a = np.array([(hi if (i >> k) & 1 else lo)[k] for k in range(3)])
            b = np.array([(hi if (j >> k) & 1 else lo)[k] for k in range(3)])
            if np.sum(a != b) == 1:
                ax.plot(*zip(a, b, strict=True), color="0.7", lw=0.8)


def plot_trajectory(robot, traj, path, initial=None, title: str = "", n_cables_at: int = 4,
                    box=None, force: bool = True):
    """3-D figure of a trajectory inside the robot: exit points, cables, workspace box.

    Parameters
    ----------
    robot : CableRobot
    traj : trajectory-like (``evaluate``, ``t_start``, ``t_end``)
    path : str or Path
        PNG file written (atomically).
    initial : trajectory-like, optional
        Drawn dashed for comparison.
    n_cables_at : int
        Number of instants at which the cables are drawn.
    box : (lo, hi), optional
        Workspace box drawn (default: robot.toml's, if any), m.
    title : str
        Figure title.
    force : bool
        Replace an existing file.

    Returns
    -------
    Path
        The PNG written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cdprid.base import save_figure
    from cdprid.model import leave_points, quat_to_matrix

    t = np.linspace(traj.t_start, traj.t_end, 1500)
    s = traj.evaluate(t)
    p = np.asarray(s.p)
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection="3d")
    A = np.asarray(robot.B_A)
    ax.scatter(A[:, 0], A[:, 1], A[:, 2], c="k", marker="^", label="exit points")
    lim = robot.limits
    if box is None and lim.workspace_min is not None and lim.workspace_max is not None:
        box = (lim.workspace_min, lim.workspace_max)
    if box is not None:
        _box_edges(ax, np.asarray(box[0]), np.asarray(box[1]))
    if initial is not None:
        pi = np.asarray(initial.evaluate(np.linspace(initial.t_start, initial.t_end, 1500)).p)
        ax.plot(pi[:, 0], pi[:, 1], pi[:, 2], "--", color="tab:gray", lw=1, label="initial")
    ax.plot(p[:, 0], p[:, 1], p[:, 2], color="tab:blue", lw=1.2, label="optimised")
    P_b = np.asarray(robot.P_b)
    for k, idx in enumerate(np.linspace(0, len(t) - 1, n_cables_at + 2).astype(int)[1:-1]):
        R = np.asarray(quat_to_matrix(s.q[idx]))
        T = np.asarray(leave_points(robot, s.p[idx], R))
        Bw = p[idx] + P_b @ R.T
        for i in range(robot.n_cables):
            ax.plot(*zip(Bw[i], T[i], strict=True), color=f"C{1 + k}", lw=0.6)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(title or "excitation trajectory")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    out = save_figure(fig, Path(path), force=force, dpi=110)
    plt.close(fig)
    return out


def plot_safety_series(series, limits, path, title: str = "", force: bool = True):
    """Time series a robot owner checks before pressing go, each with its limit.

    Panels: tensions (nominal platform, centred distribution) and the worst tension margin over
    the uncertainty box; cable speeds; acceleration and jerk of P; tilt and angular velocity;
    cable-cable and cable-body clearance.

    Parameters
    ----------
    series : cdprid.excitation._check.SafetySeries
    limits : cdprid.excitation._safety.SafetyLimits
    path : str or Path
        PNG file written (atomically).
    title : str
        Figure title.
    force : bool
        Replace an existing file.

    Returns
    -------
    Path
        The PNG written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cdprid.base import save_figure

    t = series.t
    fig, axs = plt.subplots(5, 1, figsize=(9, 12), sharex=True)
    ax = axs[0]
    ax.plot(t, series.tension_nominal, lw=0.8)
    ax.axhline(limits.tension_min, color="r", ls="--", lw=1, label="tension limits")
    ax.axhline(limits.tension_max, color="r", ls="--", lw=1)
    ax.plot(t, limits.tension_min + series.margin.min(axis=0), color="k", lw=1.2,
            label="tension_min + worst margin over the uncertainty box")
    ax.set_ylabel("tension (N)")
    ax.legend(fontsize=7, loc="upper right")
    ax = axs[1]
    ax.plot(t, series.cable_speed, lw=0.8)
    ax.axhline(limits.cable_speed_max, color="r", ls="--", lw=1)
    ax.set_ylabel("|cable speed| (m/s)")
    ax = axs[2]
    ax.plot(t, series.acceleration, color="C0", label="|a| (m/s^2)")
    ax.axhline(limits.acceleration_max, color="C0", ls="--", lw=1)
    ax.plot(t, series.jerk / 10.0, color="C1", label="|jerk| / 10 (m/s^3)")
    ax.axhline(limits.jerk_max / 10.0, color="C1", ls="--", lw=1)
    ax.legend(fontsize=7, loc="upper right")
    ax = axs[3]
    ax.plot(t, series.tilt, color="C0", label="tilt (rad)")
    ax.axhline(limits.tilt_max, color="C0", ls="--", lw=1)
    ax.plot(t, series.angular_velocity, color="C1", label="|omega| (rad/s)")
    ax.axhline(limits.angular_velocity_max, color="C1", ls="--", lw=1)
    ax.legend(fontsize=7, loc="upper right")
    ax = axs[4]
    if series.cable_cable.size:
        ax.plot(t, series.cable_cable.min(axis=1), color="C0", label="cable-cable (m)")
    if series.cable_body is not None:
        ax.plot(t, series.cable_body.min(axis=1), color="C1", label="cable-body (m)")
    ax.axhline(limits.cable_clearance, color="r", ls="--", lw=1, label="clearance limit")
    ax.set_yscale("log")
    ax.set_ylabel("least distance (m)")
    ax.set_xlabel("t (s)")
    ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(title or "excitation trajectory: checked quantities (dashed: limits)")
    fig.tight_layout()
    out = save_figure(fig, Path(path), force=force, dpi=100)
    plt.close(fig)
    return out
