# ruff: noqa: F722  (jaxtyping shape strings)
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
from jaxtyping import Float

from cdprid.base import InputError, cached_executable
from cdprid.core._motion import BLOCK, Motion, blockwise
from cdprid.model import CableRobot, regressor, wrench_matrix

__all__ = [
    "CHUNK", "Regression", "StreamedRegression", "build_regression", "cable_wrench",
    "measured_wrench", "regressor_blocks", "regressors", "wrench_matrices",
    "wrench_matrix_series",
]

CHUNK = BLOCK  # 16384, the same blocks as cdprid.core._motion
"""Time samples per block when per-sample arrays are evaluated block by block (bounded memory:
the jitted functions see one fixed block shape, the last block is padded)."""


class _StackedWrenches:
    """Stacked views shared by :class:`Regression` and :class:`StreamedRegression`."""

    t: np.ndarray
    y: np.ndarray

    @property
    def Y_ID(self) -> np.ndarray:
        """Stacked wrenches (6 n,)."""
        return self.y.reshape(-1)

    @property
    def groups(self) -> np.ndarray:
        """Row group per stacked row: 0 force, 1 moment."""
        return np.tile(np.array([0, 0, 0, 1, 1, 1]), len(self.t))


@dataclasses.dataclass(frozen=True)
class Regression(_StackedWrenches):
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

    def select(self, mask) -> Regression:
        """The samples where ``mask`` is True.

        Parameters
        ----------
        mask : array_like (n,) of bool or indices

        Returns
        -------
        Regression
        """
        return Regression(self.t[mask], self.A[mask], self.y[mask], self.model)


def wrench_matrices(robot: CableRobot, B_p, B_R_P):
    """Wrench matrices ``W`` (eq. 2) per sample; pure JAX, traceable.

    The one place where ``W`` is evaluated over a time series: every feature calls this.

    Parameters
    ----------
    robot : CableRobot
    B_p : jax.Array (n, 3)
        Platform positions, base frame, m.
    B_R_P : jax.Array (n, 3, 3)
        Orientations (platform to base).

    Returns
    -------
    jax.Array (n, 6, m)
        Unit cable directions (force rows, 1) and their moments (moment rows, m).
    """
    return jax.vmap(lambda p, R: wrench_matrix(robot, p, R))(B_p, B_R_P)


def measured_wrench(robot: CableRobot, B_p, B_R_P, tau):
    """Measured cable wrench ``y = W(pose) tau`` per sample; pure JAX, traceable.

    The one place where ``W tau`` is formed: every feature (identification, diagnosis,
    online, real-data fitting, excitation) calls this instead of its own copy.

    Parameters
    ----------
    robot : CableRobot
    B_p : jax.Array (n, 3)
        Platform positions, base frame, m.
    B_R_P : jax.Array (n, 3, 3)
        Orientations (platform to base).
    tau : jax.Array (n, m)
        Tensions, N.

    Returns
    -------
    jax.Array (n, 6)
        Force (N) and moment (N m), base frame.
    """
    return jnp.einsum("nij,nj->ni", wrench_matrices(robot, B_p, B_R_P), tau)


def regressors(model: str, B_R_P, B_a, B_omega, B_alpha, gravity):
    """Regressor ``A`` per sample (eq. 10 or the full model); pure JAX, traceable.

    ``model`` is static. The one place where the regressor is vmapped over time: every
    feature calls this.

    Parameters
    ----------
    model : {"translation", "full"}
    B_R_P : jax.Array (n, 3, 3)
        Orientations (platform to base).
    B_a : jax.Array (n, 3)
        Accelerations, base frame, m/s^2.
    B_omega, B_alpha : jax.Array (n, 3)
        Angular rate (rad/s) and acceleration (rad/s^2), base frame.
    gravity : jax.Array (3,)
        Gravity, base frame, m/s^2.

    Returns
    -------
    jax.Array (n, 6, p)
        ``A theta`` in N and N m (p = 4 or 10).

    Raises
    ------
    InputError
        An unknown ``model``.
    """
    if model not in ("translation", "full"):
        raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")
    return jax.vmap(lambda R, a, w, al: regressor(model, R, a, w, al, gravity))(
        B_R_P, B_a, B_omega, B_alpha)


_measured_wrench_jit = cached_executable(jax.jit(measured_wrench), name="core.measured_wrench")
_regressors_jit = cached_executable(jax.jit(regressors, static_argnums=0),
                                   name="core.regressors", static_argnums=(0,))
_wrench_matrices_jit = cached_executable(jax.jit(wrench_matrices), name="core.wrench_matrices")


def _blockwise(fn, arrays, out, i0: int, i1: int, chunk: int) -> None:
    """``out[j] = fn(*arrays)[i0 + j]`` for ``i0 <= i < i1``: :func:`cdprid.core.blockwise` on
    that range (one fixed block shape, so a jitted ``fn`` compiles once whatever the requests)."""
    blockwise(lambda *parts: (fn(*parts),), [np.asarray(x[i0:i1], float) for x in arrays],
              [out], chunk)


def cable_wrench(robot: CableRobot, B_p: Float[np.ndarray, "n 3"],
                 B_R_P: Float[np.ndarray, "n 3 3"], tau: Float[np.ndarray, "n m"],
                 chunk: int = CHUNK) -> Float[np.ndarray, "n 6"]:
    """Measured cable wrench ``W(pose) tau`` per sample, as numpy (jit-compiled).

    Evaluated ``chunk`` samples at a time, so the (n, 6, m) wrench matrices are never all held.

    Parameters
    ----------
    robot : CableRobot
    B_p : ndarray (n, 3)
        Platform positions, base frame, m.
    B_R_P : ndarray (n, 3, 3)
        Platform orientations (platform to base).
    tau : ndarray (n, m)
        Cable tensions, N.
    chunk : int
        Samples per block.

    Returns
    -------
    ndarray (n, 6)
        Force (N) and moment about the platform reference point (N m), base frame.
    """
    n = len(B_p)
    out = np.empty((n, 6))
    _blockwise(lambda p, R, t: _measured_wrench_jit(robot, p, R, t), (B_p, B_R_P, tau), out,
               0, n, min(int(chunk), n))
    return out


def wrench_matrix_series(robot: CableRobot, B_p: Float[np.ndarray, "n 3"],
                         B_R_P: Float[np.ndarray, "n 3 3"],
                         chunk: int = CHUNK) -> Float[np.ndarray, "n 6 m"]:
    """Wrench matrices ``W(pose)`` per sample, as numpy: :func:`wrench_matrices` jit-compiled
    and evaluated in blocks of ``chunk`` samples (one block shape, one compilation).

    Parameters
    ----------
    robot : CableRobot
    B_p, B_R_P : ndarray (n, 3) and (n, 3, 3)
        The platform's poses: positions (m) and orientations (platform to base), base frame.
    chunk : int
        Block length, samples.

    Returns
    -------
    ndarray (n, 6, m)
        Unit cable directions (force rows) and their moments about the platform reference
        point (moment rows, m), base frame.
    """
    n = len(B_p)
    out = np.empty((n, 6, robot.n_cables))
    _blockwise(lambda p, R: _wrench_matrices_jit(robot, p, R), (B_p, B_R_P), out, 0, n,
               min(int(chunk), n))
    return out


def regressor_blocks(model: str, B_R_P: Float[np.ndarray, "n 3 3"], B_a: Float[np.ndarray, "n 3"],
                     B_omega: Float[np.ndarray, "n 3"], B_alpha: Float[np.ndarray, "n 3"],
                     gravity, chunk: int = CHUNK):
    """A function ``block(i0, i1)`` that returns the regressors of samples ``i0:i1``
    (:func:`regressors`, jit-compiled for one block shape).

    Parameters
    ----------
    model : {"translation", "full"}
    B_R_P : ndarray (n, 3, 3)
        Orientations (platform to base).
    B_a, B_omega, B_alpha : ndarray (n, 3)
        Acceleration (m/s^2), angular rate (rad/s) and angular acceleration (rad/s^2), base
        frame.
    gravity : array (3,)
        Gravity, base frame, m/s^2.
    chunk : int
        Samples per jitted call.

    Returns
    -------
    callable
        ``block(i0, i1) -> ndarray (i1 - i0, 6, p)``.

    Raises
    ------
    InputError
        An unknown ``model``.
    """
    if model not in ("translation", "full"):
        raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")
    p = 4 if model == "translation" else 10
    arrays = (B_R_P, B_a, B_omega, B_alpha)
    c = max(1, min(int(chunk), len(B_a)))

    def block(i0: int, i1: int) -> np.ndarray:
        out = np.empty((i1 - i0, 6, p))
        _blockwise(lambda R, a, w, al: _regressors_jit(model, R, a, w, al, gravity), arrays,
                   out, i0, i1, c)
        return out

    return block


@dataclasses.dataclass(frozen=True)
class StreamedRegression(_StackedWrenches):
    """:class:`Regression` whose regressor is evaluated block by block, never held whole.

    Attributes
    ----------
    t : ndarray (n,)
    y : ndarray (n, 6)
        Measured wrench ``W tau`` per sample (after the matched filter, if any).
    model : str
    block : callable
        ``block(i0, i1)`` -> regressors (i1 - i0, 6, p) of samples ``i0:i1``.
    """

    t: np.ndarray
    y: np.ndarray
    model: str
    block: object

    def wrench_block(self, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
        """``(A, y)`` of samples ``i0:i1``: the form :func:`cdprid.core.least_squares_blocks`
        asks for.

        Parameters
        ----------
        i0, i1 : int
            First and one-past-last sample.

        Returns
        -------
        A : ndarray (i1 - i0, 6, p)
            Regressor rows (the parameters' SI units to N and N m).
        y : ndarray (i1 - i0, 6)
            Cable wrenches ``W tau``, N and N m.
        """
        return self.block(i0, i1), self.y[i0:i1]

    @property
    def A(self) -> np.ndarray:
        """All regressors (n, 6, p), materialised on demand."""
        return self.block(0, len(self.t))

    @property
    def W_ID(self) -> np.ndarray:
        """Stacked regressor (6 n, p), materialised on demand."""
        A = self.A
        return A.reshape(-1, A.shape[-1])

    def select(self, mask) -> Regression:
        """The samples where ``mask`` is True, materialised.

        Parameters
        ----------
        mask : array_like (n,) of bool or indices

        Returns
        -------
        Regression
            Regressor rows (k, 6, p) and cable wrenches (k, 6) of the selected samples.
        """
        return Regression(self.t[mask], self.A[mask], self.y[mask], self.model)


def build_regression(robot: CableRobot, motion: Motion, tension, model: str = "translation",
                     wrench_filter=None) -> Regression:
    """Per-sample regressors and wrenches.

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
        The differentiated motion (n samples).
    tension : ndarray (n, m)
        Tensions on the motion's time base, N.
    model : {"translation", "full"}
        Parameters of the regressor (4 or 10).
    wrench_filter : callable, optional
        Applied to the (n, 6) measured wrench (matched filtering).

    Returns
    -------
    Regression
        Regressor rows ``A`` (n, 6, p) and cable wrenches ``y = W tau`` (n, 6) in N and N m.

    Raises
    ------
    InputError
        An unknown ``model``.
    """
    if model not in ("translation", "full"):
        raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")
    y = cable_wrench(robot, motion.position, motion.B_R_P, tension)
    if wrench_filter is not None:
        y = np.asarray(wrench_filter(y))
    A = np.asarray(_regressors_jit(model, jnp.asarray(motion.B_R_P),
                                   jnp.asarray(motion.acceleration), jnp.asarray(motion.omega),
                                   jnp.asarray(motion.alpha), robot.gravity))
    return Regression(motion.t, A, y, model)
