"""Platform motion from measured poses: velocity, acceleration, angular rates.

Second step of the data path (dataset -> aligned signals -> **motion** -> regressor ->
estimate). Positions are differentiated channel by channel with any method of
:func:`cdprid.signal.differentiate`. For rotations the sign-continuous quaternion
components are differentiated and converted with
``omega = 2 vec(qd q*)``, ``alpha = 2 vec(qdd q*)`` (base frame).

A recording with gaps arrives as gap-free segments (``AlignedSignals.segments``); each is
differentiated on its own, so no derivative ever spans a gap, and :func:`segment_mask` trims the
samples near every segment edge exactly like the ends of the recording.
"""

# ruff: noqa: F722  (jaxtyping shape strings)
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import jax
import numpy as np
from jaxtyping import Float

from cdprid.base import cached_executable
from cdprid.io import AlignedSignals
from cdprid.model import angular_rates_from_quat, quat_to_matrix
from cdprid.signal import differentiate

__all__ = ["BLOCK", "Motion", "ROTATION_WARN_DEG", "angular_rates", "blockwise",
           "differentiate_pose", "estimate_motion", "rotation_angle_deg", "rotation_matrices",
           "segment_mask"]

BLOCK = 16384
"""Samples per jitted call when the per-sample rotation functions are evaluated block by block
(the same size as ``cdprid.core.CHUNK``): one block shape, so each function compiles once,
and only (BLOCK, ...) temporaries are alive at a time."""

_quat_to_matrix_jit = cached_executable(jax.jit(jax.vmap(quat_to_matrix)),
                                       name="core.quat_to_matrix_vmapped")
_angular_rates_jit = jax.jit(jax.vmap(angular_rates_from_quat))


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
    params : dict
        The differentiator's parameters (with ``method``: what :func:`differentiate_pose`
        needs to differentiate anything else the same way, e.g. noise replicates).
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
    params: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        if not self.segments:
            object.__setattr__(self, "segments", ((0, len(self.t)),))

    def keep(self, trim: float) -> np.ndarray:
        """The samples at least ``trim`` seconds from every segment edge.

        Parameters
        ----------
        trim : float
            Margin at both ends of each gap-free segment, s.

        Returns
        -------
        ndarray (n,) of bool
        """
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


def blockwise(fn: Callable, arrays: Sequence[np.ndarray], outs: Sequence[np.ndarray],
              block: int = BLOCK) -> None:
    """Evaluate a per-sample-vmapped ``fn`` over time in blocks of one fixed shape.

    ``outs[k][i] = fn(*arrays)[k][i]`` for every sample ``i``; ``fn`` sees ``block`` samples at a
    time (a shorter input or last block is padded by repeating its last sample, and the padding
    is dropped), so a jitted ``fn`` compiles once for any length and any number of segments, and
    holds only (block, ...) temporaries.

    Parameters
    ----------
    fn : callable
        Maps arrays of shape (block, ...) to a tuple of arrays of shape (block, ...).
    arrays : sequence of ndarray (n, ...)
        Inputs, numpy (sliced and padded on the host, so no eager JAX op is run).
    outs : sequence of ndarray (n, ...)
        Preallocated outputs, one per result of ``fn``, filled in place.
    block : int
        Samples per call.
    """
    n = len(arrays[0])
    c = max(1, int(block))
    for a in range(0, n, c):
        b = min(a + c, n)
        parts = [x[a:b] for x in arrays]
        if b - a < c:
            parts = [np.concatenate([x, np.repeat(x[-1:], c - (b - a), axis=0)]) for x in parts]
        for o, r in zip(outs, fn(*parts), strict=True):
            o[a:b] = np.asarray(r)[: b - a]


def rotation_matrices(q: Float[np.ndarray, "n 4"],
                      block: int = BLOCK) -> Float[np.ndarray, "n 3 3"]:
    """Rotation matrices of unit quaternions (``cdprid.model.quat_to_matrix`` per sample).

    Parameters
    ----------
    q : ndarray (n, 4)
        Quaternions ``[qw, qx, qy, qz]`` (normalised per sample).
    block : int
        Samples per jitted call (see :func:`blockwise`).

    Returns
    -------
    ndarray (n, 3, 3)
    """
    q = np.asarray(q, float)
    R = np.empty((len(q), 3, 3))
    if len(q):
        blockwise(lambda x: (_quat_to_matrix_jit(x),), (q,), (R,), block)
    return R


def angular_rates(q: Float[np.ndarray, "n 4"], qd: Float[np.ndarray, "n 4"],
                  qdd: Float[np.ndarray, "n 4"], block: int = BLOCK
                  ) -> tuple[Float[np.ndarray, "n 3"], Float[np.ndarray, "n 3"]]:
    """Angular velocity and acceleration (base frame) per sample from q and its derivatives.

    ``cdprid.model.angular_rates_from_quat`` per sample, jit-compiled and evaluated in blocks.

    Parameters
    ----------
    q, qd, qdd : ndarray (n, 4)
        Quaternion and its first and second time derivatives.
    block : int
        Samples per jitted call (see :func:`blockwise`).

    Returns
    -------
    omega, alpha : ndarray (n, 3)
    """
    arrays = tuple(np.asarray(x, float) for x in (q, qd, qdd))
    om, al = np.empty((len(arrays[0]), 3)), np.empty((len(arrays[0]), 3))
    if len(om):
        blockwise(_angular_rates_jit, arrays, (om, al), block)
    return om, al


def differentiate_pose(x, dt: float, segments=None, method: str = "euler-filtfilt",
                       params: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """First and second time derivatives of sampled channels, segment by segment.

    The differentiation :func:`estimate_motion` applies to positions and quaternions; the
    diagnosis passes its noise replicates through it with the motion's own ``method`` and
    ``params`` (:attr:`Motion.method`, :attr:`Motion.params`).

    Parameters
    ----------
    x : ndarray (n, k)
        Channels sampled every ``dt`` s.
    dt : float
        Sampling period, s.
    segments : sequence of (int, int), optional
        Half-open gap-free index ranges, each differentiated on its own (default: one).
    method : str
        A differentiator name (see ``cdprid.signal.METHODS``).
    params : dict, optional
        Its parameters.

    Returns
    -------
    xd, xdd : ndarray (n, k)
        Units of ``x`` per s and per s^2.
    """
    x = np.asarray(x, float)
    params = dict(params or {})
    xd, xdd = np.empty_like(x), np.empty_like(x)
    for i0, i1 in (segments or ((0, len(x)),)):
        d1, d2 = differentiate(x[i0:i1], dt, method=method, **params)
        xd[i0:i1], xdd[i0:i1] = np.asarray(d1), np.asarray(d2)
    return xd, xdd


def estimate_motion(sig: AlignedSignals, method: str = "euler-filtfilt", params: dict | None = None,
                    angular: bool = True) -> Motion:
    """Differentiate the aligned pose (each gap-free segment on its own).

    Parameters
    ----------
    sig : AlignedSignals
    method : str
        A differentiator name (see ``cdprid.signal.METHODS``).
    params : dict, optional
        Its parameters (e.g. ``{"cutoff_hz": 4.0}`` for ``"euler-filtfilt"``).
    angular : bool
        Also estimate omega and alpha from the quaternions (needed by the full model).

    Returns
    -------
    Motion
    """
    params = dict(params or {})
    segs = tuple(getattr(sig, "segments", ()) or ((0, len(sig.t)),))
    R = rotation_matrices(sig.quaternion)
    v, a = differentiate_pose(sig.position, sig.dt, segs, method, params)
    n = len(sig.t)
    om, al = np.zeros((n, 3)), np.zeros((n, 3))
    if angular and sig.has_rotation:
        qd, qdd = differentiate_pose(sig.quaternion, sig.dt, segs, method, params)
        for i0, i1 in segs:
            om[i0:i1], al[i0:i1] = angular_rates(sig.quaternion[i0:i1], qd[i0:i1], qdd[i0:i1])
    return Motion(sig.t, sig.position, v, a, R, om, al, method, segs, params)


ROTATION_WARN_DEG = 1.0
"""Rotation (99th percentile of the angle from the mean orientation, deg) above which the
translation model is a mismatch (its moment rows ignore I alpha and the rotating first moment)
and ``model="auto"`` picks the full model."""


def rotation_angle_deg(quaternion) -> float:
    """99th percentile of the rotation angle of each sample from the mean orientation.

    Parameters
    ----------
    quaternion : ndarray (n, 4)
        Unit quaternions (w, x, y, z); signs may flip between samples.

    Returns
    -------
    float
        Angle, deg.
    """
    q = np.asarray(quaternion, float)
    q = q * np.where(q @ q[0] < 0, -1.0, 1.0)[:, None]
    qm = q.mean(axis=0)
    qm = qm / np.linalg.norm(qm)
    c = np.clip(np.abs(q @ qm), 0.0, 1.0)
    return float(np.percentile(np.degrees(2.0 * np.arccos(c)), 99))
