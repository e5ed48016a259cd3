"""A structure signal that is a finding's own signature does not displace it (issue 37).

Backward elimination keeps a finding only when it is needed given the other findings and the
unexplained structure (:func:`cdprid.diagnosis._selection.backward_stage`), so that a
vocabulary effect fitting part of a structure it does not explain is not named as its cause.
Some structure signals, though, reproduce the form of a vocabulary effect exactly: "sign of
cable velocity" (``W_i sign(dl_i/dt)``, one column per cable) spans friction on every pulley
(its Coulomb column is their sum), and a per-cable signal of the sign of the tension rate
would span a hysteretic load cell. Given such a signal, the effect is never needed (its
columns lie in the signal's span), whatever the data say: on the floor-winch 8-cable robot
(seed 2) friction on every pulley was removed that way and the clock offset left to alias it.

The rule here: when some combination of a finding's columns is reproduced by a structure
signal (their largest canonical correlation on the training rows is at least
:data:`OWN_SIGNATURE`), the finding is tested against that signal only where it is not its
own signature: the signal's columns with the finding's columns projected out. The structure
keeps what the finding cannot explain (e.g. friction that differs between cables); the part
of it the finding reproduces belongs to the finding. A signal that merely correlates with a
finding (canonical correlation below the threshold) is used whole, as before.
"""

from __future__ import annotations

import numpy as np

#: a structure signal is a finding's own signature when the largest canonical correlation
#: between the finding's columns and the signal's (training rows) reaches this
OWN_SIGNATURE = 0.95


def _basis(M, rtol: float = 1e-9) -> np.ndarray:
    """Orthonormal basis of the column span of ``M`` (2-D), rank-revealing."""
    if M.shape[1] == 0:
        return M
    U, sv, _ = np.linalg.svd(M, full_matrices=False)
    return U[:, sv > rtol * max(float(sv[0]), 1e-300)] if sv.size else U[:, :0]


def canonical_correlation(A, B) -> float:
    """Largest canonical correlation (uncentred: the regressions have no intercept) between
    the columns of ``A`` and ``B``, ``(n, 6, p)`` and ``(n, 6, q)`` (or 2-D); 0 when either
    has no column of nonzero norm."""
    Qa = _basis(np.asarray(A, float).reshape(-1, np.shape(A)[-1]))
    Qb = _basis(np.asarray(B, float).reshape(-1, np.shape(B)[-1]))
    if Qa.shape[1] == 0 or Qb.shape[1] == 0:
        return 0.0
    return float(min(1.0, np.linalg.svd(Qa.T @ Qb, compute_uv=False)[0]))


def without_own_signature(C, F, train, own: float = OWN_SIGNATURE):
    """The structure signal ``F`` as nuisance for the finding whose columns are ``C``.

    Parameters
    ----------
    C : (n, 6, p) the finding's weighted columns
    F : (n, 6, q) the structure signal's weighted columns
    train : (n,) bool, the training rows
    own : float
        Canonical-correlation threshold of :data:`OWN_SIGNATURE`.

    Returns
    -------
    F_used : (n, 6, q)
        ``F`` unchanged when it is not the finding's signature, else ``F`` minus its least
        squares projection on ``C`` (coefficients from the training rows).
    rho : float
        The largest canonical correlation between ``C`` and ``F`` on the training rows.
    """
    rho = canonical_correlation(C[train], F[train])
    if rho < own:
        return F, rho
    p, q = C.shape[2], F.shape[2]
    b, *_ = np.linalg.lstsq(C[train].reshape(-1, p), F[train].reshape(-1, q), rcond=None)
    return F - np.einsum("nip,pq->niq", C, b), rho
