"""Load cells calibrated against another source of the cable forces (issue 41).

Given the tensions another identification predicts, ``tau_hat = T theta`` (linear in its
parameters ``theta``: the drives' model, or the free motion's dynamics), each load cell's
reading (through the same matched filter) is fitted as

    tau_meas_j = g_j tau_hat_j + o_j

by least squares with a HAC covariance; the uncertainty of ``theta`` (its reference's
included) is added by the delta method (exact derivatives: ``tau_hat`` is linear in
``theta``, the fit is differentiated by finite differences of ``theta``). A cell whose gain
differs from 1, or whose offset from 0, beyond its 95 % interval gets a warning.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.core import least_squares_blocks

__all__ = ["CellCalibration", "calibrate_cells_wrench", "cells_from_design", "fit_cells"]


@dataclasses.dataclass(frozen=True)
class CellCalibration:
    """Gain and offset of every load cell against a reference of the forces.

    Attributes
    ----------
    gain, offset : (m,) estimates (1, N)
    gain_std, offset_std : (m,) HAC std, the reference's uncertainty included
    against : str
        What the cells were calibrated against.
    warnings : tuple of str
    """

    gain: np.ndarray
    offset: np.ndarray
    gain_std: np.ndarray
    offset_std: np.ndarray
    against: str
    warnings: tuple = ()

    def as_json(self) -> list:
        """JSON ``load_cells`` of the report.

        Returns
        -------
        list of dict
            Per cell ``{"cable", "against", "gain", "offset_N"}``; ``gain`` and ``offset_N`` each
            ``{"value", "std", "interval95", "disagrees"}`` (``disagrees``: 1 resp. 0 N lies outside
            the 95 % interval).
        """
        out = []
        for j in range(len(self.gain)):
            e = {"cable": j + 1, "against": self.against}
            for key, v, s, ok in (("gain", self.gain[j], self.gain_std[j], 1.0),
                                  ("offset_N", self.offset[j], self.offset_std[j], 0.0)):
                e[key] = {"value": float(v), "std": float(s),
                          "interval95": [float(v - 1.96 * s), float(v + 1.96 * s)],
                          "disagrees": bool(abs(v - ok) > 1.96 * s)}
            out.append(e)
        return out

    def table(self) -> str:
        """Plain-text table of the calibration (gain and offset, N, with 95 % intervals).

        Returns
        -------
        str
            Lines without a trailing newline.
        """
        lines = [f"load cells against {self.against} (95 % intervals):"]
        for j in range(len(self.gain)):
            g, sg, o, so = self.gain[j], self.gain_std[j], self.offset[j], self.offset_std[j]
            lines.append(f"  cell {j + 1}: gain {g:.4f} [{g - 1.96 * sg:.4f}, "
                         f"{g + 1.96 * sg:.4f}]   offset {o:+.3f} N [{o - 1.96 * so:+.3f}, "
                         f"{o + 1.96 * so:+.3f}]")
        return "\n".join(lines)


def fit_cells(tau_hat, tau_meas, chunk: int = 16384):
    """Per cell, ``tau_meas = g tau_hat + o`` by least squares with HAC covariance.

    Parameters
    ----------
    tau_hat, tau_meas : (n, m) N

    Returns
    -------
    x (m, 2) the (gain, offset) and cov (m, 2, 2)
    """
    n, m = tau_hat.shape
    x, cov = np.zeros((m, 2)), np.zeros((m, 2, 2))
    for j in range(m):
        def block(i0, i1, j=j):
            Z = np.stack([tau_hat[i0:i1, j], np.ones(i1 - i0)], axis=1)[:, None, :]
            return Z, tau_meas[i0:i1, j][:, None]

        r = least_squares_blocks(block, n, ("gain", "offset"), covariance="hac", chunk=chunk)
        x[j], cov[j] = r.x, r.cov
    return x, cov


def _ols_cells(tau_hat, tau_meas):
    """The (gain, offset) of every cell by plain least squares (m, 2): the delta method's map."""
    out = []
    for j in range(tau_hat.shape[1]):
        X = np.stack([tau_hat[:, j], np.ones(len(tau_hat))], axis=1)
        out.append(np.linalg.lstsq(X, tau_meas[:, j], rcond=None)[0])
    return np.array(out)


def cells_from_design(T, theta, cov_theta, tau_meas, against: str,
                      chunk: int = 16384) -> CellCalibration:
    """Calibrate the cells against ``tau_hat = T theta``.

    Parameters
    ----------
    T : (n, m, q) the predicted tensions' design
    theta : (q,) and cov_theta (q, q): the other identification's estimate and covariance
    tau_meas : (n, m) the load-cell readings, filtered like ``tau_hat``
    against : str
        Named in the table and the warnings.

    Returns
    -------
    CellCalibration
    """
    tau_hat = T @ theta
    x, cov = fit_cells(tau_hat, tau_meas, chunk)
    q = len(theta)
    h = 1e-6 * np.maximum(np.abs(theta), 1e-6)
    J = np.zeros((tau_hat.shape[1], 2, q))
    base = _ols_cells(tau_hat, tau_meas)
    for k in range(q):
        if not np.any(cov_theta[k]):
            continue
        J[:, :, k] = (_ols_cells(tau_hat + h[k] * T[:, :, k], tau_meas) - base) / h[k]
    cov = cov + np.einsum("jak,kl,jbl->jab", J, cov_theta, J)
    return _calibration(x, cov, against)


def _calibration(x, cov, against: str) -> CellCalibration:
    """The calibration of (gain, offset) ``x`` (m, 2) with covariances ``cov`` (m, 2, 2), a
    warning per cell whose gain differs from 1 or offset from 0 beyond its 95 % interval."""
    s = np.sqrt(np.clip(np.diagonal(cov, axis1=1, axis2=2), 0, None))
    warns = []
    for j in range(len(x)):
        g, o = x[j]
        if abs(g - 1) > 1.96 * s[j, 0] or abs(o) > 1.96 * s[j, 1]:
            warns.append(f"load cell {j + 1} disagrees with {against}: gain {g:.4f} +- "
                         f"{1.96 * s[j, 0]:.4f}, offset {o:+.3g} +- {1.96 * s[j, 1]:.3g} N "
                         "(95 %): recalibrate the cell or check its wiring and zero.")
    return CellCalibration(x[:, 0], x[:, 1], s[:, 0], s[:, 1], against, tuple(warns))


def calibrate_cells_wrench(reg, W_all, sig, wf, idx, theta, cov_theta, chunk: int,
                           rho: float) -> CellCalibration:
    """The load cells against the free motion's dynamics in the wrench space: on the kept
    samples, the forces each cell's reading stands for, ``tau_j = a_j tau_meas_j + b_j``,
    jointly from

        F[S W (a o tau_meas + b)] = S F[Z] theta,

    all six rows (moments at the platform's radius), least squares with HAC covariance, the
    estimate's covariance added by the delta method (the fit is linear in ``theta``: its
    Jacobian ``(X^T X)^-1 X^T S F[Z]`` is exact); reported as the cells' gain ``g = 1 / a`` and
    offset ``o = -b / a`` (``tau_meas = g tau + o``, as :func:`cells_from_design`), first-order
    propagated. The reading sits in the regressor; its noise after the matched filter is far
    below the swing's tension changes (errors in variables of second order). Unlike
    ``(S W)^+ S Z theta`` (a tension per cable from the identified wrench), nothing is
    inverted: the 4-cable ``W``'s poorly conditioned directions no longer amplify the wrench's
    error; the cells are read where their forces are seen (the cable wrenches' span), the free
    directions only add residual.

    Parameters
    ----------
    reg : the matched-filter regression of the kept samples (``wrench_block`` gives F[Z])
    W_all : (n, 6, m) wrench matrices at every aligned sample
    sig : AlignedSignals (its tensions, N, at the pose times)
    wf : the matched filter (callable on (n, k) channels)
    idx : (n_kept,) the kept samples in ``sig``
    theta, cov_theta : the platform estimate and covariance (reference included)
    chunk : int
    rho : float
        Platform radius, m.

    Returns
    -------
    CellCalibration
    """
    S = np.array([1.0] * 3 + [1.0 / rho] * 3)
    n, _, m = W_all.shape
    SW = S[None, :, None] * np.asarray(W_all, float)
    tau = np.asarray(sig.tension, float)
    Xg = np.asarray(wf((SW * tau[:, None, :]).reshape(n, -1), np.ones(6 * m))).reshape(n, 6, m)
    Xo = np.asarray(wf(SW.reshape(n, -1), np.ones(6 * m))).reshape(n, 6, m)
    X = np.concatenate([Xg, Xo], axis=2)[idx]
    q = len(theta)
    T = np.empty((len(idx), 6, q))
    for i0 in range(0, len(idx), chunk):
        i1 = min(len(idx), i0 + chunk)
        T[i0:i1] = S[None, :, None] * np.asarray(reg.wrench_block(i0, i1)[0])
    y = T @ np.asarray(theta, float)
    names = tuple(f"g_{j + 1}" for j in range(m)) + tuple(f"o_{j + 1}" for j in range(m))
    res = least_squares_blocks(lambda i0, i1: (X[i0:i1], y[i0:i1]), len(idx), names,
                               covariance="hac", chunk=chunk)
    Xs, Ts = X.reshape(-1, 2 * m), T.reshape(-1, q)
    J = np.linalg.solve(Xs.T @ Xs, Xs.T @ Ts)
    C = res.cov + J @ cov_theta @ J.T
    x, cov = np.empty((m, 2)), np.empty((m, 2, 2))
    for j in range(m):  # tau = a tau_meas + b  ->  tau_meas = g tau + o: g = 1/a, o = -b/a
        a, b = res.x[j], res.x[m + j]
        x[j] = 1.0 / a, -b / a
        D = np.array([[-1.0 / a ** 2, 0.0], [b / a ** 2, -1.0 / a]])
        cov[j] = D @ C[np.ix_([j, m + j], [j, m + j])] @ D.T
    return _calibration(x, cov, "the free motion's dynamics")
