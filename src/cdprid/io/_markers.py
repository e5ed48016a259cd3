# ruff: noqa: F722  (jaxtyping shape strings)
"""Rigid-body pose from marker trajectories: the one Kabsch/Horn fit of every importer.

Used by the UACDPR importer (raw Vicon exports, :mod:`cdprid.io._vicon`) and the C3D importer
(:mod:`cdprid.io._c3d`). The body's marker layout ``M_m`` (k, 3) is either given or estimated
from the data (:func:`estimate_layout`): an initial layout from a reference frame, then
alternately (1) fit every frame by Kabsch (:func:`kabsch`) and (2) replace the layout by the
mean, over frames, of the measured markers brought back into the marker frame
(``V_R_M^T (V_m - V_p_M)``). The gauge of the marker frame ``M`` is fixed after every
iteration: its origin is the layout position of one chosen marker (``origin_marker``) and its
axes are the measurement axes at the reference frame (so ``V_R_M = I`` there).

Frames with fewer than three seen markers get NaN poses: gaps are reported by the callers,
never bridged here.

Names carry their frame: ``V_`` measurement (motion-capture) frame, ``M_`` marker frame;
``V_R_M`` rotates marker-frame vectors into the measurement frame and ``V_p_M`` is the
marker-frame origin.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from jaxtyping import Float

from cdprid.base import InputError

__all__ = ["MarkerFit", "kabsch", "fit_rigid_body", "estimate_layout"]


def kabsch(M_m: Float[np.ndarray, "k 3"], V_m: Float[np.ndarray, "*batch k 3"],
           weights: Float[np.ndarray, " k"] | None = None
           ) -> tuple[Float[np.ndarray, "*batch 3 3"], Float[np.ndarray, "*batch 3"]]:
    """Rigid transform that best maps a layout onto measured points (Kabsch/Horn, SVD).

    Minimises ``sum_j w_j |V_R_M M_m_j + V_p_M - V_m_j|^2`` over rotations (det = +1).

    Parameters
    ----------
    M_m : array (k, 3)
        Layout, body frame.
    V_m : array (..., k, 3)
        Measured points (batched over leading axes); NaN rows are ignored.
    weights : array (k,), optional

    Returns
    -------
    V_R_M : ndarray (..., 3, 3)
    V_p_M : ndarray (..., 3)
    """
    M_m = np.asarray(M_m, float)
    V_m = np.asarray(V_m, float)
    w = np.ones(M_m.shape[0]) if weights is None else np.asarray(weights, float)
    ok = np.all(np.isfinite(V_m), axis=-1)
    W = np.where(ok, w, 0.0)  # (..., k)
    V = np.where(ok[..., None], V_m, 0.0)
    sw = W.sum(-1, keepdims=True)
    if np.any(sw <= 0):
        raise InputError("kabsch: a frame has no valid marker.")
    cM = np.einsum("...j,jd->...d", W, M_m) / sw
    cV = np.einsum("...j,...jd->...d", W, V) / sw
    A = M_m - cM[..., None, :]
    B = V - cV[..., None, :]
    H = np.einsum("...j,...ja,...jb->...ab", W, A, B)  # sum w a b^T
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    d = np.where(d == 0, 1.0, d)
    D = np.zeros(H.shape)
    D[..., 0, 0] = 1.0
    D[..., 1, 1] = 1.0
    D[..., 2, 2] = d
    R = np.swapaxes(Vt, -1, -2) @ D @ np.swapaxes(U, -1, -2)
    p = cV - np.einsum("...ab,...b->...a", R, cM)
    return R, p


@dataclasses.dataclass(frozen=True)
class MarkerFit:
    """Result of a rigid-body fit of marker trajectories.

    Attributes
    ----------
    M_m : ndarray (k, 3)
        Marker layout, marker frame, m.
    V_R_M : ndarray (n, 3, 3)
    V_p_M : ndarray (n, 3)
        Pose of the marker frame in the measurement frame (NaN for frames with < 3 markers).
    residual : ndarray (n, k)
        Distance of each measured marker from its fitted position, m (NaN when missing).
    n_iter : int
    origin_marker : int
        0-based index of the marker at the marker-frame origin.
    reference_frame : int
        0-based row whose measurement axes define the marker-frame axes.
    """

    M_m: np.ndarray
    V_R_M: np.ndarray
    V_p_M: np.ndarray
    residual: np.ndarray
    n_iter: int
    origin_marker: int
    reference_frame: int

    @property
    def rms_per_marker(self) -> np.ndarray:
        """RMS residual of each marker over the frames where it was seen, m."""
        return np.sqrt(np.nanmean(self.residual**2, axis=0))

    @property
    def rms(self) -> float:
        """RMS residual over all seen markers, m."""
        return float(np.sqrt(np.nanmean(self.residual**2)))


def fit_rigid_body(V_m: Float[np.ndarray, "n k 3"], M_m: Float[np.ndarray, "k 3"],
                   min_markers: int = 3) -> tuple[Float[np.ndarray, "n 3 3"],
                                                  Float[np.ndarray, "n 3"],
                                                  Float[np.ndarray, "n k"]]:
    """Fit every frame to a known layout; frames with fewer than ``min_markers`` get NaN.

    Returns
    -------
    V_R_M : (n, 3, 3), V_p_M : (n, 3), residual : (n, k) in m
    """
    V_m = np.asarray(V_m, float)
    n = V_m.shape[0]
    ok = np.all(np.isfinite(V_m), axis=2)
    good = ok.sum(1) >= max(3, min_markers)
    R = np.full((n, 3, 3), np.nan)
    p = np.full((n, 3), np.nan)
    if good.any():
        R[good], p[good] = kabsch(M_m, V_m[good])
    pred = np.einsum("nab,kb->nka", R, M_m) + p[:, None, :]
    res = np.linalg.norm(pred - V_m, axis=2)
    return R, p, res


def _gauge(M_m, R_ref, p_ref, origin_marker):
    """Re-express a layout so that V_R_M(ref) = I and the origin is at ``origin_marker``."""
    L = M_m @ R_ref.T  # marker vectors in measurement axes at the reference frame
    return L - L[origin_marker]


def estimate_layout(V_m: Float[np.ndarray, "n k 3"], origin_marker: int = 0,
                    reference_frame: int | None = None,
                    n_iter: int = 10, tol: float = 1e-9) -> MarkerFit:
    """Estimate a rigid marker layout from the trajectories and fit every frame to it.

    Parameters
    ----------
    V_m : array (n, k, 3)
        Marker positions, measurement frame, m (NaN = missing).
    origin_marker : int
        0-based index of the marker taken as the marker-frame origin.
    reference_frame : int, optional
        0-based row whose measurement axes define the marker-frame axes; default: the first frame
        where all markers are seen.
    n_iter : int
        Maximum number of fit / re-estimate iterations.
    tol : float
        Stop when the layout changes by less than this, m.

    Returns
    -------
    MarkerFit

    Raises
    ------
    ValueError
        When no frame shows all markers, or a marker is never seen.
    """
    V_m = np.asarray(V_m, float)
    n, k, _ = V_m.shape
    ok = np.all(np.isfinite(V_m), axis=2)
    if not 0 <= origin_marker < k:
        raise InputError(f"origin_marker {origin_marker} is out of range for {k} markers.")
    if np.any(ok.sum(0) == 0):
        raise InputError(f"marker {int(np.argmin(ok.sum(0))) + 1} is never seen in the data.")
    full = np.nonzero(ok.all(1))[0]
    if reference_frame is None:
        if full.size == 0:
            raise InputError("no frame shows all markers, so no initial layout can be formed.")
        reference_frame = int(full[0])
    if not ok[reference_frame].all():
        raise InputError(f"reference frame {reference_frame} does not show all markers.")
    # initial layout: the reference frame (median of the next frames where all markers show)
    near = full[(full >= reference_frame) & (full < reference_frame + 10)]
    M_m = np.median(V_m[near], axis=0)
    M_m = M_m - M_m[origin_marker]
    it = 0
    while it < n_iter:
        it += 1
        R, p, _ = fit_rigid_body(V_m, M_m)
        back = np.einsum("nba,nkb->nka", R, V_m - p[:, None, :])  # R^T (V_m - p)
        new = np.nanmean(back, axis=0)
        Rr, pr = kabsch(new, V_m[reference_frame])
        new = _gauge(new, Rr, pr, origin_marker)
        change = float(np.max(np.abs(new - M_m)))
        M_m = new
        if change < tol:
            break
    R, p, res = fit_rigid_body(V_m, M_m)
    return MarkerFit(M_m, R, p, res, it, origin_marker, reference_frame)
