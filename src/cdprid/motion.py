"""Platform motion from measured poses: velocity, acceleration, angular rates.

Second step of the data path (dataset -> aligned signals -> **motion** -> regressor ->
estimate). Positions are differentiated channel by channel with any method of
:func:`cdprid.differentiators.differentiate`. For rotations the sign-continuous quaternion
components are differentiated and converted with
``omega = 2 vec(qd q*)``, ``alpha = 2 vec(qdd q*)`` (base frame).

A recording with gaps arrives as gap-free segments (``AlignedSignals.segments``); each is
differentiated on its own, so no derivative ever spans a gap, and :func:`segment_mask` trims the
samples near every segment edge exactly like the ends of the recording.
"""

from __future__ import annotations

import dataclasses

import jax
import numpy as np

from .differentiators import differentiate
from .io.dataset import AlignedSignals
from .rotations import angular_rates_from_quat, quat_to_matrix

__all__ = ["Motion", "estimate_motion", "segment_mask"]


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
    segments : tuple of (int, int)
        Half-open index ranges of the gap-free segments, each differentiated separately.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    B_R_P: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray
    method: str
    segments: tuple = ()

    def __post_init__(self):
        if not self.segments:
            object.__setattr__(self, "segments", ((0, len(self.t)),))

    def keep(self, trim: float) -> np.ndarray:
        """Boolean mask of the samples at least ``trim`` seconds from every segment edge."""
        return segment_mask(self.t, self.segments, trim)


def segment_mask(t, segments, trim: float) -> np.ndarray:
    """Samples at least ``trim`` seconds from both edges of their gap-free segment.

    Parameters
    ----------
    t : ndarray (n,)
        Sample times, s.
    segments : sequence of (int, int)
        Half-open index ranges of the segments (``AlignedSignals.segments``).
    trim : float
        Seconds dropped at both edges of every segment (differentiator transients).

    Returns
    -------
    ndarray (n,) of bool
    """
    t = np.asarray(t, float)
    keep = np.zeros(len(t), bool)
    for a, b in segments:
        ts = t[a:b]
        keep[a:b] = (ts >= ts[0] + trim) & (ts <= ts[-1] - trim)
    return keep


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
    segs = tuple(getattr(sig, "segments", ()) or ((0, len(sig.t)),))
    R = np.asarray(jax.vmap(quat_to_matrix)(sig.quaternion))
    rot = angular and sig.has_rotation
    n = len(sig.t)
    v, a = np.empty((n, 3)), np.empty((n, 3))
    om, al = np.zeros((n, 3)), np.zeros((n, 3))
    for i0, i1 in segs:
        vs, as_ = differentiate(sig.position[i0:i1], sig.dt, method=method, **params)
        v[i0:i1], a[i0:i1] = np.asarray(vs), np.asarray(as_)
        if rot:
            q = sig.quaternion[i0:i1]
            qd, qdd = differentiate(q, sig.dt, method=method, **params)
            o, al_ = jax.vmap(angular_rates_from_quat)(q, qd, qdd)
            om[i0:i1], al[i0:i1] = np.asarray(o), np.asarray(al_)
    return Motion(sig.t, sig.position, v, a, R, om, al, method, segs)
