"""Stage 1 of the diagnosis: base fit, noise levels and the null model.

The model ``identify --model auto`` would use: the paper's translation model (x = [m, m s_G]),
or the full 10-parameter model when the platform rotates (``Problem.rotational_base``), with
matched filtering; force and moment rows
weighted by the inverse of their residual RMS. The sensor noise is estimated from the data and
drives the null residuals that calibrate the thresholds of the tests.
"""

from __future__ import annotations

import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from cdprid.core import differentiate_pose, least_squares
from cdprid.diagnosis._model import regs_jit, rotvec_from_quat
from cdprid.diagnosis._parts import ParameterEstimate, ParameterEstimates
from cdprid.diagnosis._problem import Problem, cable_side
from cdprid.diagnosis._testing import estimate_noise, wald
from cdprid.model import PARAMETER_NAMES


@dataclasses.dataclass(frozen=True)
class BaseFit:
    """The paper's model fitted to the data (before any effect)."""

    x: np.ndarray  # (4,) m, m s_G, or (10,) with the inertia when ``rotational``
    parameters: ParameterEstimates
    residual_rms: list
    residual: np.ndarray  # (n, 6) unweighted, filtered
    y: np.ndarray  # (n, 6) filtered measured wrench at theta = 0
    A4: np.ndarray  # (n, 6, 4)
    A10: np.ndarray | None  # (n, 6, 10) with rotation, else None
    rotational: bool = False  # the base model is the full model

    @property
    def A(self) -> np.ndarray:
        """The base model's regressors, ``(n, 6, 4)`` or ``(n, 6, 10)``."""
        return self.A10 if self.rotational else self.A4


@dataclasses.dataclass(frozen=True)
class NoiseLevels:
    """Sensor noise estimated from the data, and the rotation amplitude of the motion."""

    position_m: float
    tension_N: np.ndarray  # (m,)
    rotation_amplitude: float
    rotation_amplitude_std: float


def base_fit(prob: Problem) -> tuple[Problem, BaseFit]:
    """Fit the base model; returns the problem with its row weights set, and the fit.

    Force and moment rows are weighted by the inverse of their residual RMS; when the moment
    residual is nil (every cable attached at one point and the model fits the zero moments
    exactly) the moment rows get the force rows' weight.

    Parameters
    ----------
    prob : Problem
        From :func:`prepare`.

    Returns
    -------
    (Problem, BaseFit)
        The problem with ``wrow`` (row weights, 1/N and 1/(N m)) set, and the fit (x: m in kg,
        m s_G in kg m, the inertia in kg m^2 when rotational; residual rms in N).
    """
    theta0 = (jnp.zeros(prob.layout.size) if prob.theta0 is None
              else jnp.asarray(prob.theta0, float))  # the drive model on currents
    A4 = np.asarray(regs_jit(prob.d, theta0, prob.layout, False))
    A10 = np.asarray(regs_jit(prob.d, theta0, prob.layout, True)) if prob.has_rotation else None
    y0 = cable_side(prob, theta0)[0]
    train = prob.train
    beta, *_ = np.linalg.lstsq(A4[train].reshape(-1, 4), y0[train].reshape(-1), rcond=None)
    e = y0[train] - np.einsum("nip,p->ni", A4[train], beta)
    sf = np.sqrt(np.mean(e[:, :3] ** 2))
    sm = np.sqrt(np.mean(e[:, 3:] ** 2))
    if not sm > 1e-9 * sf:  # all cables meet at one point (a point-mass robot): no moments
        sm = sf
    wrow = np.array([1 / sf] * 3 + [1 / sm] * 3)
    prob = dataclasses.replace(prob, wrow=wrow)
    rot = bool(prob.rotational_base and A10 is not None)
    A = A10 if rot else A4
    names = PARAMETER_NAMES["full" if rot else "translation"]
    x = least_squares((A[train] * wrow[None, :, None]).reshape(-1, A.shape[2]),
                      (y0[train] * wrow).reshape(-1), names).x
    res = y0 - np.einsum("nij,j->ni", A, x)
    Zb, yb = A * wrow[None, :, None], y0 * wrow
    _, _, Vb, _ = wald(Zb[train], yb[train], [0], prob.lags)
    params = ParameterEstimates({
        nm: ParameterEstimate(
            value=float(v_), std=float(np.sqrt(Vb[i, i])),
            rel_std_percent=float(100 * np.sqrt(Vb[i, i]) / max(abs(v_), 1e-300)))
        for i, (nm, v_) in enumerate(zip(names, x, strict=True))
    })
    rms = [float(np.sqrt(np.mean(res[train][:, i] ** 2))) for i in range(6)]
    return prob, BaseFit(x, params, rms, res, y0, A4, A10, rot)


def noise_levels(prob: Problem) -> NoiseLevels:
    """White-noise levels of position and tensions (4th differences, MAD) and rotation size.

    Parameters
    ----------
    prob : Problem

    Returns
    -------
    NoiseLevels
        Position noise (m), per-cable tension noise (N, (m,)), the rotation's 99.5 %
        amplitude and its noise (rad).
    """
    sig_p = float(np.median(estimate_noise(prob.position)))
    sig_tau = estimate_noise(prob.tau_grid)
    amp = std = 0.0
    if prob.has_rotation:
        rv = rotvec_from_quat(prob.quaternion[prob.use])
        amp = float(np.max(np.percentile(np.abs(rv), 99.5, axis=0)))
        std = float(np.median(estimate_noise(rv)))
    return NoiseLevels(sig_p, sig_tau, amp, std)


def null_residuals(prob: Problem, noise: NoiseLevels, x, n_null: int, rng):
    """Residual replicates of the base model under sensor noise alone, ``(n, 6)`` each.

    The position noise reaches the accelerations through the differentiator of the problem's
    motion (:attr:`Problem.motion`, :func:`cdprid.core.differentiate_pose`).

    Parameters
    ----------
    prob : Problem
    noise : NoiseLevels
        The levels to simulate (:func:`noise_levels`).
    x : array_like (4,) or (10,)
        The base fit's parameters.
    n_null : int
        Number of replicates.
    rng : numpy.random.Generator

    Yields
    ------
    numpy.ndarray (n, 6)
        One replicate's weighted wrench residual (N and N m times the row weights).
    """
    n, m, dt = prob.n, prob.m, prob.dt
    mo = prob.motion
    for _ in range(n_null):
        eta_t = rng.normal(size=(n, m)) * noise.tension_N[None, :] * math.sqrt(prob.tdt / dt)
        eta_p = rng.normal(size=(n, 3)) * noise.position_m
        _, acc = differentiate_pose(eta_p, dt, method=mo.method, params=mo.params)
        yw = prob.filt(np.einsum("nij,nj->ni", prob.W_all, eta_t))
        ms = np.einsum("nij,j->ni", prob.R, x[1:4])  # first moment, base frame
        yield yw - np.concatenate([x[0] * acc, np.cross(ms, acc)], axis=1)
