"""The pose noise inside the output error's regressor (errors in variables): its bias removed
by re-noising the measured poses (``identify --source currents``, estimator ``oe``).

The output error's tensions ``tau(x) = W^+ Z x`` come from the measured poses: ``Z`` holds
their second differences (through the matched filter) and ``W`` their geometry. The fit treats
them as exact, so the pose noise biases the estimate at second order (``~ sigma^2``; through
the differentiator ``~ f_c^5``): on the six-cable design of results/currents-designed.md
m z_G sat 2-3 of its std off, with the same sign on every seed.

The correction follows the free motion's (:mod:`cdprid.identify._free_eiv`), applied to the
estimates themselves: the measured poses get fresh white noise of the levels their 4th
differences give (``noise_levels``: position, and rotation with the full model) in antithetic
pairs ``y + e``, ``y - e``, and the output error is refitted on each (the motion, the
regression, ``W``, its null space and the filter's commutator all recomputed: the rows' whole
chain; the currents, the lengths and the friction signs kept). A pair's mean has no
first-order term and, the noise variance being doubled, exceeds the original fit by the bias
in expectation (a bias quadratic in ``sigma``). The estimate subtracts that shift; its
covariance gets the pairs' Monte-Carlo spread (the pair means' covariance over their number).

Assumed: white pose noise of the levels the 4th differences measure, and a bias quadratic in
the noise (higher orders are left at the ratio 3 : 1 of ``sigma^4``'s terms, small where the
correction is a few std).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.core import estimate_motion
from cdprid.identify._currents_oe import (
    BANDWIDTH_PERIODS,
    _a_prior,
    commutator,
    fit_output_error,
    oe_inputs,
)
from cdprid.identify._free_eiv import _perturbed

__all__ = ["PAIRS", "PoseShift", "pose_noise_shift"]

#: antithetic pairs of the re-noising (each pair two output-error refits)
PAIRS = 2


@dataclasses.dataclass(frozen=True)
class PoseShift:
    """The pose noise's bias of the output error, estimated by re-noising.

    Attributes
    ----------
    shift : ndarray (q,)
        The bias (parameters' units, ``k`` in N/A): subtracted from the estimate.
    cov_mc : ndarray (q, q)
        Monte-Carlo covariance of ``shift`` (the pair means' over their number).
    s_pos : float
        Position noise added, m.
    s_rot : float or None
        Rotation noise added, rad (None: the orientation not perturbed).
    pairs : int
    """

    shift: np.ndarray
    cov_mc: np.ndarray
    s_pos: float
    s_rot: float | None
    pairs: int


def _theta(phi, p: int, m: int) -> np.ndarray:
    """``(x, k, J, f_v, f_c, c)`` of the output error's ``(x, a, ...)`` (``k = 1 / a``)."""
    th = np.asarray(phi, float).copy()
    th[p:p + m] = 1.0 / th[p:p + m]
    return th


@dataclasses.dataclass(frozen=True)
class RefitSetup:
    """What a refit on re-noised poses needs besides the poses (:func:`pose_noise_shift`)."""

    ds: object
    model: str
    differentiator: str
    params: dict
    wf: object
    idx: np.ndarray
    #: ``(sig, motion) -> reg``: the platform regression of the poses at ``idx``
    regression: object
    current: np.ndarray
    lengths: np.ndarray
    sign: np.ndarray
    weights: np.ndarray


def _refit(st: RefitSetup, sig, motion, phi0, theta0, fixed: int, p: int, prior):
    """The output error on the poses of ``sig`` (``motion`` their differentiated motion),
    started from ``phi0``: its estimate as ``theta``."""
    sub = st.regression(sig, motion)
    dt = float(sig.dt)
    G, I, L2, L1, S, C1, Nn = oe_inputs(st.ds, motion, st.idx, sub, st.current, st.lengths,
                                        st.sign, st.wf, dt, st.params)
    Dc = commutator(st.ds, motion, st.idx, st.current, st.lengths, st.sign, st.wf, dt, theta0,
                    p)
    oe = fit_output_error(G, I, L2, L1, S, C1, phi0, fixed, st.weights, Nn, prior,
                         bandwidth=np.ceil(BANDWIDTH_PERIODS / (st.params["cutoff_hz"] * dt)),
                         Dc=Dc)
    return _theta(oe.phi, p, st.ds.robot.n_cables)


def pose_noise_shift(st: RefitSetup, sig, motion, phi, p: int, ref, drives, noise: dict,
                     pairs: int | None = None, seed: int = 0) -> PoseShift | None:
    """The output error's bias from the pose noise (module docstring).

    Parameters
    ----------
    st : RefitSetup
        The recording's settings and inputs other than the poses.
    sig : AlignedSignals
        The aligned poses (currents as tensions).
    motion : Motion
        Their differentiated motion.
    phi : ndarray (p + 5m,)
        The output error's estimate ``(x, a, J, f_v, f_c, c)`` (the refits' start).
    p : int
        Number of platform parameters.
    ref : ScaleReference
    drives : DriveData or None
        The datasheet priors' source.
    noise : dict
        The noise levels (``position_m``, ``rotation_rad``).
    pairs : int, optional
        Antithetic pairs (default :data:`PAIRS`; 0: no correction).
    seed : int
        Seed of the added noise (the result is deterministic).

    Returns
    -------
    PoseShift, or None when the poses show no noise (or ``pairs`` is 0).
    """
    pairs = PAIRS if pairs is None else int(pairs)
    if pairs <= 0:
        return None
    m = st.ds.robot.n_cables
    s_pos = float(noise.get("position_m") or 0.0)
    s_rot = noise.get("rotation_rad")
    if st.model != "full" or s_rot is None or not s_rot > 0:
        s_rot = None
    if not s_pos > 0 and s_rot is None:
        return None
    theta0 = _theta(phi, p, m)
    prior = _a_prior(drives, ref, p, m)
    rng = np.random.default_rng(seed)
    n, means = len(sig.t), []
    for _ in range(int(pairs)):
        e_pos = s_pos * rng.standard_normal((n, 3))
        e_rot = None if s_rot is None else s_rot * rng.standard_normal((n, 3))
        fits = []
        for sgn in (1.0, -1.0):
            sig2, mo = _perturbed(sig, motion, sgn * e_pos,
                                  None if e_rot is None else sgn * e_rot)
            mo = estimate_motion(sig2, st.differentiator, st.params,
                                 angular=(st.model == "full"))
            fits.append(_refit(st, sig2, mo, phi, theta0, ref.index(p), p, prior))
        means.append(0.5 * (fits[0] + fits[1]) - theta0)
    means = np.array(means)
    d = means - means.mean(0)
    cov_mc = d.T @ d / max(1, len(d) - 1) / len(d)
    return PoseShift(means.mean(0), cov_mc, s_pos, None if s_rot is None else float(s_rot),
                     int(pairs))


def shifted_fit(fit: dict, sh: PoseShift | None, p: int, notes: list, warns: list) -> dict:
    """``fit`` (the output error's dict of ``_currents._fit`` keys) with the pose noise's bias
    ``sh`` subtracted, its Monte-Carlo covariance added, a note with the noise levels and the
    shift in std units, and a warning when it exceeds one std; ``fit`` unchanged when ``sh``
    is None.

    Parameters
    ----------
    fit : dict
    sh : PoseShift or None
    p : int
        Number of platform parameters.
    notes, warns : list of str
        Appended to.

    Returns
    -------
    dict
    """
    if sh is None:
        return fit
    names = fit["names"]
    cov = fit["cov"] + sh.cov_mc
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(std > 0, sh.shift / std, 0.0)
    rot = "" if sh.s_rot is None else f", rotation {1e3 * sh.s_rot:.3g} mrad"
    shown = ", ".join(f"{names[k]} {z[k]:+.2f}" for k in range(p))
    notes.append(f"pose noise (errors in variables): the output error refitted on the poses "
                 f"re-noised at their measured levels (position {1e3 * sh.s_pos:.3g} mm{rot}; "
                 f"{sh.pairs} antithetic pairs); their mean shift, the bias, removed (platform, "
                 f"in std: {shown}; largest over the drives "
                 f"{z[p:][np.argmax(np.abs(z[p:]))]:+.2f}), its Monte-Carlo spread in the std")
    big = [names[k] for k in np.flatnonzero(np.abs(z) > 1.0)]
    if big:
        more = f" and {len(big) - 6} more" if len(big) > 6 else ""
        warns.append(f"the pose noise biased {', '.join(big[:6])}{more} by more than one std "
                     "(removed by "
                     "re-noising; the correction assumes white pose noise of the measured "
                     "level): lower the cutoff or the pose noise to need less of it.")
    compared = dict(fit.get("compared") or {}, pose_shift=sh.shift, pose_shift_cov=sh.cov_mc)
    return dict(fit, theta=fit["theta"] - sh.shift, cov=cov, cov_iid=fit["cov_iid"] + sh.cov_mc,
                compared=compared)
