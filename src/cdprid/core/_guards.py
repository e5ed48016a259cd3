"""Plausibility guards: a mistaken input must not give a confident number (issues 25, 40).

Shared by the features: ``identify`` adds their sentences to its warnings, ``diagnose``
refuses (exit 2) when any of :func:`refusals` fires, since it must not name effects on data
whose base fit cannot be trusted (:func:`refuse_implausible`, called at its entry).

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
from cdprid.core._motion import rotation_matrices
from cdprid.core._noise import estimate_noise

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

    All cable exits at one point (the wrench matrix has rank 3 at most), two cables with the
    same exit and attachment, or a cable of zero length at some sample (its direction is
    undefined: every estimate would be ``nan``).

    Parameters
    ----------
    robot : CableRobot
    t : array_like (n,)
        Pose times, s.
    position : array_like (n, 3)
        Platform positions, base frame, m.
    quaternion : array_like (n, 4), optional
        Orientations ``(w, x, y, z)``; None: the platform does not rotate.

    Raises
    ------
    UserError
        One sentence naming robot.toml or the sample time.
    """
    B_A = np.asarray(robot.B_A, float)
    spread = float(np.max(np.linalg.norm(B_A - B_A.mean(0), axis=1)))
    if spread < 1e-3:
        raise UserError(f"robot.toml: all {len(B_A)} cable exits are within {spread * 1e3:.2g} mm "
                        "of one point; the wrench matrix cannot be formed (check [[cable]] exit).")
    P_b = np.asarray(robot.P_b, float)
    same = _same_cables(B_A, P_b)
    if same:
        i, j = same
        raise UserError(f"robot.toml: cables {i + 1} and {j + 1} have the same exit and the same "
                        "attachment point: the wrench matrix has two equal columns (a copied "
                        "[[cable]] block?).")
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


def _same_cables(B_A, P_b=None, tol: float = 1e-6):
    """The first pair of cables (i, j) whose exits (and attachments, when given) coincide."""
    for i in range(len(B_A)):
        for j in range(i + 1, len(B_A)):
            if np.linalg.norm(B_A[i] - B_A[j]) < tol and (
                    P_b is None or np.linalg.norm(P_b[i] - P_b[j]) < tol):
                return i, j
    return None


def _duplicate_exit_warning(robot) -> str | None:
    """Two cables leaving from one exit point: possible (two cables through one eyelet) but
    far more often a copied ``exit`` line; the first moment is then biased with no other sign."""
    same = _same_cables(np.asarray(robot.B_A, float))
    if same is None:
        return None
    i, j = same
    return (f"robot.toml: cables {i + 1} and {j + 1} have the same exit point "
            f"{np.round(np.asarray(robot.B_A, float)[i], 4).tolist()} m: a copied exit line? "
            "A wrong exit biases m s_G with no other sign (check [[cable]] exit).")


def _flat_tension_warning(tension) -> str | None:
    """A tension column that does not change at all: no load cell gives that (a constant
    written in place of the measurement, a unit or export error)."""
    tau = np.asarray(tension, float)
    if len(tau) < 3:
        return None
    flat = np.flatnonzero(np.ptp(tau, axis=0) <= 1e-12 * np.maximum(np.abs(tau).max(0), 1.0))
    if flat.size == 0:
        return None
    names = ", ".join(f"tau_{k + 1}" for k in flat)
    return (f"tensions.csv: {names} does not vary over the recording (constant "
            f"{tau[0, flat[0]]:.6g} N): a load cell always varies with the motion and its noise "
            "(check the export of the tension columns).")


def _quaternion_order_warning(quaternion) -> str | None:
    """Quaternions stored scalar-last read as scalar-first: the platform then seems turned by
    about 180 deg throughout, while the other reading is near the identity."""
    if quaternion is None or len(quaternion) == 0:
        return None
    q = np.abs(np.asarray(quaternion, float))
    if np.median(q[:, 0]) < 0.5 and np.median(q[:, 3]) > 0.9:
        return ("pose.csv: the quaternions read as scalar-first (qw, qx, qy, qz) turn the "
                "platform by about 180 deg throughout, and read scalar-last they are near the "
                "identity: are the columns in (qx, qy, qz, qw) order? spec v1 is scalar-first.")
    return None


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

    Parameters
    ----------
    ds : Dataset
    signals : AlignedSignals
        The aligned window identified.
    differentiator : str
        The method used.
    params : dict
        Its parameters.
    acceleration : ndarray (n, 3), optional
        The differentiator's accelerations at ``signals.t`` (m/s^2) when the caller has them
        (identify), so the motion is not differentiated twice.

    Returns
    -------
    list of str
        The warnings (gravity, duplicate exits, workspace, quaternion order, flat tensions,
        clocks, signal-to-noise); empty when none applies.
    """
    out = [_gravity_warning(ds.robot), _duplicate_exit_warning(ds.robot),
           _workspace_warning(ds.robot, signals.position),
           _quaternion_order_warning(ds.quaternion), _flat_tension_warning(ds.tension),
           _clock_warning(ds.pose_t, ds.tension_t),
           _snr_warning(signals, differentiator, params, acceleration)]
    return [w for w in out if w]


#: Words of the guards under which the diagnosis refuses: every guard of identify except the
#: residual and physical-consistency ones, which point to unmodelled effects (what the
#: diagnosis is for).
REFUSAL_KEYS = ("|gravity|", "outside the box", "are both in seconds", "too small for the position",
                "look swapped", "far from robot.toml's", "does not vary", "scalar-first",
                "same exit point")


def refusals(warnings: list[str]) -> list[str]:
    """The input problems under which the diagnosis refuses to name effects.

    Parameters
    ----------
    warnings : list of str
        Sentences of :func:`input_warnings` and :func:`result_warnings`.

    Returns
    -------
    list of str
        Those that contain a key of ``REFUSAL_KEYS``.
    """
    return [w for w in warnings if any(k in w for k in REFUSAL_KEYS)]


def result_warnings(robot, names, x, sigma_rho: float, tension) -> list[str]:
    """Problems of an identification result (one sentence each).

    Parameters
    ----------
    robot : CableRobot
        Its ``[platform] mass`` (kg) is compared with the identified one.
    names : sequence of str
        Parameter names.
    x : array (p,)
        The estimates (SI units).
    sigma_rho : float
        Residual rms, N.
    tension : ndarray (n, m)
        Tensions, N (their noise sets the residual's floor).

    Returns
    -------
    list of str
        Mass far from robot.toml, residual far above the tension noise, non-finite estimates.
    """
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


def swapped_columns_warning(robot, motion, A, idx, tension, wf, linear: bool) -> str | None:
    """Name two tension columns that look swapped: exchanging them lowers the residual of the
    same least-squares fit below :data:`SWAP_RESIDUAL_RATIO` of what it is (tensions in the
    wrong cable order gave a confident mzG off by 4 sigma with no warning).

    Parameters
    ----------
    robot : CableRobot
    motion : Motion
        The estimated motion at the pose times (n samples).
    A : ndarray (n_kept, 6, p)
        The fit's regressor at the kept samples ``idx``.
    idx : ndarray of int (n_kept,)
        Indices of the kept samples into ``motion.t``.
    tension : ndarray (n, m)
        Tensions at ``motion.t``, N.
    wf : callable or None
        The wrench filter of the fit (matched filtering), applied to (n, k) channels.
    linear : bool
        ``wf`` is linear (a zero-phase or FIR filter): the candidates are filtered at once.

    Returns
    -------
    str or None
        One sentence naming the two columns and the residual ratio; None when no exchange
        helps or the check does not apply (too many samples, one cable, < 10 kept samples).
    """
    from cdprid.core._regression import wrench_matrix_series

    n, m = len(motion.t), np.asarray(tension).shape[1]
    if n > SWAP_CHECK_MAX_SAMPLES or m < 2 or len(idx) < 10:
        return None
    A = np.asarray(A).reshape(-1, np.asarray(A).shape[-1])
    tau = np.asarray(tension, float)
    # W evaluated once: exchanging tau_i and tau_j adds (W_i - W_j)(tau_j - tau_i)
    W = wrench_matrix_series(robot, np.asarray(motion.position), np.asarray(motion.B_R_P))
    y0 = np.einsum("nkm,nm->nk", W, tau)
    Q = np.linalg.qr(A)[0]  # one projection for every candidate: residual = y - Q Q^T y
    pairs = [(i, j) for i in range(m) for j in range(i + 1, m)]

    def rms_residual(y):  # y (n_kept * 6, k) -> (k,)
        return np.sqrt(np.mean((y - Q @ (Q.T @ y)) ** 2, axis=0))

    def filtered(y):  # (n, 6 k) -> (n_kept * 6, k)
        f = np.asarray(wf(y) if wf is not None else y)[idx]
        return f.reshape(len(idx), 6, -1).reshape(len(idx) * 6, -1)

    deltas = [(W[:, :, i] - W[:, :, j]) * (tau[:, j] - tau[:, i])[:, None] for i, j in pairs]
    if linear:  # every candidate's filtered wrench is f0 plus its filtered change
        res = rms_residual(filtered(y0) + filtered(np.stack(deltas, axis=2).reshape(n, -1)))
    else:  # a homogeneous differentiator's describing function depends on the amplitude
        res = np.array([rms_residual(filtered(y0 + d))[0] for d in deltas])
    base = float(rms_residual(filtered(y0))[0])
    k = int(np.argmin(res))
    if res[k] < SWAP_RESIDUAL_RATIO * base:
        i, j = pairs[k]
        return (f"tension columns tau_{i + 1} and tau_{j + 1} look swapped: exchanging them "
                f"lowers the residual from {base:.3g} to {float(res[k]):.3g} (check the column "
                "order against robot.toml's cable order).")
    return None


#: Longest window (pose samples) of the guards' own base fit: a longer recording is checked on
#: its middle (the swapped-columns check runs up to this length).
GUARD_FIT_MAX_SAMPLES = SWAP_CHECK_MAX_SAMPLES
#: Fewest usable pose samples (every cable taut) below which no fit is attempted.
MIN_USABLE_SAMPLES = 200


def refuse_implausible(ds, taut_N: float | None = None, enforce: bool = True) -> list[str]:
    """Raise :class:`~cdprid.base.UserError` (exit 2) when a plausibility guard fires on ``ds``.

    Called at the entry of a feature that must not report on untrustworthy data (the
    diagnosis): the geometry (:func:`check_geometry`), the usable samples (the tension unit,
    gaps), then every guard of :data:`REFUSAL_KEYS` on the data and on a base fit of the
    paper's model (:func:`plausibility_warnings`).

    Parameters
    ----------
    ds : Dataset
    taut_N : float, optional
        Tension below which a cable counts as slack, N (default
        :data:`cdprid.base.TAUT_THRESHOLD_N`).
    enforce : bool
        False: the guards on the base fit are returned instead of raised (the diagnosis on
        motor currents, whose datasheet model lacks the drives' inertia and friction that the
        guards' thresholds assume absent); the geometry and the usable samples still refuse.

    Returns
    -------
    list of str
        With ``enforce=False``, the guards that fired (else empty).
    """
    from cdprid.io import align

    check_geometry(ds.robot, ds.pose_t, ds.position, ds.quaternion)
    sig = align(ds)
    _check_usable(ds, sig, taut_N)
    bad = refusals(plausibility_warnings(ds, sig))
    if bad and not enforce:
        return bad
    if bad:
        raise UserError(f"{ds.path}: the base model cannot be trusted on these data, so no "
                        f"effect is named: {bad[0]}")
    return []


def _check_usable(ds, sig, taut_N: float | None) -> None:
    """Name why too few samples are usable: slack cables (tensions in kN?) or short segments."""
    from cdprid.base import TAUT_THRESHOLD_N
    from cdprid.core._nuisance import taut_mask

    t = np.asarray(ds.pose_t, float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    cuts = np.flatnonzero(np.diff(t) > 1.5 * dt) + 1  # a missing sample or more
    bounds = np.concatenate([[0], cuts, [len(t)]])
    lengths = np.diff(bounds)
    usable = int(np.sum(np.maximum(lengths - 2 * int(round(1.0 / dt)), 0)))
    if len(cuts) and usable < MIN_USABLE_SAMPLES:
        k = int(np.argmax(lengths))
        raise UserError(f"{ds.path}: the pose stream has {len(cuts)} gaps (never bridged); its "
                        f"longest gap-free segment is {lengths[k] * dt:.3g} s ({lengths[k]} "
                        f"samples, from t = {t[bounds[k]]:.6g} s); with 1 s dropped at both ends "
                        f"of every segment (filter transients) {usable} samples are left, "
                        f"{MIN_USABLE_SAMPLES} are needed: fill the gaps at the source or record "
                        "longer stretches.")
    thr = TAUT_THRESHOLD_N if taut_N is None else float(taut_N)
    if len(cuts):  # every segment, not only the longest
        from cdprid.io import align

        sig = align(ds, split_gaps=True)
    taut = taut_mask(sig.t, ds.tension_t, ds.tension, threshold_N=thr)
    if int(taut.sum()) < MIN_USABLE_SAMPLES:
        top = float(np.nanmax(ds.tension))
        hint = (f"the largest tension is {top:.3g}: are the tensions in kN (or another unit) "
                "instead of N?" if top < thr else
                "slack cables or taut phases too short: check the tension columns and their "
                "offsets.")
        raise UserError(f"{ds.path}: only {int(taut.sum())} pose samples have every cable above "
                        f"{thr:g} N (taut), {MIN_USABLE_SAMPLES} are needed: {hint}")


def plausibility_warnings(ds, sig) -> list[str]:
    """Every guard's sentence on ``ds``: :func:`input_warnings` and :func:`result_warnings`
    of a base fit of the paper's model (euler-filtfilt at 4 Hz, matched filter, ordinary least
    squares; the full model when the platform rotates) with the swapped-columns check, on
    the middle :data:`GUARD_FIT_MAX_SAMPLES` samples of a longer recording.

    Parameters
    ----------
    ds : Dataset
    sig : AlignedSignals
        ``ds`` aligned (:func:`cdprid.io.align`).

    Returns
    -------
    list of str
        One sentence per guard that fires (:func:`refusals` selects the refusing ones).
    """
    from cdprid.core._motion import (
        ROTATION_WARN_DEG,
        estimate_motion,
        rotation_angle_deg,
        segment_mask,
    )
    from cdprid.core._regression import build_regression
    from cdprid.io import align
    from cdprid.model import PARAMETER_NAMES
    from cdprid.signal import acceleration_filter

    out = input_warnings(ds, sig, "euler-filtfilt", {})
    if len(sig.t) > GUARD_FIT_MAX_SAMPLES:
        mid, half = 0.5 * (sig.t[0] + sig.t[-1]), 0.5 * GUARD_FIT_MAX_SAMPLES * sig.dt
        sig = align(ds, mid - half, mid + half)
    rot = rotation_angle_deg(sig.quaternion) if sig.has_rotation else 0.0
    model = "full" if rot > ROTATION_WARN_DEG else "translation"
    params = {"cutoff_hz": 4.0, "order": 2}
    motion = estimate_motion(sig, "euler-filtfilt", params, angular=model == "full")

    def wf(y):
        return acceleration_filter(y, sig.dt, "euler-filtfilt", **params)

    reg = build_regression(ds.robot, motion, sig.tension, model, wf)
    segs = tuple(getattr(sig, "segments", ()) or ((0, len(sig.t)),))
    idx = np.flatnonzero(segment_mask(sig.t, segs, 1.0))
    p = len(PARAMETER_NAMES[model])
    if len(idx) * 6 <= 2 * p:
        return out
    A = np.asarray(reg.A)[idx]
    y = np.asarray(reg.y)[idx]
    x, *_ = np.linalg.lstsq(A.reshape(-1, p), y.reshape(-1), rcond=None)
    sigma = float(np.sqrt(np.mean((y.reshape(-1) - A.reshape(-1, p) @ x) ** 2)))
    out += result_warnings(ds.robot, PARAMETER_NAMES[model], x, sigma, ds.tension)
    swap = swapped_columns_warning(ds.robot, motion, A, idx, sig.tension, wf, True)
    return out + ([swap] if swap else [])
