"""The data and the result of the geometric calibration (:mod:`cdprid.identify._calibration`).

Frames: ``B`` base, ``V`` Vicon, ``M`` marker frame, ``P`` platform frame.
"""

from __future__ import annotations

import dataclasses

import numpy as np

__all__ = ["CalibrationData", "CalibrationResult"]


@dataclasses.dataclass(frozen=True)
class CalibrationData:
    """Samples used by the calibration (one row per motion-capture frame).

    Attributes
    ----------
    t : ndarray (n,)
    V_R_M : ndarray (n, 3, 3)
        Rotation marker frame -> Vicon frame.
    V_p_M : ndarray (n, 3)
        Marker-frame origin, Vicon frame, m.
    swivel : ndarray (n, m) or None
        Measured swivel angles, rad (encoder zero arbitrary); None to use lengths only.
    """

    t: np.ndarray
    V_R_M: np.ndarray
    V_p_M: np.ndarray
    swivel: np.ndarray | None = None

    def subsample(self, step: int) -> CalibrationData:
        """Every ``step``-th sample.

        Parameters
        ----------
        step : int
            Positive stride.

        Returns
        -------
        CalibrationData
        """
        sl = slice(None, None, step)
        return CalibrationData(self.t[sl], self.V_R_M[sl], self.V_p_M[sl],
                               None if self.swivel is None else self.swivel[sl])


@dataclasses.dataclass(frozen=True)
class CalibrationResult:
    """Estimated geometry, its standard deviations and the residuals before/after.

    Attributes
    ----------
    anchors : {"config", "free"}
    B_R_V, B_p_V : ndarray (3, 3), (3,)
        Vicon frame -> base frame.
    M_R_P, M_p_P : ndarray (3, 3), (3,) or None
        Platform frame in the marker frame (``anchors="config"``).
    M_b : ndarray (m, 3)
        Attachment points, marker frame, m (always filled: ``M_R_P P_b + M_p_P`` in config
        mode).
    lengths : ndarray (m,)
        Constant cable lengths, m (pulley entry point to attachment, arc included).
    swivel_offset : ndarray (m,)
        Encoder offsets delta_i, rad.
    params : dict name -> ndarray
        Raw parameter vector pieces (rotation vectors ``*_r_*`` are corrections of ``R0``).
    sigma : dict name -> ndarray
        Standard deviations of ``params`` (rotation vectors: rad, about the estimate).
    rms_before, rms_after : dict
        ``{"length_m": ..., "swivel_rad": ...}``: RMS residuals of the naive start (Vicon =
        base, marker frame = platform frame, best constants) and of the solution.
    rms_per_cable : dict
        ``{"length_m": (m,), "swivel_rad": (m,)}`` after the fit.
    n_samples : int
    condition : float
        Condition number of the weighted Jacobian.
    swivel_sign : float
    """

    anchors: str
    B_R_V: np.ndarray
    B_p_V: np.ndarray
    M_R_P: np.ndarray | None
    M_p_P: np.ndarray | None
    M_b: np.ndarray
    lengths: np.ndarray
    swivel_offset: np.ndarray
    params: dict
    sigma: dict
    rms_before: dict
    rms_after: dict
    rms_per_cable: dict
    n_samples: int
    condition: float
    swivel_sign: float

    def as_dict(self) -> dict:
        """Plain-Python summary (for meta.toml / JSON).

        Returns
        -------
        dict
            The fields as nested lists and floats (rotations as 3x3 lists, lengths in m, angles
            in rad); ``M_R_P``/``M_p_P`` only with ``anchors="config"``; ``params`` left out.
        """
        out = {
            "anchors": self.anchors,
            "B_R_V": self.B_R_V.tolist(),
            "B_p_V": self.B_p_V.tolist(),
            "M_b": self.M_b.tolist(),
            "lengths": self.lengths.tolist(),
            "swivel_offset": self.swivel_offset.tolist(),
            "sigma": {k: np.asarray(v).tolist() for k, v in self.sigma.items()},
            "rms_before": dict(self.rms_before),
            "rms_after": dict(self.rms_after),
            "rms_per_cable": {k: np.asarray(v).tolist() for k, v in self.rms_per_cable.items()},
            "n_samples": self.n_samples,
            "condition": self.condition,
            "swivel_sign": self.swivel_sign,
        }
        if self.M_R_P is not None:
            out["M_R_P"] = self.M_R_P.tolist()
            out["M_p_P"] = self.M_p_P.tolist()
        return out
