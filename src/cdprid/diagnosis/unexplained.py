"""Stage 6 of the diagnosis: what the extended model leaves unexplained.

The residual is tested against generic signals that are not effects of the vocabulary (sign
of the cable velocity, tension level, pose, slow drift); what is significant is reported
under ``unexplained`` and takes part in the backward elimination, so that a vocabulary effect
fitting part of a structure it does not explain is not named as its cause.
"""

from __future__ import annotations

import numpy as np
from scipy import stats

from .testing import partial_wald

#: generic signals the residual of the extended model is tested against (unexplained stage)
STRUCTURE_SIGNALS = ("sign of cable velocity", "tension level", "pose", "time (slow drift)")


def structure_features(W_all, v, om, tension, position, t, use) -> dict:
    """Generic residual-structure regressors, unfiltered, ``(n, 6, q)`` each.

    These are not effects of the vocabulary: they describe what a remaining residual is
    *like*. ``sign of cable velocity`` is ``W_i sign(dl_i/dt)`` per cable (a Coulomb-like
    force along each cable, with ``dl/dt = -W^T [v; omega]``); ``tension level`` is
    ``W_i (z_i^2 - 1)`` with z_i the standardised tension (a load cell that is not linear);
    ``pose`` is a force linear in the position, per force axis; ``time (slow drift)`` is a
    force that drifts as Legendre polynomials of degree 1-3 in time, per force axis.

    Parameters
    ----------
    W_all : (n, 6, m) nominal wrench matrices
    v, om : (n, 3) platform velocity and angular rate
    tension : (n, m) tensions at the pose times
    position : (n, 3)
    t : (n,)
    use : (n,) bool, the samples that are fitted

    Returns
    -------
    dict
        Signal name (one of :data:`STRUCTURE_SIGNALS`) -> array ``(n, 6, q)``.
    """
    n = W_all.shape[0]
    twist = np.concatenate([v, om], axis=1)
    ldot = -np.einsum("nim,ni->nm", W_all, twist)
    tz = (tension - tension[use].mean(0)) / np.maximum(tension[use].std(0), 1e-9)
    pc = position - position[use].mean(0)
    tu = t[use]
    s = 2.0 * (t - tu[0]) / max(tu[-1] - tu[0], 1e-9) - 1.0
    legendre = [s, 0.5 * (3 * s**2 - 1), 0.5 * (5 * s**3 - 3 * s)]
    P = np.zeros((n, 6, 9))
    D = np.zeros((n, 6, 9))
    for j in range(3):
        for k in range(3):
            P[:, j, 3 * j + k] = pc[:, k]
            D[:, j, 3 * j + k] = legendre[k]
    return {
        "sign of cable velocity": W_all * np.sign(ldot)[:, None, :],
        "tension level": W_all * (tz**2 - 1.0)[:, None, :],
        "pose": P,
        "time (slow drift)": D,
    }


def _where(name: str, beta, V) -> str:
    """Which cables / force axes a structure sits on (coefficients with |t| > 3)."""
    tstat = np.abs(beta) / np.sqrt(np.clip(np.diag(V), 1e-300, None))
    if name in ("sign of cable velocity", "tension level"):
        idx = [i + 1 for i in np.nonzero(tstat > 3)[0]]
        return ("load cells of cables " + ", ".join(map(str, idx))) if idx else "all cables"
    axes = sorted({"xyz"[i // 3] for i in np.nonzero(tstat > 3)[0]})
    return ("force along " + ", ".join(axes)) if axes else "force rows"


def structure_tests(feats: dict, Z, y, wrow, lags: int, alpha: float) -> list:
    """Test the residual of ``y ~ Z`` for generic structure, strongest first (stepwise).

    Each signal is tested (HAC Wald, Bonferroni over the signals) given the model and the
    signals already found significant, so that one structure is not reported again under
    the name of a correlated signal.

    Parameters
    ----------
    feats : dict
        Signal name -> weighted, matched-filtered regressors ``(n, 6, q)`` (training rows).
    Z : (n, 6, p)
        The extended model's columns (weighted, training rows).
    y : (n, 6)
        Its target (weighted, training rows).
    wrow : (6,) row weights (to give sizes in newtons)
    lags : int
        HAC lag window.
    alpha : float
        Family-wise level; every signal is returned, ``significant`` marks p < alpha.

    Returns
    -------
    list of dict
        ``where``, ``size`` (RMS force in N of the fitted structure), ``correlates_with``,
        ``p_value`` (Bonferroni over the signals), ``coefficients`` and ``significant``.
    """
    out: list = []
    left = dict(feats)
    while left:
        tests = _structure_step(left, Z, y, wrow, lags, alpha, len(feats))
        if not tests:
            break
        best = min(tests, key=lambda u: u["p_value"])
        if not best["significant"]:
            return out + sorted(tests, key=lambda u: u["p_value"])
        out.append(best)
        Z = np.concatenate([Z, left.pop(best["correlates_with"])], axis=2)
    return out


def _structure_step(feats, Z, y, wrow, lags, alpha, n_signals):
    n, _, p = Z.shape
    Q = np.linalg.qr(Z.reshape(-1, p))[0]

    def partial(M):
        M2 = M.reshape(n * 6, -1)
        return (M2 - Q @ (Q.T @ M2)).reshape(n, 6, -1)

    yt = partial(y)[:, :, 0]
    out = []
    for name, F in feats.items():
        Ft = partial(F)
        keep = np.linalg.norm(Ft.reshape(-1, Ft.shape[2]), axis=0) > 1e-9 * max(
            1.0, float(np.linalg.norm(F)))
        Ft = Ft[:, :, keep]
        if Ft.shape[2] == 0:
            continue
        stat, beta, V = partial_wald(Ft, yt, lags)
        pv = float(min(1.0, stats.chi2.sf(stat, Ft.shape[2]) * n_signals))
        fit = np.einsum("niq,q->ni", Ft, beta) / wrow[None, :]
        out.append({
            "where": _where(name, beta, V),
            "size": float(np.sqrt(np.mean(fit[:, :3] ** 2))),
            "correlates_with": name,
            "p_value": pv,
            "coefficients": [float(b) for b in beta],
            "significant": bool(pv < alpha),
        })
    return out
