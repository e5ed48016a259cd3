"""``frame_tilt``: the pose frame is tilted relative to gravity (one module, one effect)."""

from __future__ import annotations

import numpy as np

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC", "tilt_matrix", "tilt_gravity"]


def tilt_matrix(rx: float, ry: float) -> np.ndarray:
    """``R_tilt = Ry(ry) Rx(rx)``: pose-frame vectors -> level frame.

    Parameters
    ----------
    rx, ry : float
        Tilt about x, then about the fixed y, rad.

    Returns
    -------
    ndarray (3, 3)
    """
    cx, sx, cy, sy = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry)
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    Ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    return Ry @ Rx


def tilt_gravity(g, tilt):
    """Gravity in the pose frame for a frame tilt ``[rx, ry]`` (JAX; see ``frame_tilt``).

    Parameters
    ----------
    g : (3,) gravity of robot.toml, m/s^2
    tilt : (2,) ``[rx, ry]``, rad

    Returns
    -------
    (3,) ``R_tilt^T g``, m/s^2
    """
    import jax.numpy as jnp

    rx, ry = tilt[0], tilt[1]
    cx, sx, cy, sy = jnp.cos(rx), jnp.sin(rx), jnp.cos(ry), jnp.sin(ry)
    Rx = jnp.array([[1.0, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = jnp.array([[cy, 0, sy], [0, 1.0, 0], [-sy, 0, cy]])
    return (Ry @ Rx).T @ g  # g_pose = R_tilt^T g, R_tilt = Ry(ry) Rx(rx)


SPEC = EffectSpec(
    name="frame_tilt",
    parameters=(Parameter("tilt_rad", "vec2", "rad"),),
    doc="""``frame_tilt {tilt_rad: [rx, ry]}``
    The pose frame (in which robot.toml and pose.csv are expressed) is tilted relative to
    gravity: with ``R_tilt = Ry(ry) Rx(rx)`` (about x first, then about the fixed y) mapping
    pose-frame vectors to the level frame, the plant's gravity in the pose frame is
    ``g_pose = R_tilt^T g`` with g robot.toml's gravity (for g = [0, 0, -9.81]:
    ``g_pose = 9.81 [sin ry, -sin rx cos ry, -cos rx cos ry]``); robot.toml keeps the
    nominal g.""",
    place=Place.GRAVITY, once=True,
    gravity=lambda g, p: tilt_matrix(*p["tilt_rad"]).T @ g,
    diagnosis=DiagnosisForm(
        blocks=(("tilt", 2),), keys=("tilt_rad",), bounds={"tilt_rad": 0.05},
        gravity=lambda g, q: tilt_gravity(g, q["tilt"])),
)
