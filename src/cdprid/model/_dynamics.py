"""Platform dynamics: Newton-Euler wrench (eqs. 1-7) and the linear regressors (eqs. 8-10).

All quantities are in the base frame unless their name starts with ``P_`` (platform frame).
The equation identified is ``W tau = w(x)`` with the platform wrench about P

    force  = m (a - g) + (alpha x + omega x omega x) (B_R_P m s_G)
    moment = (B_R_P m s_G) x (a - g) + B_R_P (I_P alpha_P + omega_P x I_P omega_P)

where a is the acceleration of P, s_G the centre of mass (platform frame), I_P the inertia
about P in the platform frame, ``omega_P = B_R_P^T omega`` and ``alpha_P = B_R_P^T alpha``.
This is eq. (7) rearranged with the paper's sign conventions (g = [0, 0, -9.81]); for a pure
translation with ``B_R_P = I`` the moment row reads ``m S_G (a - g)`` as in eq. (8).

Parameter vectors:

- translation model (eq. 10): ``x = [m, mxG, myG, mzG]`` (first moment in the platform frame)
- full model: ``x = [m, mxG, myG, mzG, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` with the inertia about P
  in the platform frame.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.model._rotations import skew

__all__ = [
    "InertialParameters",
    "PARAMETER_NAMES",
    "platform_wrench",
    "regressor_translation",
    "regressor_full",
    "regressor",
    "inertia_vector_matrix",
]

PARAMETER_NAMES = {
    "translation": ("m", "mxG", "myG", "mzG"),
    "full": ("m", "mxG", "myG", "mzG", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz"),
}


class InertialParameters(eqx.Module):
    """Inertial parameters of the platform (an immutable pytree).

    Attributes
    ----------
    mass : float
        m, kg.
    com : array (3,)
        s_G, centre of mass from P, platform frame, m.
    inertia_com : array (3, 3)
        Inertia about the centre of mass, platform frame, kg m^2.
    """

    mass: jnp.ndarray
    com: jnp.ndarray
    inertia_com: jnp.ndarray

    def __init__(self, mass, com, inertia_com=None):
        self.mass = jnp.asarray(mass, dtype=float)
        self.com = jnp.asarray(com, dtype=float)
        self.inertia_com = (
            jnp.zeros((3, 3)) if inertia_com is None else jnp.asarray(inertia_com, dtype=float)
        )

    @property
    def first_moment(self):
        """m s_G (3,), platform frame, kg m."""
        return self.mass * self.com

    @property
    def inertia_P(self):
        """Inertia about P, platform frame (parallel-axis theorem), kg m^2."""
        s = self.com
        return self.inertia_com + self.mass * ((s @ s) * jnp.eye(3) - jnp.outer(s, s))

    def vector(self, model: str = "translation"):
        """The parameter vector x of the ``translation`` (4) or ``full`` (10) model.

        Parameters
        ----------
        model : {"translation", "full"}
            Which model.

        Returns
        -------
        array (4,) or (10,)
            ``[m, m xG, m yG, m zG]`` (kg, kg m), then for ``full`` the inertia about P, platform
            frame, ``[Ixx, Ixy, Ixz, Iyy, Iyz, Izz]`` (kg m^2).

        Raises
        ------
        InputError
            Unknown ``model``.
        """
        x4 = jnp.concatenate([self.mass[None], self.first_moment])
        if model == "translation":
            return x4
        if model == "full":
            I = self.inertia_P
            return jnp.concatenate(
                [x4, jnp.array([I[0, 0], I[0, 1], I[0, 2], I[1, 1], I[1, 2], I[2, 2]])]
            )
        raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")

    @classmethod
    def from_vector(cls, x, model: str = "translation") -> InertialParameters:
        """Inverse of :meth:`vector` (inertia about P converted back to the centre of mass).

        Parameters
        ----------
        x : array-like (4,) or (10,)
            The parameter vector, units as :meth:`vector`; ``x[0]`` (the mass) must not be 0.
        model : {"translation", "full"}
            Which model ``x`` belongs to (any other value reads it as ``full``).

        Returns
        -------
        InertialParameters
            With zero inertia for ``translation``.
        """
        x = np.asarray(x, float)
        m = x[0]
        s = x[1:4] / m
        if model == "translation":
            return cls(m, s)
        Ixx, Ixy, Ixz, Iyy, Iyz, Izz = x[4:10]
        I_P = np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
        I_G = I_P - m * ((s @ s) * np.eye(3) - np.outer(s, s))
        return cls(m, s, I_G)


def inertia_vector_matrix(w):
    """L(w) such that ``I @ w == L(w) @ [Ixx, Ixy, Ixz, Iyy, Iyz, Izz]``.

    Parameters
    ----------
    w : array (3,)
        A vector (an angular velocity or acceleration).

    Returns
    -------
    array (3, 6)
    """
    z = jnp.zeros_like(w[0])
    return jnp.array(
        [
            [w[0], w[1], w[2], z, z, z],
            [z, w[0], z, w[1], w[2], z],
            [z, z, w[0], z, w[1], w[2]],
        ]
    )


def platform_wrench(params: InertialParameters, B_R_P, B_a, B_omega, B_alpha, gravity):
    """Wrench the cables must apply on the platform (force; moment about P), eqs. 1-7.

    Independent of the regressors: computed from the physical parameters directly, so that
    the regressors can be tested against it.

    Parameters
    ----------
    params : InertialParameters
    B_R_P : array (3, 3)
        Rotation platform -> base.
    B_a : array (3,)
        Acceleration of P, base frame, m/s^2.
    B_omega : array (3,)
        Angular velocity, base frame, rad/s.
    B_alpha : array (3,)
        Angular acceleration, base frame, rad/s^2.
    gravity : array (3,)
        Gravity acceleration, base frame, m/s^2.

    Returns
    -------
    array (6,)
        Force (N) and moment about P (N m), base frame.
    """
    m = params.mass
    c = B_R_P @ params.com  # centre of mass offset, base frame
    aG = B_a + jnp.cross(B_alpha, c) + jnp.cross(B_omega, jnp.cross(B_omega, c))
    force = m * (aG - gravity)
    # moment about P: sum of moments = d/dt(angular momentum about G) + c x m aG - c x m g
    I_G_base = B_R_P @ params.inertia_com @ B_R_P.T
    moment = I_G_base @ B_alpha + jnp.cross(B_omega, I_G_base @ B_omega) + jnp.cross(c, force)
    return jnp.concatenate([force, moment])


def regressor_translation(B_R_P, B_a, gravity):
    """Translation-only regressor A of eq. (10): ``A @ [m, mxG, myG, mzG] = W tau``.

    With ``B_R_P = I`` this is exactly the paper's matrix; with a measured rotation the
    first moment (platform frame) is rotated into the base frame.

    Parameters
    ----------
    B_R_P : array (3, 3)
        Rotation platform -> base.
    B_a : array (3,)
        Acceleration of P, base frame, m/s^2.
    gravity : array (3,)
        Gravity acceleration, base frame, m/s^2.

    Returns
    -------
    array (6, 4)
    """
    ag = B_a - gravity
    top = jnp.concatenate([ag[:, None], jnp.zeros((3, 3))], axis=1)
    bottom = jnp.concatenate([jnp.zeros((3, 1)), -skew(ag) @ B_R_P], axis=1)
    return jnp.concatenate([top, bottom], axis=0)


def regressor_full(B_R_P, B_a, B_omega, B_alpha, gravity):
    """Full regressor: ``A @ [m, m s_G, Ixx, Ixy, Ixz, Iyy, Iyz, Izz] = W tau``.

    The inertia entries are about P in the platform frame.

    Parameters
    ----------
    B_R_P : array (3, 3)
        Rotation platform -> base.
    B_a : array (3,)
        Acceleration of P, base frame, m/s^2.
    B_omega : array (3,)
        Angular velocity, base frame, rad/s.
    B_alpha : array (3,)
        Angular acceleration, base frame, rad/s^2.
    gravity : array (3,)
        Gravity acceleration, base frame, m/s^2.

    Returns
    -------
    array (6, 10)
    """
    ag = B_a - gravity
    K = skew(B_alpha) + skew(B_omega) @ skew(B_omega)
    wP = B_R_P.T @ B_omega
    alP = B_R_P.T @ B_alpha
    top = jnp.concatenate([ag[:, None], K @ B_R_P, jnp.zeros((3, 6))], axis=1)
    Lin = B_R_P @ (inertia_vector_matrix(alP) + skew(wP) @ inertia_vector_matrix(wP))
    bottom = jnp.concatenate([jnp.zeros((3, 1)), -skew(ag) @ B_R_P, Lin], axis=1)
    return jnp.concatenate([top, bottom], axis=0)


def regressor(model: str, B_R_P, B_a, B_omega, B_alpha, gravity):
    """Dispatch to :func:`regressor_translation` or :func:`regressor_full` by ``model``.

    Parameters
    ----------
    model : {"translation", "full"}
        Which regressor.
    B_R_P : array (3, 3)
        Rotation platform -> base.
    B_a : array (3,)
        Acceleration of P, base frame, m/s^2.
    B_omega : array (3,)
        Angular velocity, base frame, rad/s.
    B_alpha : array (3,)
        Angular acceleration, base frame, rad/s^2.
        Unused by ``translation``.
    gravity : array (3,)
        Gravity acceleration, base frame, m/s^2.

    Returns
    -------
    array (6, 4) or (6, 10)

    Raises
    ------
    InputError
        Unknown ``model``.
    """
    if model == "translation":
        return regressor_translation(B_R_P, B_a, gravity)
    if model == "full":
        return regressor_full(B_R_P, B_a, B_omega, B_alpha, gravity)
    raise InputError(f"unknown model {model!r}; use 'translation' or 'full'.")
