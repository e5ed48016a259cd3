"""Raw Vicon marker exports and rigid-body pose fitting (Kabsch/Horn).

A Vicon Nexus "Trajectories" export (tab- or comma-separated) looks like::

    Trajectories
    100                                   <- frame rate, Hz
    ,,platform:points1,,,platform:points2,...      <- marker names (every third column)
    Frame,Sub Frame,X,Y,Z,X,Y,Z,...
    ,,mm,mm,mm,mm,mm,mm,...
    1,0,80.37,-39.55,806.31,...

Missing markers appear as empty fields (or, in some exports, as exact zeros); both are read
as NaN. :func:`read_vicon_trajectories` returns positions in metres.

Pose from markers. The body's marker layout ``M_m`` (k, 3) is not known beforehand; it is
estimated from the data (:func:`estimate_layout`): an initial layout from a reference frame,
then alternately (1) fit every frame by Kabsch (:func:`kabsch`) and (2) replace the layout by
the mean, over frames, of the measured markers brought back into the marker frame
(``V_R_M^T (V_m - V_p_M)``). The gauge of the marker frame ``M`` is fixed after every
iteration: its origin is the layout position of one chosen marker (``origin_marker``; the
UACDPR authors use marker 9, the lowest one) and its axes are the Vicon axes at the
reference frame (so ``V_R_M = I`` there). The relation between this marker frame and the
robot's platform frame is a nuisance that :mod:`cdprid.calibration` estimates.

Names carry their frame: ``V_`` Vicon frame, ``M_`` marker frame; ``V_R_M`` rotates
marker-frame vectors into the Vicon frame and ``V_p_M`` is the marker-frame origin.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

__all__ = [
    "ViconTrajectories",
    "MarkerFit",
    "read_vicon_trajectories",
    "kabsch",
    "fit_rigid_body",
    "estimate_layout",
]


@dataclasses.dataclass(frozen=True)
class ViconTrajectories:
    """Marker trajectories of one Vicon export.

    Attributes
    ----------
    frame : ndarray (n,) of int
        Vicon frame numbers (1-based in Nexus exports).
    rate_hz : float
        Frame rate from the header.
    names : tuple of str
        Marker names, e.g. ``platform:points1``.
    V_m : ndarray (n, k, 3)
        Marker positions, Vicon frame, m; NaN where a marker was not seen.
    """

    frame: np.ndarray
    rate_hz: float
    names: tuple
    V_m: np.ndarray

    @property
    def t(self) -> np.ndarray:
        """Time of each frame, s, with frame 1 at t = 0: ``(frame - 1) / rate``."""
        return (self.frame - 1) / self.rate_hz


def _split(line: str) -> list[str]:
    sep = "\t" if "\t" in line else ","
    return [f.strip() for f in line.rstrip("\r\n").split(sep)]


def read_vicon_trajectories(path: str | Path, units: str | None = None) -> ViconTrajectories:
    """Read a Vicon Nexus "Trajectories" export (5 header lines, then numeric rows).

    Parameters
    ----------
    path : file
    units : {"mm", "m"}, optional
        Overrides the units row of the header (default: read it; ``mm`` when absent).

    Raises
    ------
    ValueError
        One sentence naming the file and the line: a missing file, a header that is not a
        Vicon trajectories header, a non-numeric value or a truncated row.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: Vicon file is missing.")
    try:
        lines = path.read_text(encoding="utf-8", errors="strict").splitlines()
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (a Vicon trajectories export was expected).") \
            from None
    if len(lines) < 6:
        raise ValueError(f"{path}: has {len(lines)} lines, fewer than the 5 header lines and one "
                         "data row of a Vicon trajectories export.")
    if not lines[0].strip().lower().startswith("trajectories"):
        raise ValueError(f"{path}: line 1 is {lines[0].strip()[:40]!r}, not 'Trajectories' "
                         "(expected a Vicon Nexus trajectories export).")
    try:
        rate = float(_split(lines[1])[0])
    except ValueError:
        rate = float("nan")
    if not np.isfinite(rate) or rate <= 0:
        raise ValueError(f"{path}: line 2 should hold the frame rate in Hz, got "
                         f"{lines[1].strip()[:40]!r}.")
    head = _split(lines[3])
    if len(head) < 5 or head[0].lower() != "frame" or head[1].lower() != "sub frame":
        raise ValueError(f"{path}: line 4 should start with 'Frame', 'Sub Frame', 'X', 'Y', 'Z', "
                         f"got {', '.join(head[:5])!r}.")
    coord = [h for h in head[2:] if h]
    if len(coord) % 3 != 0 or any(c.upper() != "XYZ"[j % 3] for j, c in enumerate(coord)):
        raise ValueError(f"{path}: line 4 should list X, Y, Z columns after 'Sub Frame'.")
    k = len(coord) // 3
    ncol = 2 + 3 * k
    name_fields = _split(lines[2])
    names = tuple(f for f in name_fields if f)
    if len(names) != k:
        names = tuple(f"marker{j + 1}" for j in range(k))
    unit_fields = [u for u in _split(lines[4]) if u]
    if units is None:
        units = unit_fields[0] if unit_fields else "mm"
    scale = {"mm": 1e-3, "m": 1.0}.get(units.lower())
    if scale is None:
        raise ValueError(f"{path}: line 5 gives the unit {units!r}; only 'mm' and 'm' are known.")
    rows = []
    for lineno, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        fields = _split(line)
        while len(fields) > ncol and fields[-1] == "":
            fields.pop()
        if len(fields) < ncol:
            raise ValueError(f"{path}: line {lineno} is truncated ({len(fields)} fields, "
                             f"{ncol} expected).")
        if len(fields) > ncol:
            raise ValueError(f"{path}: line {lineno} has {len(fields)} fields, {ncol} expected.")
        row = []
        for j, f in enumerate(fields):
            if f == "" and j >= 2:
                row.append(np.nan)
                continue
            try:
                row.append(float(f))
            except ValueError:
                raise ValueError(f"{path}: line {lineno}, field {j + 1}: {f[:20]!r} is not a "
                                 "number.") from None
        rows.append(row)
    if not rows:
        raise ValueError(f"{path}: no data rows after the 5 header lines.")
    data = np.asarray(rows, float)
    frame = data[:, 0]
    if not np.all(np.isfinite(frame)) or np.any(np.diff(frame) <= 0):
        raise ValueError(f"{path}: the Frame column is not strictly increasing.")
    V_m = data[:, 2:].reshape(len(data), k, 3) * scale
    zero = np.all(V_m == 0.0, axis=2)
    V_m[zero] = np.nan
    V_m[~np.all(np.isfinite(V_m), axis=2)] = np.nan
    return ViconTrajectories(frame.astype(int), rate, names, V_m)


# --------------------------------------------------------------------------- Kabsch / Horn


def kabsch(M_m, V_m, weights=None):
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
        raise ValueError("kabsch: a frame has no valid marker.")
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
        Pose of the marker frame in the Vicon frame (NaN for frames with < 3 markers).
    residual : ndarray (n, k)
        Distance of each measured marker from its fitted position, m (NaN when missing).
    n_iter : int
    origin_marker : int
        0-based index of the marker at the marker-frame origin.
    reference_frame : int
        0-based row whose Vicon axes define the marker-frame axes.
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


def fit_rigid_body(V_m, M_m, min_markers: int = 3):
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
    L = M_m @ R_ref.T  # marker vectors in Vicon axes at the reference frame
    return L - L[origin_marker]


def estimate_layout(V_m, origin_marker: int = 0, reference_frame: int | None = None,
                    n_iter: int = 10, tol: float = 1e-9) -> MarkerFit:
    """Estimate a rigid marker layout from the trajectories and fit every frame to it.

    Parameters
    ----------
    V_m : array (n, k, 3)
        Marker positions, Vicon frame, m (NaN = missing).
    origin_marker : int
        0-based index of the marker taken as the marker-frame origin.
    reference_frame : int, optional
        0-based row whose Vicon axes define the marker-frame axes; default: the first frame
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
        raise ValueError(f"origin_marker {origin_marker} is out of range for {k} markers.")
    if np.any(ok.sum(0) == 0):
        raise ValueError(f"marker {int(np.argmin(ok.sum(0))) + 1} is never seen in the data.")
    full = np.nonzero(ok.all(1))[0]
    if reference_frame is None:
        if full.size == 0:
            raise ValueError("no frame shows all markers, so no initial layout can be formed.")
        reference_frame = int(full[0])
    if not ok[reference_frame].all():
        raise ValueError(f"reference frame {reference_frame} does not show all markers.")
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
