"""Sampled trajectories: quintic Hermite interpolation of samples with their derivatives."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.model._rotation_paths import Rotation, _identity, _rotation_state
from cdprid.model._rotations import quat_multiply
from cdprid.model._smoothstep import _derivs
from cdprid.model._trajectories import TrajectoryState, _evaluate_padded


def _hermite5(s, h, y0, d0, dd0, y1, d1, dd1):
    s2 = s * s
    s3 = s2 * s
    s4 = s3 * s
    s5 = s4 * s
    H0 = 1 - 10 * s3 + 15 * s4 - 6 * s5
    H1 = s - 6 * s3 + 8 * s4 - 3 * s5
    H2 = 0.5 * (s2 - 3 * s3 + 3 * s4 - s5)
    H3 = 10 * s3 - 15 * s4 + 6 * s5
    H4 = -4 * s3 + 7 * s4 - 3 * s5
    H5 = 0.5 * (s3 - 2 * s4 + s5)
    return H0 * y0 + H1 * h * d0 + H2 * h * h * dd0 + H3 * y1 + H4 * h * d1 + H5 * h * h * dd1


class SampledTrajectory(eqx.Module):
    """A trajectory given by samples (e.g. read from CSV); see the module docstring.

    Attributes
    ----------
    t : (n,)
    p, v, a : (n, 3)
    q : (n, 4) or None
    omega, alpha : (n, 3) or None
    rotation : Rotation or None
        An analytic rotation added by :func:`with_rotation` (only when q is None).
    """

    t: jnp.ndarray
    p: jnp.ndarray
    v: jnp.ndarray
    a: jnp.ndarray
    q: jnp.ndarray | None = None
    omega: jnp.ndarray | None = None
    alpha: jnp.ndarray | None = None
    rotation: Rotation | None = None
    name: str = eqx.field(static=True, default="sampled")

    @property
    def has_rotation(self) -> bool:
        """True when the platform rotates."""
        return self.q is not None or (
            self.rotation is not None and bool(np.any(np.asarray(self.rotation.amplitude) != 0))
        )

    @property
    def t_start(self) -> float:
        """First sample time, s."""
        return float(self.t[0])

    @property
    def t_end(self) -> float:
        """Last sample time, s."""
        return float(self.t[-1])

    @property
    def duration(self) -> float:
        """Last sample time, s."""
        return float(self.t[-1])

    def _segment(self, t):
        tc = jnp.clip(t, self.t[0], self.t[-1])
        k = jnp.clip(jnp.searchsorted(self.t, tc, side="right") - 1, 0, self.t.shape[0] - 2)
        h = self.t[k + 1] - self.t[k]
        return k, h, (tc - self.t[k]) / h

    def position(self, t):
        """Interpolated position at a scalar time t (quintic Hermite, clipped to the sampled span).

        Parameters
        ----------
        t : float
            Time, s.

        Returns
        -------
        array (3,)
            Position of P, base frame, m.
        """
        k, h, s = self._segment(t)
        return _hermite5(
            s, h, self.p[k], self.v[k], self.a[k], self.p[k + 1], self.v[k + 1], self.a[k + 1]
        )

    def quat(self, t):
        """Interpolated, renormalised quaternion at a scalar time t.

        Parameters
        ----------
        t : float
            Time, s.

        Returns
        -------
        array (4,)
            Unit quaternion, scalar first, platform -> base.
        """
        k, h, s = self._segment(t)

        def qdots(i):
            q = self.q[i]
            wq = jnp.concatenate([jnp.zeros(1), self.omega[i]])
            aq = jnp.concatenate([jnp.zeros(1), self.alpha[i]])
            qd = 0.5 * quat_multiply(wq, q)
            qdd = 0.5 * (quat_multiply(aq, q) + quat_multiply(wq, qd))
            return q, qd, qdd

        q0, d0, dd0 = qdots(k)
        q1, d1, dd1 = qdots(k + 1)
        q1 = jnp.where(q0 @ q1 < 0, -1.0, 1.0) * q1
        d1 = jnp.where(q0 @ self.q[k + 1] < 0, -1.0, 1.0) * d1
        dd1 = jnp.where(q0 @ self.q[k + 1] < 0, -1.0, 1.0) * dd1
        h_ = _hermite5(s, h, q0, d0, dd0, q1, d1, dd1)
        return h_ / jnp.linalg.norm(h_)

    def _one(self, t):
        p, v, a, j = _derivs(self.position, t, 3)
        if self.q is not None:
            q, w, al = _rotation_state(self.quat, t)
        elif self.rotation is not None:
            q, w, al = _rotation_state(self.rotation.quat, t)
        else:
            q, w, al = _identity()
        return p, v, a, j, q, w, al

    def evaluate(self, t) -> TrajectoryState:
        """Evaluate the motion at times t (exact at the sample times).

        Parameters
        ----------
        t : array (n,)

        Returns
        -------
        TrajectoryState
        """
        return _evaluate_padded(self, t)
