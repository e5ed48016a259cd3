"""Simulated winch drives: motor currents and encoder lengths from the drive model
(``docs/drives.md``), with the drives' own effects (a torque-constant error against the
datasheet, reflected inertia, viscous and Coulomb friction, a current offset).

The plant is :func:`cdprid.simulation.simulate`'s (true tensions at the tension times); each
winch's paid-out length is the true geometry's cable length ``L`` (exit, pulley arc,
attachment) up to a constant, its rate and acceleration exact (second-order Taylor of the pose
path, forward-mode derivatives), and the current reading is

    i = (tau - J L'' - f_v L' - f_c sign(L') + c) / k + noise

(:mod:`cdprid.core._drives`: ``c = k i_0``).
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import InputError
from cdprid.core import DriveParameters
from cdprid.model import cable_lengths, skew

__all__ = ["DriveSimulation", "length_derivatives", "simulate_drives", "write_drive_simulation"]


@dataclasses.dataclass(frozen=True)
class DriveSimulation:
    """Simulated drive streams at the tension times of a :class:`SimResult`.

    Attributes
    ----------
    t : (k,) s
    current : (k, m) measured currents, A
    lengths : (k, m) measured paid-out lengths, m
    truth : DriveParameters
    nominal : dict
        Per-cable robot.toml drive fields (``drum_radius``, ``gear_ratio``,
        ``torque_constant``, ``torque_constant_tolerance``, ...), a list of dicts.
    noise_A, noise_m : float
        Current and encoder noise std.
    """

    t: np.ndarray
    current: np.ndarray
    lengths: np.ndarray
    truth: DriveParameters
    nominal: list
    noise_A: float
    noise_m: float


def length_derivatives(robot, p, v, a, q_R, omega, alpha):
    """``(L, L', L'')`` (n, m) of the cable lengths along a pose path.

    The pose path's second-order Taylor expansion about each sample (exact first and second
    derivatives there), its cable lengths differentiated by 5-point stencils of step 1 ms
    (truncation ~1e-12, rounding ~1e-10 m/s^2).

    Parameters
    ----------
    robot : CableRobot
    p, v, a : (n, 3) position of P and its derivatives, base frame
    q_R : (n, 3, 3) rotation matrices platform -> base
    omega, alpha : (n, 3) angular velocity and acceleration, base frame

    Returns
    -------
    tuple of (n, m) arrays: m, m/s, m/s^2
    """
    out = _length_rates(robot, *(jnp.asarray(np.asarray(x), float) for x in (
        p, v, a, q_R, omega, alpha)))
    return tuple(np.asarray(x) for x in out)


_H = 1e-3  # s along the Taylor path: 5-point stencils, error ~h^4 (and 1e-10 rounding)


def _one_sample(robot, pk, vk, ak, Rk, wk, alk):
    S, A = skew(wk), skew(alk)

    def f(s):
        R = Rk + s * S @ Rk + 0.5 * s * s * (A + S @ S) @ Rk
        return cable_lengths(robot, pk + s * vk + 0.5 * s * s * ak, R)

    fm2, fm1, f0, f1, f2 = (f(k * _H) for k in (-2.0, -1.0, 0.0, 1.0, 2.0))
    return (f0, (fm2 - 8 * fm1 + 8 * f1 - f2) / (12 * _H),
            (-fm2 + 16 * fm1 - 30 * f0 + 16 * f1 - f2) / (12 * _H * _H))


_length_rates = jax.jit(jax.vmap(_one_sample, in_axes=(None, 0, 0, 0, 0, 0, 0)))


def simulate_drives(result, truth: DriveParameters, nominal: list, noise_A: float = 0.03,
                    noise_m: float = 5e-5, seed: int = 0) -> DriveSimulation:
    """Motor currents and encoder lengths of a simulated recording.

    Parameters
    ----------
    result : SimResult
        The plant (true tensions and motion at its tension times).
    truth : DriveParameters
        The drives' true parameters (k: N/A, J: kg, fv: N s/m, fc: N, c: N).
    nominal : list of dict
        What robot.toml states for each drive (datasheet values; they may differ from the
        truth).
    noise_A, noise_m : float
        White current and encoder noise std.
    seed : int
        Noise seed (its own stream, independent of the plant's sensors).

    Returns
    -------
    DriveSimulation
    """
    if not (np.isfinite(noise_A) and noise_A >= 0 and np.isfinite(noise_m) and noise_m >= 0):
        raise InputError("drive noise levels must be finite numbers >= 0.")
    if np.any(np.asarray(truth.k) <= 0):
        raise InputError("every drive's current-to-force constant k must be > 0.")
    mt = result.motion_tension
    k = result.tension_t.size
    R = jax.vmap(_quat_matrix)(jnp.asarray(np.asarray(mt.q)[:k]))
    L, Ld, Ldd = length_derivatives(result.robot_true, *(np.asarray(x)[:k] for x in (
        mt.p, mt.v, mt.a)), R, *(np.asarray(x)[:k] for x in (mt.omega, mt.alpha)))
    tau = np.asarray(result.tension_true)
    i_true = (tau - truth.J * Ldd - truth.fv * Ld - truth.fc * np.sign(Ld)) / truth.k
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 41]))
    cur = i_true + truth.c / truth.k + noise_A * rng.standard_normal(tau.shape)
    lengths = L + noise_m * rng.standard_normal(tau.shape)
    return DriveSimulation(np.asarray(result.tension_t), cur, lengths, truth, list(nominal),
                           float(noise_A), float(noise_m))


def _quat_matrix(q):
    from cdprid.model import quat_to_matrix

    return quat_to_matrix(q)


def write_drive_simulation(result, drives: DriveSimulation, out_dir, load_cells: bool = False,
                           overwrite: bool = False):
    """Write the recording with currents.csv and lengths.csv (format 1.2).

    Parameters
    ----------
    result : SimResult
    drives : DriveSimulation
    out_dir : str or Path
    load_cells : bool
        Also write tensions.csv (the load cells of ``result``); default: none.
    overwrite : bool

    Returns
    -------
    Path
    """
    from cdprid.simulation._simulate import write_simulation

    m = drives.current.shape[1]
    extra = {"currents": (["t"] + [f"i_{j}" for j in range(1, m + 1)],
                          np.column_stack([drives.t, drives.current])),
             "lengths": (["t"] + [f"l_{j}" for j in range(1, m + 1)],
                         np.column_stack([drives.t, drives.lengths]))}
    truth = {n: [float(v) for v in np.asarray(getattr(drives.truth, n))]
             for n in ("k", "J", "fv", "fc", "c")}
    truth.update(noise_A=drives.noise_A, noise_m=drives.noise_m)
    return write_simulation(result, out_dir, overwrite=overwrite, extra=extra,
                            drives=drives.nominal, drive_truth=truth, load_cells=load_cells)
