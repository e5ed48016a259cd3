"""The stacked regression ``Y_ID = W_ID x + rho`` (eq. 11) from motion and tensions.

Per sample: ``W`` (eq. 2) at the measured pose, ``y = W tau`` (the measured cable wrench),
and the regressor ``A`` (eq. 10 or the full 10-parameter one) from the motion estimate.
Both are built by per-sample functions vmapped over time.

Matched filtering: when the accelerations come from a zero-phase low-pass (the paper's
Euler + 4 Hz recipe), the regressor sees the filter through the accelerations; applying the
same filter to ``W tau`` keeps both sides of the equation on the same footing (filtering one
side only creates a spurious residual correlated with the motion).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .dynamics import regressor
from .geometry import CableRobot, wrench_matrix
from .motion import Motion

__all__ = [
    "Regression", "build_regression", "cable_wrench", "measured_wrench", "regressors",
    "wrench_matrices",
]


@dataclasses.dataclass(frozen=True)
class Regression:
    """Per-sample regressors and measured wrenches.

    Attributes
    ----------
    t : ndarray (n,)
    A : ndarray (n, 6, p)
        Regressor per sample.
    y : ndarray (n, 6)
        Measured wrench ``W tau`` per sample (after the matched filter, if any).
    model : str
    """

    t: np.ndarray
    A: np.ndarray
    y: np.ndarray
    model: str

    @property
    def W_ID(self) -> np.ndarray:
        """Stacked regressor (6 n, p)."""
        return self.A.reshape(-1, self.A.shape[-1])

    @property
    def Y_ID(self) -> np.ndarray:
        """Stacked wrenches (6 n,)."""
        return self.y.reshape(-1)

    @property
    def groups(self) -> np.ndarray:
        """Row group per stacked row: 0 force, 1 moment."""
        return np.tile(np.array([0, 0, 0, 1, 1, 1]), len(self.t))

    def select(self, mask) -> Regression:
        """The samples where ``mask`` is True."""
        return Regression(self.t[mask], self.A[mask], self.y[mask], self.model)


def wrench_matrices(robot: CableRobot, B_p, B_R_P):
    """Wrench matrices ``W`` (eq. 2) per sample, (n, 6, m); pure JAX, traceable.

    The one place where ``W`` is evaluated over a time series: every feature calls this.
    """
    return jax.vmap(lambda p, R: wrench_matrix(robot, p, R))(B_p, B_R_P)


def measured_wrench(robot: CableRobot, B_p, B_R_P, tau):
    """Measured cable wrench ``y = W(pose) tau`` per sample, (n, 6); pure JAX, traceable.

    The one place where ``W tau`` is formed: every feature (identification, diagnosis,
    online, real-data fitting, excitation) calls this instead of its own copy.
    """
    return jnp.einsum("nij,nj->ni", wrench_matrices(robot, B_p, B_R_P), tau)


def regressors(model: str, B_R_P, B_a, B_omega, B_alpha, gravity):
    """Regressor ``A`` per sample (eq. 10 or the full model), (n, 6, p); pure JAX, traceable.

    ``model`` is static ("translation" or "full"). The one place where the regressor is
    vmapped over time: every feature calls this.
    """
    if model not in ("translation", "full"):
        raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")
    return jax.vmap(lambda R, a, w, al: regressor(model, R, a, w, al, gravity))(
        B_R_P, B_a, B_omega, B_alpha)


_measured_wrench_jit = jax.jit(measured_wrench)
_regressors_jit = jax.jit(regressors, static_argnums=0)


def cable_wrench(robot: CableRobot, B_p, B_R_P, tau) -> np.ndarray:
    """Measured cable wrench ``W(pose) tau`` per sample (n, 6), as numpy (jit-compiled)."""
    return np.asarray(_measured_wrench_jit(robot, jnp.asarray(B_p), jnp.asarray(B_R_P),
                                           jnp.asarray(tau)))


def build_regression(robot: CableRobot, motion: Motion, tension, model: str = "translation",
                     wrench_filter=None) -> Regression:
    """Per-sample regressors and wrenches.

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
    tension : ndarray (n, m)
        Tensions on the motion's time base.
    model : {"translation", "full"}
    wrench_filter : callable, optional
        Applied to the (n, 6) measured wrench (matched filtering).
    """
    if model not in ("translation", "full"):
        raise ValueError(f"unknown model {model!r}; use 'translation' or 'full'.")
    y = cable_wrench(robot, motion.position, motion.B_R_P, tension)
    if wrench_filter is not None:
        y = np.asarray(wrench_filter(y))
    A = np.asarray(_regressors_jit(model, jnp.asarray(motion.B_R_P),
                                   jnp.asarray(motion.acceleration), jnp.asarray(motion.omega),
                                   jnp.asarray(motion.alpha), robot.gravity))
    return Regression(motion.t, A, y, model)
