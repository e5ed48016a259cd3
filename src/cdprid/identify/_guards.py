"""Plausibility guards: a mistaken input must not give a confident number (issue 25).

Every check compares what the data say with what physics or ``robot.toml`` expect and returns
one sentence per problem, naming the likely mistake (a unit, an axis, a clock, a column). Two
kinds:

* :func:`input_warnings` look at the dataset alone (before any fit): gravity, poses outside
  the box of the cable exits, tension time stamps on another clock or unit than the poses,
  motion too small for the sensor noise.
* :func:`result_warnings` look at an identification: the mass against ``[platform] mass``,
  the residual against the tension noise.

:func:`check_geometry` raises (exit 2) where the geometry makes the model meaningless: every
exit at one point, or a cable of zero length at some sample. :func:`refusals` selects the
input problems under which the diagnosis must not name effects.
"""

from __future__ import annotations

import math

import numpy as np

from cdprid.base import UserError
from cdprid.core import estimate_noise, rotation_matrices

#: Relative gap between the identified and the stated mass above which identify warns.
MASS_WARN_RATIO = 0.3
#: Residual RMS over the raw tension noise times sqrt(m) above which identify warns (a clean
#: recording stays near 0.2-0.6: the matched filter removes most of the noise).
RESIDUAL_WARN_FACTOR = 1.5
#: Acceleration signal-to-noise ratio below which the excitation is called too weak.
ACCEL_SNR_MIN = 3.0
EARTH_G = 9.81


def check_geometry(robot, t, position, quaternion=None) -> None:
    """Raise :class:`~cdprid.base.UserError` when the geometry makes W meaningless.

    All cable exits at one point (the wrench matrix has rank 3 at most), or a cable of zero
    length at some sample (its direction is undefined: every estimate would be ``nan``).
    """
    B_A = np.asarray(robot.B_A, float)
    spread = float(np.max(np.linalg.norm(B_A - B_A.mean(0), axis=1)))
    if spread < 1e-3:
        raise UserError(f"robot.toml: all {len(B_A)} cable exits are within {spread * 1e3:.2g} mm "
                        "of one point; the wrench matrix cannot be formed (check [[cable]] exit).")
    P_b = np.asarray(robot.P_b, float)
    pos = np.asarray(position, float)
    step = max(1, len(pos) // 20000)  # a bounded check on long recordings
    idx = np.arange(0, len(pos), step)
    R = (rotation_matrices(np.asarray(quaternion, float)[idx]) if quaternion is not None
         else np.broadcast_to(np.eye(3), (len(idx), 3, 3)))
    B = pos[idx, None, :] + np.einsum("nij,mj->nmi", R, P_b)
    L = np.linalg.norm(B_A[None] - B, axis=2)
    k, i = np.unravel_index(int(np.argmin(L)), L.shape)
    if L[k, i] < 1e-6:
        raise UserError(f"at t = {float(np.asarray(t)[idx[k]]):.4g} s cable {i + 1} has zero "
                        "length (its attachment is at its exit point): check pose.csv and "
                        "robot.toml.")


def _gravity_warning(robot) -> str | None:
    g = float(np.linalg.norm(np.asarray(robot.gravity, float)))
    if abs(g - EARTH_G) > 0.05 * EARTH_G:
        return (f"robot.toml: |gravity| is {g:.4g} m/s^2, not Earth's {EARTH_G}: every mass "
                "and first moment scales with it (check the value and its unit).")
    return None


def _workspace_warning(robot, position) -> str | None:
    B_A = np.asarray(robot.B_A, float)
    lo, hi = B_A.min(0), B_A.max(0)
    margin = 0.1 * np.maximum(hi - lo, 0.1)
    lo = lo.copy()
    lo[2] -= float(np.max(hi - lo))  # a suspended platform hangs below its exits
    pos = np.asarray(position, float)
    outside = np.any((pos < lo - margin) | (pos > hi + margin), axis=1)
    frac = float(outside.mean()) if len(pos) else 0.0
    if frac > 0.05:
        z_flip = bool(np.mean(pos[:, 2] < lo[2] - margin[2]) > 0.5)
        hint = ("the poses lie below the exits' box: is z pointing down, or the base frame not "
                "the one of robot.toml?" if z_flip else
                "check the position unit (m) and the base frame of the motion capture.")
        box = " .. ".join("[" + ", ".join(f"{v:.3g}" for v in b) + "]" for b in (lo, hi))
        return (f"{100 * frac:.0f} % of the poses lie outside the box of the cable exits "
                f"{box} m: " + hint)
    return None


def _clock_warning(pose_t, tension_t) -> str | None:
    pt, tt = np.asarray(pose_t, float), np.asarray(tension_t, float)
    if len(pt) < 3 or len(tt) < 3:
        return None
    dp, dq = float(np.median(np.diff(pt))), float(np.median(np.diff(tt)))
    span_p, span_t = pt[-1] - pt[0], tt[-1] - tt[0]
    if dp > 0 and dq > 0 and (dq / dp > 50 or dp / dq > 50 or span_t / max(span_p, 1e-12) > 50
                              or span_p / max(span_t, 1e-12) > 50):
        return (f"the tension stream spans {span_t:.4g} (sample step {dq:.3g}) and the poses "
                f"{span_p:.4g} (step {dp:.3g}) in their time columns: are both in seconds "
                "(ms vs s)?")
    overlap = min(pt[-1], tt[-1]) - max(pt[0], tt[0])
    if overlap < 0.5 * min(span_p, span_t):
        return (f"poses and tensions overlap for {max(overlap, 0):.3g} s of {span_p:.3g} s: the "
                "two clocks may be offset (check the tension time column and its origin).")
    return None


def _snr_warning(signals, differentiator: str, params: dict, acceleration=None) -> str | None:
    """Accelerations of the motion against those the differentiator makes of pure noise
    (``acceleration``: the ones the identification already estimated, else computed here)."""
    from cdprid.signal import differentiate

    pos = np.asarray(signals.position, float)
    if len(pos) < 50:
        return None
    s = float(np.median(estimate_noise(pos)))
    if not s > 0:
        return None
    n = min(len(pos), 4000)
    noise = np.random.default_rng(0).normal(0.0, s, (n, 1))
    _, a_noise = differentiate(noise, signals.dt, differentiator, **params)
    a = (np.asarray(acceleration, float) if acceleration is not None
         else differentiate(pos, signals.dt, differentiator, **params)[1])
    trim = max(1, int(1.0 / signals.dt))
    rms = lambda x: float(np.sqrt(np.mean(np.square(x[trim:-trim]))))  # noqa: E731
    a_sig = rms(a - a.mean(0)) * math.sqrt(pos.shape[1])  # vector RMS of the motion
    a_n = rms(a_noise) * math.sqrt(pos.shape[1])  # the same for noise on every axis
    if a_n > 0 and a_sig < ACCEL_SNR_MIN * a_n:
        amp = float(np.max(np.ptp(pos, axis=0)))
        return (f"the motion is too small for the position noise: acceleration RMS "
                f"{a_sig:.3g} m/s^2 against {a_n:.3g} m/s^2 from the noise ({s * 1e3:.2g} mm) "
                f"alone, over a range of {amp * 1e3:.3g} mm; the estimates and their std "
                "are not trustworthy (excite the platform more).")
    return None


def input_warnings(ds, signals, differentiator: str, params: dict,
                   acceleration=None) -> list[str]:
    """Problems of a dataset that make any identification of it doubtful (one sentence each).

    ``acceleration`` (n, 3): the differentiator's accelerations at ``signals.t`` when the caller
    has them (identify), so the motion is not differentiated twice."""
    out = [_gravity_warning(ds.robot), _workspace_warning(ds.robot, signals.position),
           _clock_warning(ds.pose_t, ds.tension_t),
           _snr_warning(signals, differentiator, params, acceleration)]
    return [w for w in out if w]


def refusals(warnings: list[str]) -> list[str]:
    """The input problems under which the diagnosis refuses to name effects."""
    keys = ("|gravity|", "outside the box", "are both in seconds", "too small for the position")
    return [w for w in warnings if any(k in w for k in keys)]


def result_warnings(robot, names, x, sigma_rho: float, tension) -> list[str]:
    """Problems of an identification result (one sentence each)."""
    out = []
    names = list(names)
    m_stated = robot.platform.mass
    if "m" in names and m_stated:
        m = float(x[names.index("m")])
        if not math.isfinite(m) or abs(m - m_stated) > MASS_WARN_RATIO * m_stated:
            out.append(f"identified mass {m:.4g} kg is far from robot.toml's [platform] mass "
                       f"{m_stated:.4g} kg: check the tension unit (N), the position unit (m), "
                       "gravity and the z axis.")
    s_tau = float(np.median(estimate_noise(np.asarray(tension, float))))
    m_cables = np.asarray(tension).shape[1]
    floor = max(s_tau * math.sqrt(m_cables), 0.05)
    if math.isfinite(sigma_rho) and sigma_rho > RESIDUAL_WARN_FACTOR * floor:
        out.append(f"the model residual ({sigma_rho:.3g} N rms) is {sigma_rho / floor:.0f} times "
                   f"what the tension noise ({s_tau:.2g} N) explains: check the tension column "
                   "order, units and clock, or run `cdprid diagnose` for unmodelled effects.")
    if not np.all(np.isfinite(np.asarray(x, float))):
        out.append("some estimates are not finite: the data do not determine them.")
    return out


#: Residual ratio (best swap / as given) below which two columns are named as swapped: clean
#: recordings give 1.0 (no swap helps), a swapped pair 0.36-0.51 (8-cable, 4- and 10-parameter).
SWAP_RESIDUAL_RATIO = 0.7
#: Longest recording (pose samples) on which the column-order check runs (it refits once per
#: pair of cables).
SWAP_CHECK_MAX_SAMPLES = 30_000


def swapped_columns_warning(robot, report, tension) -> str | None:
    """Name two tension columns that look swapped: exchanging them lowers the residual of the
    same least-squares fit below :data:`SWAP_RESIDUAL_RATIO` of what it is (tensions in the
    wrong cable order gave a confident mzG off by 4 sigma with no warning)."""
    from cdprid.core import cable_wrench
    from cdprid.identify._batch import _wrench_filter

    motion, reg = report.motion, report.regression
    n, m = len(motion.t), np.asarray(tension).shape[1]
    if n > SWAP_CHECK_MAX_SAMPLES or m < 2 or len(reg.t) < 10:
        return None
    wf, _, _ = _wrench_filter(robot, report.differentiator, report.params,
                              float(np.median(np.diff(motion.t))), report.wrench_filter)
    idx = np.searchsorted(motion.t, reg.t)
    A = np.asarray(reg.A).reshape(-1, np.asarray(reg.A).shape[-1])
    tau = np.asarray(report.signals.tension, float)
    if tau.shape[0] != n:
        return None

    # W evaluated once: exchanging tau_i and tau_j adds (W_i - W_j)(tau_j - tau_i); its
    # columns by the identification's own compiled W tau with unit tensions (no new trace)
    eye = np.eye(m)
    W = np.stack([cable_wrench(robot, motion.position, motion.B_R_P,
                               np.broadcast_to(eye[i], (n, m))) for i in range(m)], axis=2)
    y0 = np.einsum("nkm,nm->nk", W, tau)

    Q = np.linalg.qr(A)[0]  # one projection for every candidate: residual = y - Q Q^T y
    pairs = [(i, j) for i in range(m) for j in range(i + 1, m)]

    def rms_residual(y):  # y (n_kept * 6, k) -> (k,)
        return np.sqrt(np.mean((y - Q @ (Q.T @ y)) ** 2, axis=0))

    def filtered(y):  # (n, 6 k) -> (n_kept * 6, k)
        f = np.asarray(wf(y) if wf is not None else y)[idx]
        return f.reshape(len(idx), 6, -1).reshape(len(idx) * 6, -1)

    deltas = [(W[:, :, i] - W[:, :, j]) * (tau[:, j] - tau[:, i])[:, None] for i, j in pairs]
    if report.differentiator == "euler-filtfilt" or hasattr(wf, "taps"):  # a linear filter:
        f0 = filtered(y0)  # every candidate's filtered wrench is f0 plus its filtered change
        fd = filtered(np.stack(deltas, axis=2).reshape(n, -1))
        res = rms_residual(f0 + fd)
    else:  # a homogeneous differentiator's describing function depends on the amplitude
        res = np.array([rms_residual(filtered(y0 + d))[0] for d in deltas])
    base = float(rms_residual(filtered(y0))[0])
    k = int(np.argmin(res))
    best = (float(res[k]), pairs[k]) if res[k] < base else (base, None)
    if best[1] is not None and best[0] < SWAP_RESIDUAL_RATIO * base:
        i, j = best[1]
        return (f"tension columns tau_{i + 1} and tau_{j + 1} look swapped: exchanging them "
                f"lowers the residual from {base:.3g} to {best[0]:.3g} (check the column order "
                "against robot.toml's cable order).")
    return None
