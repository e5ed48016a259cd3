"""The winch drive model: cable tension from motor current and the winch's motion.

A winch: motor (torque constant K_t, rotor inertia J_m) -> gear (N motor turns per drum turn)
-> drum (radius r, inertia J_d). ``l`` is the length paid out (``l' > 0`` while the cable pays
out), the drum angle ``theta = l / r`` and the motor angle ``N theta``. A positive current
makes a torque that winds the cable in. Free body of the drum with everything reflected to it
(tension torque ``tau r`` pays out, the motor torque ``N K_t i`` winds in, friction opposes the
motion):

    (N^2 J_m + J_d) theta'' = tau r - N K_t i - b theta' - T_c sign(theta')

so, dividing by r and with ``theta = l / r``,

    tau = k i + J l'' + f_v l' + f_c sign(l') - c                                 (drive model)

with ``k = N K_t / r`` (N/A), ``J = (N^2 J_m + J_d) / r^2`` (kg, reflected inertia), ``f_v = b /
r^2`` (N s/m), ``f_c = T_c / r`` (N) and ``c = k i_0`` (N) for a current reading ``i = i_true +
i_0`` offset by ``i_0``. Paying out with positive acceleration, the cable must also accelerate
the rotor: a larger tension for the same current (+J l''); friction resists paying out (+f_v
l', +f_c). ``tests/core/test_drives.py`` checks these signs against an ODE of the drum.

Every term is linear in ``d = (k, J, f_v, f_c, c)``: ``W tau = D d`` with the columns of
:func:`drive_columns`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["DRIVE_PARAMETER_NAMES", "DRIVE_UNITS", "DriveParameters", "drive_tension",
           "drive_columns", "drive_names"]

#: parameter kinds of every drive, in the order of :func:`drive_columns`
DRIVE_PARAMETER_NAMES = ("k", "J", "fv", "fc", "c")
#: their units
DRIVE_UNITS = {"k": "N/A", "J": "kg", "fv": "N s/m", "fc": "N", "c": "N"}


@dataclasses.dataclass(frozen=True)
class DriveParameters:
    """Parameters of every winch drive (each an array (m,)).

    Attributes
    ----------
    k : current-to-force constant, N/A
    J : reflected rotor and drum inertia, kg
    fv : viscous drive friction, N s/m
    fc : Coulomb drive friction, N
    c : current offset as a force (``k i_0``), N
    """

    k: np.ndarray
    J: np.ndarray
    fv: np.ndarray
    fc: np.ndarray
    c: np.ndarray

    def vector(self) -> np.ndarray:
        """The parameters as one vector, kinds in the order of :data:`DRIVE_PARAMETER_NAMES`.

        Returns
        -------
        ndarray (5 m,)
            ``(k_1..k_m, J_1..J_m, fv_1..fv_m, fc_1..fc_m, c_1..c_m)`` in N/A, kg, N s/m, N, N.
        """
        return np.concatenate([np.asarray(getattr(self, n), float)
                               for n in DRIVE_PARAMETER_NAMES])

    @classmethod
    def from_vector(cls, d) -> DriveParameters:
        """Inverse of :meth:`vector`.

        Parameters
        ----------
        d : array_like (5 m,)
            ``(k_1..k_m, J_1..J_m, fv_1..fv_m, fc_1..fc_m, c_1..c_m)`` in N/A, kg, N s/m, N, N.

        Returns
        -------
        DriveParameters
            Each kind an array (m,).
        """
        d = np.asarray(d, float)
        return cls(*np.split(d, len(DRIVE_PARAMETER_NAMES)))


def drive_names(m: int) -> tuple:
    """Names of the 5m drive parameters.

    Parameters
    ----------
    m : int
        Number of cables.

    Returns
    -------
    tuple of str
        ``("k_1", ..., "k_m", "J_1", ..., "c_m")``, the order of :meth:`DriveParameters.vector`.
    """
    return tuple(f"{n}_{j}" for n in DRIVE_PARAMETER_NAMES for j in range(1, m + 1))


def drive_tension(p: DriveParameters, current, ldot, lddot, sign=None) -> np.ndarray:
    """Cable tensions of the drive model, ``k i + J l'' + f_v l' + f_c sign(l') - c``.

    Parameters
    ----------
    p : DriveParameters
    current : ndarray (n, m)
        Current readings, A.
    ldot, lddot : ndarray (n, m)
        Paid-out length rate (m/s) and acceleration (m/s^2).
    sign : ndarray (n, m), optional
        ``sign(l')`` (default ``np.sign(ldot)``).

    Returns
    -------
    ndarray (n, m)
        Tensions, N.
    """
    s = np.sign(ldot) if sign is None else sign
    return p.k * current + p.J * lddot + p.fv * ldot + p.fc * s - p.c


def drive_columns(W, current, ldot, lddot, sign) -> np.ndarray:
    """The drive regressor ``D`` with ``W tau = D d`` (``d``: :meth:`DriveParameters.vector`).

    Parameters
    ----------
    W : ndarray (n, 6, m)
        Wrench matrices.
    current, ldot, lddot, sign : ndarray (n, m)
        As in :func:`drive_tension` (A, m/s, m/s^2, sign of ``ldot``).

    Returns
    -------
    ndarray (n, 6, 5 m)
        Columns in the order of :meth:`DriveParameters.vector`; ``D d`` in N and N m.
    """
    W = np.asarray(W, float)
    parts = [W * np.asarray(x, float)[:, None, :] for x in (current, lddot, ldot, sign)]
    return np.concatenate(parts + [-W], axis=2)
