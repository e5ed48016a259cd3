"""The exact safety certificate of a trajectory (numpy and the CasADi/HiGHS LP, no smoothing).

Every limit of :class:`cdprid.excitation.SafetyLimits` is checked on the samples given
(``cdprid excite`` passes the 100 Hz grid of the written CSV for tensions and clearances, and a
500 Hz grid for the kinematic limits):

- workspace box (position of P), norm of the acceleration and of the jerk of P, tilt (rotation
  angle ``2 atan2(|q_vec|, |q_w|)`` from the identity), norms of the angular velocity and
  acceleration, cable speeds ``|dl_i/dt| = |W_i^T [v; omega]|``;
- cable-cable and cable-body clearance (:mod:`cdprid.model._clearance`);
- tension feasibility at the nominal platform and at every corner of the uncertainty box:
  the best of a few closed-form distributions ``tau = c (1 - W^+ W 1) + W^+ w`` (c the
  mid-range and fixed levels above tension_min, so the bound is monotone in tension_max)
  certifies a sample when it satisfies ``W tau = w`` within bounds; the samples where it does
  not, and the ones with the smallest closed-form margins, get the LP ``max s``
  (:func:`cdprid.model.feasibility_margin`). The robust margin is a proven lower bound of the
  worst-corner LP margin.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.core import regressors, wrench_matrices
from cdprid.excitation._safety import SafetyLimits, UncertaintyBox
from cdprid.model import (
    TrajectoryState,
    cable_body_distances,
    cable_cable_distances,
    feasibility_margin,
    quat_to_matrix,
)

__all__ = ["SafetyCertificate", "SafetySeries", "certify_trajectory", "kinematic_peaks",
           "limit_ratios", "robust_tension_margins", "safety_series"]

_TOL = 1e-9
_LP_BUDGET = 256


@dataclasses.dataclass(frozen=True)
class SafetyCertificate:
    """Peaks, limits and verdict of one trajectory.

    ``peaks`` maps each checked quantity to its worst value (max, or min for margins and
    clearances); ``failed`` lists one sentence per violated check (empty when certified).
    """

    peaks: dict
    failed: tuple
    robust_margin_N: float
    nominal_margin_N: float
    worst_corner: list
    n_corners: int
    n_lp: int

    @property
    def certified(self) -> bool:
        """True when no check failed."""
        return not self.failed

    def as_json(self) -> dict:
        """JSON of the certificate.

        Returns
        -------
        dict
            ``peaks``, ``failed_checks``, robust and nominal tension margins (N), worst corner,
            ``n_corners``, ``n_lp_solved`` and ``certified``.
        """
        return {"peaks": self.peaks, "failed_checks": list(self.failed),
                "robust_tension_margin_N": self.robust_margin_N,
                "nominal_tension_margin_N": self.nominal_margin_N,
                "worst_corner": self.worst_corner, "n_corners": self.n_corners,
                "n_lp_solved": self.n_lp, "certified": self.certified}


def _tilt(q):
    q = np.asarray(q)
    return 2.0 * np.arctan2(np.linalg.norm(q[:, 1:], axis=1), np.abs(q[:, 0]))


def kinematic_peaks(states: TrajectoryState) -> dict:
    """Largest |a|, |j| (of P), tilt, |omega|, |alpha| over the samples.

    Parameters
    ----------
    states : TrajectoryState

    Returns
    -------
    dict
        ``acceleration_m_s2``, ``jerk_m_s3``, ``tilt_rad``, ``angular_velocity_rad_s``,
        ``angular_acceleration_rad_s2`` (floats).
    """
    n = lambda x: float(np.max(np.linalg.norm(np.asarray(x), axis=1)))  # noqa: E731
    return {"acceleration_m_s2": n(states.a), "jerk_m_s3": n(states.j),
            "tilt_rad": float(np.max(_tilt(states.q))),
            "angular_velocity_rad_s": n(states.omega),
            "angular_acceleration_rad_s2": n(states.alpha)}


def limit_ratios(robot, states: TrajectoryState, lim: SafetyLimits) -> dict:
    """Peak over limit (dimensionless) of every kinematic limit and of the cable speed.

    Parameters
    ----------
    robot : CableRobot
    states : TrajectoryState
        Motion samples (n of each field).
    lim : SafetyLimits

    Returns
    -------
    dict
        ``{"acceleration": ..., "jerk": ..., "tilt": ..., "angular_velocity": ...,
        "angular_acceleration": ..., "cable_speed": ...}``; 1.0 means at the limit.
    """
    kin = kinematic_peaks(states)
    _, W, _ = _pose_arrays(robot, *(jnp.asarray(x) for x in (states.p, states.q, states.a,
                                                             states.omega, states.alpha)))
    tw = np.hstack([np.asarray(states.v), np.asarray(states.omega)])
    speed = float(np.max(np.abs(np.einsum("nim,ni->nm", np.asarray(W), tw))))
    return {"acceleration": kin["acceleration_m_s2"] / lim.acceleration_max,
            "jerk": kin["jerk_m_s3"] / lim.jerk_max, "tilt": kin["tilt_rad"] / lim.tilt_max,
            "angular_velocity": kin["angular_velocity_rad_s"] / lim.angular_velocity_max,
            "angular_acceleration": kin["angular_acceleration_rad_s2"]
            / lim.angular_acceleration_max,
            "cable_speed": speed / lim.cable_speed_max}


#: Centres of the closed-form distributions, N above tension_min: fixed values, so that a
#: looser tension_max never loses a distribution a tighter one had (the margin bound is then
#: monotone in the limits), plus the mid-range centre.
_CENTRES_ABOVE_MIN_N = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0)


def _centres(tmin: float, tmax: float) -> list[float]:
    """Centres c of the closed-form distributions: the mid-range and fixed levels above tmin."""
    return [0.5 * (tmin + tmax)] + [tmin + c for c in _CENTRES_ABOVE_MIN_N if tmin + c < tmax]


def _least_norm(W, w):
    """``v = 1 - W^+ W 1`` (n, m) and ``W^+ w`` (..., n, m): the distributions
    ``tau = c v + W^+ w`` of every centre c share them."""
    Wp = np.linalg.pinv(W)  # (n, m, 6)
    v = 1.0 - np.einsum("nmi,ni->nm", Wp, W.sum(axis=2))
    return v, np.einsum("nmi,...ni->...nm", Wp, w)


def _closed_form_margins(W, w, tmin, tmax):
    """Margins (k, n) of the best of a few least-norm distributions ``tau = c v + W^+ w`` with
    ``v = 1 - W^+ W 1`` (each exact where ``W tau = w``: a proven lower bound of the LP margin);
    -inf where ``W tau != w``. The centres c are the mid-range and fixed levels above
    ``tmin`` (a large ``tmax`` moves the mid-range far from what a suspended robot can hold)."""
    v, tau0 = _least_norm(W, w)  # (n, m), (k, n, m)
    resid = np.einsum("nim,knm->kni", W, tau0) - w
    ok = np.max(np.abs(resid), axis=-1) <= 1e-6 * (1.0 + np.max(np.abs(w), axis=-1))
    marg = np.full(tau0.shape[:2], -np.inf)
    for c in _centres(tmin, tmax):
        tau = tau0 + c * v[None]
        marg = np.maximum(marg, np.minimum(tau - tmin, tmax - tau).min(axis=-1))
    return np.where(ok, marg, -np.inf)


def _nominal_tensions(W, w, tmin: float, tmax: float) -> np.ndarray:
    """Per sample, the closed-form distribution (of the centres of :func:`_closed_form_margins`)
    with the largest margin: the nominal tension profile that is shown and written."""
    v, tau0 = _least_norm(W, w)  # (n, m), (n, m)
    taus = np.stack([tau0 + c * v for c in _centres(tmin, tmax)])  # (c, n, m)
    marg = np.minimum(taus - tmin, tmax - taus).min(axis=-1)  # (c, n)
    return taus[np.argmax(marg, axis=0), np.arange(W.shape[0])]


def robust_tension_margins(W, A_full, corners, tmin: float, tmax: float,
                           lp_budget: int = _LP_BUDGET):
    """Proven lower bounds of the LP tension margin at every corner and sample.

    Closed-form margins everywhere; the LP (:func:`cdprid.model.feasibility_margin`) where
    the closed form fails, where it is negative (up to 4096 pairs) and at the ``lp_budget``
    smallest closed-form margins (a closed-form margin >= 0 already proves feasibility: the LP
    only tightens it). Pairs not solved keep their closed-form margin (a lower bound of the LP
    one), so the minimum over all pairs is a lower bound of the true worst margin, and equal to
    it when the smallest LP margin is below the smallest unsolved closed-form margin.

    Parameters
    ----------
    W : array (n, 6, m)
        Wrench matrices.
    A_full : array (n, 6, 10)
        Full regressors.
    corners : array (k, 10)
        Parameter vectors (kg, kg m, kg m^2).
    tmin, tmax : float
        Tension limits, N.
    lp_budget : int
        Smallest closed-form margins always tightened by the LP.

    Returns
    -------
    margins : ndarray (k, n)
        Margins, N.
    n_lp : int
        Number of LPs solved.
    """
    W = np.asarray(W, float)
    w = np.einsum("nip,kp->kni", np.asarray(A_full, float), np.asarray(corners, float))
    cf = np.vstack([_closed_form_margins(W, w[k0:k0 + 128], tmin, tmax)
                    for k0 in range(0, w.shape[0], 128)])
    order = np.argsort(cf, axis=None)
    n_neg = int(np.sum(~(cf >= 0.0)))  # the order starts with them
    todo = order[:max(lp_budget, min(n_neg, 4096))]
    todo = np.union1d(todo, np.flatnonzero(~np.isfinite(cf.ravel())))
    out = cf.copy()
    if len(todo):
        k, i = np.unravel_index(todo, cf.shape)
        lp = np.atleast_1d(feasibility_margin(W[i], w[k, i], tmin, tmax))
        out[k, i] = np.maximum(lp, cf[k, i])
    return out, len(todo)


@jax.jit
def _pose_arrays(robot, p, q, a, omega, alpha):
    R = jax.vmap(quat_to_matrix)(q)
    W = wrench_matrices(robot, p, R)
    A = regressors("full", R, a, omega, alpha, robot.gravity)
    return R, W, A


def rest_margins(robot, points, lim: SafetyLimits, box: UncertaintyBox) -> np.ndarray:
    """Proven lower bounds (n,) of the robust tension margin (N) of the platform at rest at
    each of ``points`` (n, 3) with the nominal orientation, over the uncertainty box's
    corners (the static part of :func:`certify_trajectory`)."""
    p = np.atleast_2d(np.asarray(points, float))
    n = len(p)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    z = jnp.zeros((n, 3))
    _, W, A = (np.asarray(x) for x in _pose_arrays(robot, jnp.asarray(p), jnp.asarray(q), z, z,
                                                   z))
    corners = np.vstack([box.x_nominal[None], box.corners])
    marg, _ = robust_tension_margins(W, A, corners, lim.tension_min, lim.tension_max)
    return marg.min(axis=0)


@dataclasses.dataclass(frozen=True)
class SafetySeries:
    """Time series of every checked quantity on one grid (for the certificate and figures)."""

    t: np.ndarray
    tension_nominal: np.ndarray  # (n, m) centred least-norm distribution, nominal platform
    margin: np.ndarray  # (k, n) tension margin lower bounds, row 0 nominal, then the corners
    n_lp: int
    cable_speed: np.ndarray  # (n, m) |dl/dt|
    acceleration: np.ndarray  # (n,)
    jerk: np.ndarray
    tilt: np.ndarray
    angular_velocity: np.ndarray
    angular_acceleration: np.ndarray
    cable_cable: np.ndarray  # (n, k) checked pairs
    cable_body: np.ndarray | None  # (n, m)


def safety_series(robot, states: TrajectoryState, lim: SafetyLimits,
                  box: UncertaintyBox) -> SafetySeries:
    """Every checked quantity at the samples of ``states`` (exact: numpy and LP).

    Parameters
    ----------
    robot : CableRobot
    states : TrajectoryState
    lim : SafetyLimits
    box : UncertaintyBox

    Returns
    -------
    SafetySeries
    """
    R, W, A = (np.asarray(x) for x in _pose_arrays(
        robot, *(jnp.asarray(x) for x in (states.p, states.q, states.a, states.omega,
                                           states.alpha))))
    corners = np.vstack([box.x_nominal[None], box.corners])
    marg, n_lp = robust_tension_margins(W, A, corners, lim.tension_min, lim.tension_max)
    tau = _nominal_tensions(W, A @ box.x_nominal, lim.tension_min, lim.tension_max)
    v, om = np.asarray(states.v), np.asarray(states.omega)
    speeds = np.abs(np.einsum("nim,ni->nm", W, np.hstack([v, om])))
    p = np.asarray(states.p)
    nrm = lambda x: np.linalg.norm(np.asarray(x), axis=1)  # noqa: E731
    cb = cable_body_distances(robot, p, R) if robot.platform.body_min is not None else None
    return SafetySeries(np.asarray(states.t), tau, marg, n_lp, speeds, nrm(states.a),
                        nrm(states.j), _tilt(states.q), nrm(om), nrm(states.alpha),
                        cable_cable_distances(robot, p, R), cb)


def certify_trajectory(robot, states_grid: TrajectoryState, states_dense: TrajectoryState,
                       lim: SafetyLimits, box: UncertaintyBox) -> SafetyCertificate:
    """Exact check of every limit (module docstring).

    Parameters
    ----------
    robot : CableRobot
    states_grid : TrajectoryState
        Samples for tensions, clearances, workspace, speeds and kinematics.
    states_dense : TrajectoryState
        A denser grid for kinematics and workspace.
    lim : SafetyLimits
    box : UncertaintyBox

    Returns
    -------
    SafetyCertificate
        Peaks, failed checks (one sentence each), margins (N) and the worst corner.
    """
    peaks = {}
    failed = []

    def check(name, value, limit, unit, below=True):
        peaks[name] = value
        bad = value > limit * (1 + _TOL) if below else value < limit * (1 - _TOL)
        if bad:
            word = "exceeds" if below else "is below"
            failed.append(f"{name} {value:.4g} {unit} {word} the limit {limit:.4g} {unit}")

    kin = {k: max(a, b) for (k, a), b in zip(kinematic_peaks(states_dense).items(),
                                             kinematic_peaks(states_grid).values(), strict=True)}
    check("acceleration_m_s2", kin["acceleration_m_s2"], lim.acceleration_max, "m/s^2")
    check("jerk_m_s3", kin["jerk_m_s3"], lim.jerk_max, "m/s^3")
    check("tilt_rad", kin["tilt_rad"], lim.tilt_max, "rad")
    check("angular_velocity_rad_s", kin["angular_velocity_rad_s"], lim.angular_velocity_max,
          "rad/s")
    check("angular_acceleration_rad_s2", kin["angular_acceleration_rad_s2"],
          lim.angular_acceleration_max, "rad/s^2")
    lo, hi = np.asarray(lim.workspace_min), np.asarray(lim.workspace_max)
    p = np.vstack([np.asarray(states_dense.p), np.asarray(states_grid.p)])
    check("workspace_distance_m", float(np.min(np.minimum(p - lo, hi - p))), 0.0, "m", below=False)
    ser = safety_series(robot, states_grid, lim, box)
    marg = ser.margin
    check("cable_speed_m_s", float(ser.cable_speed.max()), lim.cable_speed_max, "m/s")
    cc = ser.cable_cable
    check("cable_cable_clearance_m", float(cc.min()) if cc.size else float("inf"),
          lim.cable_clearance, "m", below=False)
    if ser.cable_body is not None:
        check("cable_body_clearance_m", float(ser.cable_body.min()), lim.cable_clearance, "m",
              below=False)
    else:
        peaks["cable_body_clearance_m"] = None
    peaks["tension_nominal_min_N"] = float(ser.tension_nominal.min())
    peaks["tension_nominal_max_N"] = float(ser.tension_nominal.max())
    robust = float(marg.min())
    k_worst = int(np.unravel_index(np.argmin(marg), marg.shape)[0])
    peaks["robust_tension_margin_N"] = robust
    if not robust >= 0.0:
        n_bad = int(np.sum(np.any(marg < 0, axis=0)))
        failed.append(f"tensions: {n_bad} samples have no tension distribution within "
                      f"[{lim.tension_min:g}, {lim.tension_max:g}] N for some platform in the "
                      f"uncertainty box (worst margin {robust:.3g} N)")
    x = np.vstack([box.x_nominal[None], box.corners])[k_worst]
    return SafetyCertificate(peaks, tuple(failed), robust, float(marg[0].min()),
                             [float(v) for v in x], len(box.corners), ser.n_lp)
