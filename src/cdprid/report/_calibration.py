"""Figures of the geometric calibration (:mod:`cdprid.identify._calibration`)."""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

from cdprid.base import save_figure
from cdprid.identify import CalibrationData, CalibrationResult, platform_pose
from cdprid.model import CableRobot, cable_lengths, swivel_angles

__all__ = ["calibration_figures"]


def calibration_figures(robot: CableRobot, data: CalibrationData, result: CalibrationResult,
                        folder, force: bool = True) -> list[Path]:
    """Sanity figures: length and swivel residuals over time, after the calibration.

    Parameters
    ----------
    robot : CableRobot
    data : CalibrationData
    result : CalibrationResult
    folder : path
        Created if missing.
    force : bool
        Replace existing figures.

    Returns
    -------
    list of Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    B_R_P, B_p_P = platform_pose(result, data.V_R_M, data.V_p_M)
    rob = robot if result.M_R_P is not None else robot.replace(P_b=result.M_b)
    L = np.asarray(jax.vmap(lambda p, R: cable_lengths(rob, p, R))(B_p_P, B_R_P))
    psi = np.asarray(jax.vmap(lambda p, R: swivel_angles(rob, p, R))(B_p_P, B_R_P))
    m = robot.n_cables
    fig, ax = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for i in range(m):
        ax[0].plot(data.t, 1e3 * (L[:, i] - result.lengths[i]), lw=0.7, label=f"cable {i + 1}")
    ax[0].set_ylabel("length - L_i, mm")
    ax[0].legend(ncol=m, fontsize=8)
    if data.swivel is not None:
        for i in range(m):
            d = result.swivel_sign * (psi[:, i] - result.swivel_offset[i]) - data.swivel[:, i]
            ax[1].plot(data.t, 1e3 * np.arctan2(np.sin(d), np.cos(d)), lw=0.7)
    ax[1].set_ylabel("swivel residual, mrad")
    ax[1].set_xlabel("t, s")
    fig.suptitle(f"geometric calibration ({result.anchors} anchors): residuals")
    fig.tight_layout()
    p1 = save_figure(fig, folder / "calibration_residuals.png", force=force, dpi=110)
    plt.close(fig)
    return [p1]
