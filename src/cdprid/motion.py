"""Platform motion from measured poses: velocity, acceleration, angular rates.

Second step of the data path (dataset -> aligned signals -> **motion** -> regressor ->
estimate). Positions are differentiated channel by channel with any method of
:func:`cdprid.differentiators.differentiate`. For rotations the sign-continuous quaternion
components are differentiated and converted with
``omega = 2 vec(qd q*)``, ``alpha = 2 vec(qdd q*)`` (base frame).
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np

from .differentiators import differentiate
from .io.dataset import AlignedSignals
from .rotations import angular_rates_from_quat, quat_to_matrix

__all__ = ["Motion", "estimate_motion"]


@dataclasses.dataclass(frozen=True)
class Motion:
    """Kinematics of the platform on the aligned time base (all base frame).

    Attributes
    ----------
    t, position, velocity, acceleration : ndarrays (n,), (n, 3) x3
    B_R_P : ndarray (n, 3, 3)
    omega, alpha : ndarray (n, 3)
        Angular velocity and acceleration (zeros when the dataset has no rotation).
    method : str
        Differentiator used.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    B_R_P: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    method: str


def estimate_motion(sig: AlignedSignals, method: str = "euler-filtfilt", params: dict | None = None,
                    angular: bool = True) -> Motion:
    """Differentiate the aligned pose.

    Parameters
    ----------
    sig : AlignedSignals
    method : str
        A differentiator name (see ``cdprid.differentiators.METHODS``).
    params : dict, optional
        Its parameters.
    angular : bool
        Also estimate omega and alpha from the quaternions (needed by the full model).
    """
    params = dict(params or {})
    v, a = differentiate(sig.position, sig.dt, method=method, **params)
    R = np.asarray(jax.vmap(quat_to_matrix)(sig.quaternion))
    n = len(sig.t)
    if angular and sig.has_rotation:
        qd, qdd = differentiate(sig.quaternion, sig.dt, method=method, **params)
        om, al = jax.vmap(angular_rates_from_quat)(sig.quaternion, qd, qdd)
        om, al = np.asarray(om), np.asarray(al)
    else:
        om = np.zeros((n, 3))
        al = np.zeros((n, 3))
    return Motion(sig.t, sig.position, np.asarray(v), np.asarray(a), R, om, al, method)
