"""The diagnosis of ``cable_elasticity`` from the optional winch-encoder stream ``lengths.csv``.

A cdprid extension of spec 1.1 (``docs/lengths.md``): ``lengths.csv`` with columns
``t, l_1, ..., l_m`` (s, m), one column per ``[[cable]]``, the unstrained cable length the
winch encoder measures. For an elastic cable (:mod:`cdprid.effects`, ``cable_elasticity``)
``l = L / (1 + tau / EA)`` with L the geometric length from the exit point to the
attachment (:func:`cdprid.model.cable_lengths`) and tau the tension; the encoder zero is
unknown, so each cable is fitted as ``l = c + L / (1 + tau k)`` with ``k = 1 / EA`` and an
offset c (Gauss-Newton from the linearised fit). The force model is not involved: this is its
own test, on its own residual (metres), named only when a dataset carries the stream.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from cdprid.base import normal_sf
from cdprid.core import hac_covariance
from cdprid.diagnosis._problem import Problem
from cdprid.diagnosis._result import Finding
from cdprid.diagnosis._testing import blocks
from cdprid.effects import ENCODER_EFFECT
from cdprid.model import cable_lengths

#: the stream's file stem and column names (``l_1..l_m``), in the style of tensions.csv
STREAM = "lengths"


@dataclasses.dataclass(frozen=True)
class LengthsStream:
    """Winch-encoder lengths: times ``t`` (k,) and lengths ``l`` (k, m), m."""

    t: np.ndarray
    l: np.ndarray  # noqa: E741


def lengths_stream(ds) -> tuple[LengthsStream | None, list[str]]:
    """The dataset's ``lengths.csv`` stream, or None; and notes on why it is not used.

    Parameters
    ----------
    ds : cdprid.io.Dataset
        Its ``extra`` streams (read by :func:`cdprid.io.read_dataset`).

    Returns
    -------
    (stream, notes)
    """
    if STREAM not in ds.extra:
        return None, []
    cols, vals = ds.extra[STREAM]
    m = ds.robot.n_cables
    want = ["t"] + [f"l_{i + 1}" for i in range(m)]
    if list(cols) != want:
        return None, [f"lengths.csv: columns {', '.join(cols)} are not {', '.join(want)} "
                      "(one per cable of robot.toml); cable_elasticity was not tested."]
    vals = np.asarray(vals, float)
    if len(vals) < 50 or not np.all(np.isfinite(vals)) or np.any(np.diff(vals[:, 0]) <= 0):
        return None, ["lengths.csv: fewer than 50 rows, a non-finite value or time not "
                      "strictly increasing; cable_elasticity was not tested."]
    return LengthsStream(vals[:, 0], vals[:, 1:]), []


def stream_on_subset(stream: LengthsStream, sub) -> LengthsStream:
    """The stream on the joined time axis of a budgeted subset (:mod:`.budget`).

    Each block's samples (original times ``[a, b]`` of ``sub.windows``) are shifted like the
    pose and tension streams; samples outside the blocks are dropped.
    """
    pt = np.asarray(sub.dataset.pose_t)
    per = len(pt) // len(sub.windows)
    dt = float(np.median(np.diff(pt)))
    ts, ls = [], []
    for k, (a, _b) in enumerate(sub.windows):
        keep = (stream.t >= a) & (stream.t < a + per * dt)
        ts.append(stream.t[keep] + (pt[k * per] - a))
        ls.append(stream.l[keep])
    return LengthsStream(np.concatenate(ts), np.concatenate(ls))


def fit_cable(l_meas, L, tau, n_iter: int = 30):
    """Least squares of ``l = c + L / (1 + tau k)`` for one cable: ``(c, k)`` and residual.

    Gauss-Newton from the linearised fit ``l - L = c - k tau L``; stops when the step is
    below 1e-15 relative.
    """
    A = np.column_stack([np.ones_like(L), -tau * L])
    c, k = np.linalg.lstsq(A, l_meas - L, rcond=None)[0]
    for _ in range(n_iter):
        den = 1.0 + tau * k
        e = l_meas - (c + L / den)
        J = np.column_stack([np.ones_like(L), -L * tau / den**2])
        d = np.linalg.lstsq(J, e, rcond=None)[0]
        c, k = c + d[0], k + d[1]
        if abs(d[1]) <= 1e-15 * max(abs(k), 1e-300) and abs(d[0]) <= 1e-15 * max(abs(c), 1.0):
            break
    den = 1.0 + tau * k
    J = np.column_stack([np.ones_like(L), -L * tau / den**2])
    return c, k, l_meas - (c + L / den), J


def _cv_rms(y, X, n_folds: int, guard: int) -> float:
    """Blocked cross-validated RMS of the linear fit of y on X."""
    sse, cnt = 0.0, 0
    for lo, hi in blocks(len(y), n_folds):
        tr = np.ones(len(y), bool)
        tr[max(0, lo - guard):hi + guard] = False
        b = np.linalg.lstsq(X[tr], y[tr], rcond=None)[0]
        r = y[lo:hi] - X[lo:hi] @ b
        sse += float(r @ r)
        cnt += len(r)
    return math.sqrt(sse / max(cnt, 1))


def elasticity_stage(prob: Problem, stream: LengthsStream, alpha: float) -> tuple[list, dict]:
    """Test every cable for ``cable_elasticity`` against the winch-encoder lengths.

    Per cable, on the used samples (taut, trimmed) inside the stream's time range: the fit
    of :func:`fit_cable` with the lengths and tensions interpolated to the pose times and
    the nominal geometry of robot.toml at the measured poses. ``k = 1 / EA`` is tested
    one-sided (k > 0) with a HAC standard deviation (Bartlett window of the problem's
    ``lags``), Bonferroni over the cables; a cable is named when ``p < alpha`` and the
    blocked cross-validated length RMS (offset only -> offset and stretch) falls. The
    held-out fall is not required to reach ``min_gain``: the pose noise (through L)
    dominates the length residual, so a well-determined stretch can lower it by < 1 %.

    Returns
    -------
    (findings, info)
        Findings ``cable_elasticity {cable, EA_N}`` with the 95 % interval of EA (the
        reciprocal of k's interval); ``info`` per cable: k, its std, z, p, held-out RMS.
    """
    inside = (prob.t >= stream.t[0]) & (prob.t <= stream.t[-1])
    use = prob.use & inside
    m = prob.m
    if use.sum() < 50:
        return [], {"note": "lengths.csv does not overlap the used samples"}
    L_geo = np.asarray(jax.vmap(lambda p, R: cable_lengths(prob.d.robot, p, R))(
        jnp.asarray(prob.position[use]), jnp.asarray(prob.R[use])))
    tau = prob.tension[use]
    n_folds = prob.n_folds
    findings, per_cable = [], []
    for i in range(m):
        l_meas = np.interp(prob.t[use], stream.t, stream.l[:, i])
        c, k, e, J = fit_cable(l_meas, L_geo[:, i], tau[:, i])
        V = hac_covariance(J[:, None, :], e[:, None], bandwidth=prob.lags + 1)[0]
        sd = float(np.sqrt(max(V[1, 1], 1e-300)))
        z = k / sd
        p = float(min(1.0, m * normal_sf(z)))
        X0 = np.ones((len(e), 1))
        X1 = np.column_stack([X0[:, 0], -tau[:, i] * L_geo[:, i]])
        rms0 = _cv_rms(l_meas - L_geo[:, i], X0, n_folds, prob.lags)
        rms1 = _cv_rms(l_meas - L_geo[:, i], X1, n_folds, prob.lags)
        per_cable.append({"cable": i + 1, "k_per_N": float(k), "k_std": sd, "z": float(z),
                          "p_value": p, "offset_m": float(c), "heldout_rms_before_m": rms0,
                          "heldout_rms_after_m": rms1})
        if p < alpha and rms1 < rms0 and k > 0:
            zc = 1.959963984540054
            findings.append(Finding(
                effect=ENCODER_EFFECT, parameters={"cable": i + 1, "EA_N": float(1.0 / k)},
                interval={"EA_N": [float(1.0 / (k + zc * sd)),
                                   float(1.0 / (k - zc * sd)) if k > zc * sd else None]},
                aliases=[], heldout_rms_before=rms0, heldout_rms_after=rms1, p_value=p,
                statistic=float(z * z), threshold=float(alpha),
                separated_by={}))
    info = {"n_samples": int(use.sum()), "units": "m (encoder length residual)",
            "cables": per_cable}
    return findings, info


def with_elasticity(findings: list, prob: Problem, stream: LengthsStream | None, sub,
                    alpha: float, say=None) -> tuple[list, dict | None]:
    """The findings plus those of :func:`elasticity_stage` when the dataset has lengths.

    ``sub``: the budgeted subset the problem was built on (:mod:`.budget`), or None.
    Returns the findings and ``info["lengths"]`` (None without a stream).
    """
    if stream is None:
        return findings, None
    if sub is not None:
        stream = stream_on_subset(stream, sub)
    el, info = elasticity_stage(prob, stream, alpha)
    if say is not None:
        say(f"cable elasticity (lengths.csv): {len(el)} finding(s)")
    return findings + el, info
