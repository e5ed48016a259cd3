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

The pose noise also has a first-order share of the estimate's variance, ``D Sigma D^T``. The
Bartlett sandwich sees it in the residual but reads it low (its window's bias), and the floor
below it (``H^-1``, the current noise's propagation) lacks it: on the six-cable design the
viscous drive friction's intervals covered 91.9 % (RMS z 1.12; 1.03 with exact poses).
:func:`pose_noise_variance` estimates it from antithetic one-step probes (the estimate's
first-order response to ``PROBES`` re-noisings, far cheaper than refits), and the floor of
every std is ``H^-1`` plus that share (:func:`shifted_fit`). A pair's own half-difference
``(f+ - f-) / 2`` is one such response, but two pairs are two degrees of freedom: too few.

The encoder lengths, where lengths.csv is measured, sit in the regressor too (``J l''`` and
``f_v l'``, their differences through the filter): they are re-noised with the poses, at the
level their 4th differences give on the pose clock. (On the six-cable design, recordings
without encoder noise halve a +0.4 std bias of Ixz, but re-noising the encoders does not move
it: it is not this errors-in-variables term; the Coulomb signs and the samples left out near
rest, both from the noisy encoder rates and kept in the refits, are the untested suspects.)

The seeds come from the recording's poses (:func:`data_seed`): one recording always gets the
same result, and recordings of one trajectory independent Monte-Carlo errors.

Assumed: white pose noise of the levels the 4th differences measure, and a bias quadratic in
the noise (higher orders are left at the ratio 3 : 1 of ``sigma^4``'s terms, small where the
correction is a few std).
"""

from __future__ import annotations

import dataclasses
import zlib

import numpy as np

from cdprid.core import estimate_motion
from cdprid.identify._currents_oe import (
    BANDWIDTH_PERIODS,
    _a_prior,
    _floored,
    _residual_fn,
    commutator,
    gradient_fn,
    fit_output_error,
    oe_inputs,
)
from cdprid.identify._free_eiv import _perturbed

__all__ = ["PAIRS", "PROBES", "PoseShift", "data_seed", "pose_noise_correction",
           "pose_noise_shift", "pose_noise_variance"]

#: antithetic pairs of the re-noising (each pair two output-error refits); with 2 the shift's
#: Monte-Carlo error was up to 0.9 of a std in the pose noise's worst case (six-cable design)
PAIRS = 4
#: antithetic one-step probes of the pose noise's first-order variance (each two residuals)
PROBES = 16


@dataclasses.dataclass(frozen=True)
class PoseShift:
    """The pose noise's bias of the output error, estimated by re-noising.

    Attributes
    ----------
    shift : ndarray (q,)
        The bias (parameters' units, ``k`` in N/A): subtracted from the estimate.
    cov_mc : ndarray (q, q)
        Monte-Carlo covariance of ``shift`` (the pair means' over their number).
    cov_first : ndarray (q, q) or None
        The pose noise's first-order share of the estimate's covariance: the mean outer
        product of the pairs' half-differences (``pairs`` degrees of freedom), or of
        :func:`pose_noise_variance`'s probes.
    probes : int
        How many probes ``cov_first`` comes from (0: the pairs).
    s_len : ndarray (m,) or None
        Encoder length noise added per cable, m (None: the lengths not perturbed).
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
    cov_first: np.ndarray | None = None
    probes: int = 0
    s_len: np.ndarray | None = None


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


def _inputs(st: RefitSetup, sig, motion, theta0, p: int):
    """The output error's inputs on the poses of ``sig`` (``motion`` their differentiated
    motion): ``(G, I, L2, L1, S, C1, Nn, Dc)``, the rows' whole chain recomputed."""
    sub = st.regression(sig, motion)
    dt = float(sig.dt)
    ins = oe_inputs(st.ds, motion, st.idx, sub, st.current, st.lengths, st.sign, st.wf, dt,
                    st.params)
    Dc = commutator(st.ds, motion, st.idx, st.current, st.lengths, st.sign, st.wf, dt, theta0,
                    p)
    return ins + (Dc,)


#: the chord refits' iteration cap and relative step tolerance (the six-cable recordings
#: converge in about 7 steps; on the eight-cable design the chord can oscillate: then the
#: Gauss-Newton fit takes over from its first step)
CHORD_ITER, CHORD_TOL = 12, 1e-10


def _refit(st: RefitSetup, sig, motion, phi0, theta0, fixed: int, p: int, prior, lin=None):
    """The output error on the poses of ``sig`` (``motion`` their differentiated motion),
    started from ``phi0``: its estimate as ``theta``.

    With ``lin = (o, Jm, H)`` (:func:`_linearised`, the recording's own Gauss-Newton matrix)
    the refit is a chord iteration, ``phi -= H^-1 g(phi)`` with ``g`` the re-noised problem's
    gradient (one reverse pass instead of a Jacobian per step): it converges to the same
    stationary point as the Gauss-Newton fit, at a linear rate (``H`` differs from the
    re-noised problem's by the noise's share); when it does not converge within
    :data:`CHORD_ITER` steps the Gauss-Newton fit runs from the chord's first step."""
    G, I, L2, L1, S, C1, Nn, Dc = _inputs(st, sig, motion, theta0, p)
    m = st.ds.robot.n_cables
    if lin is not None:
        o, _, H = lin
        grad = gradient_fn(G, I, L2, L1, S, C1, np.sqrt(np.asarray(st.weights, float))[None, :],
                           Nn, Dc)
        P, pm = ((np.zeros(len(phi0)), np.zeros(len(phi0))) if prior is None else prior)
        Hi = np.linalg.inv(H)
        phi = np.asarray(phi0, float).copy()
        for k in range(CHORD_ITER):
            step = -Hi @ (grad(phi)[o] + P[o] * (phi[o] - pm[o]))
            phi[o] += step
            if np.all(np.abs(step) <= CHORD_TOL * (np.abs(phi[o]) + 1e-6)):
                return _theta(phi, p, m)
            first = phi.copy() if k == 0 else first
        phi0 = first
    oe = fit_output_error(G, I, L2, L1, S, C1, phi0, fixed, st.weights, Nn, prior,
                         bandwidth=np.ceil(BANDWIDTH_PERIODS / (st.params["cutoff_hz"]
                                                               * float(sig.dt))), Dc=Dc)
    return _theta(oe.phi, p, m)


def _linearised(st: RefitSetup, sig, motion, phi, p: int, ref, drives):
    """``(o, Jm, H)`` at the estimate: the free parameters' indices (the reference's left
    out), the whitened Jacobian's free columns (``(n m, q - 1)``) and the Gauss-Newton matrix
    ``Jm^T Jm`` plus the datasheet priors' precision."""
    m = st.ds.robot.n_cables
    ins = _inputs(st, sig, motion, _theta(phi, p, m), p)
    jac = _residual_fn(*ins[:6], np.sqrt(np.asarray(st.weights, float))[None, :], *ins[6:])[1]
    o = np.delete(np.arange(len(phi)), ref.index(p))
    Jm = np.asarray(jac(phi)).reshape(-1, len(phi))[:, o]
    prior = _a_prior(drives, ref, p, m)
    return o, Jm, Jm.T @ Jm + (0.0 if prior is None else np.diag(prior[0][o]))


def _renoised(st: RefitSetup, sig, motion, e, sgn: float):
    """``(st2, sig2, motion2)``: the setup, the aligned signals and their motion re-estimated
    with the draw ``e = (e_pos, e_rot, e_len)`` added times ``sgn`` (poses moved by
    ``e_pos``, rotated by ``e_rot``, encoder lengths moved by ``e_len``; None: not
    perturbed)."""
    e_pos, e_rot, e_len = e
    sig2, _ = _perturbed(sig, motion, sgn * e_pos, None if e_rot is None else sgn * e_rot)
    st2 = st if e_len is None else dataclasses.replace(st, lengths=st.lengths + sgn * e_len)
    return st2, sig2, estimate_motion(sig2, st.differentiator, st.params,
                                      angular=(st.model == "full"))


def _levels(st: RefitSetup, noise: dict):
    """``(s_pos, s_rot, s_len)``: the re-noising's levels (``s_rot`` None: no rotation
    noise, or the translation model; ``s_len`` None: no encoder lengths measured, or no
    noise in them); None when neither the poses nor the encoders show noise."""
    s_pos = float(noise.get("position_m") or 0.0)
    s_rot = noise.get("rotation_rad")
    if st.model != "full" or s_rot is None or not s_rot > 0:
        s_rot = None
    s_len = noise.get("length_m") if noise.get("lengths_measured") else None
    if s_len is not None:
        s_len = np.clip(np.nan_to_num(np.asarray(s_len, float)), 0.0, None)
        s_len = s_len if np.any(s_len > 0) else None
    if not s_pos > 0 and s_rot is None and s_len is None:
        return None
    return s_pos, None if s_rot is None else float(s_rot), s_len


def _start(st: RefitSetup, noise: dict, phi, p: int, count: int):
    """``(lv, m, theta0)`` for ``count`` antithetic draws: the levels (:func:`_levels`), the
    number of cables and the estimate as ``theta``; None without draws or without noise."""
    lv = _levels(st, noise) if count > 0 else None
    if lv is None:
        return None
    m = st.ds.robot.n_cables
    return lv, m, _theta(phi, p, m)


def _draw(rng, n: int, m: int, lv):
    """One draw ``(e_pos (n, 3), e_rot (n, 3) or None, e_len (n, m) or None)`` at the levels
    ``lv`` of :func:`_levels`."""
    s_pos, s_rot, s_len = lv
    e_pos = s_pos * rng.standard_normal((n, 3))
    e_rot = None if s_rot is None else s_rot * rng.standard_normal((n, 3))
    e_len = None if s_len is None else s_len[None, :] * rng.standard_normal((n, m))
    return e_pos, e_rot, e_len


def data_seed(sig) -> int:
    """A seed drawn from the recording's own poses: the same recording always gets the same
    re-noising, and different recordings independent ones (a fixed seed would give every
    recording of one trajectory the same Monte-Carlo error).

    Parameters
    ----------
    sig : AlignedSignals

    Returns
    -------
    int
    """
    return zlib.crc32(np.ascontiguousarray(np.asarray(sig.position, float)).tobytes())


def pose_noise_variance(st: RefitSetup, sig, motion, phi, p: int, ref, drives, noise: dict,
                        probes: int | None = None, seed: int | None = None, lin=None):
    """The pose noise's first-order share of the output error's covariance, from antithetic
    one-step probes.

    For each probe the poses are re-noised at their measured levels, ``y + e`` and ``y - e``,
    the rows' whole chain recomputed (motion, regression, ``W``, its null space, the filter's
    commutator) and the residual evaluated at the estimate; one Gauss-Newton step with the
    recording's own Jacobian gives the estimate's first-order response ``h = -H^-1 J^T (r+ -
    r-) / 2`` (``phi`` space, mapped to ``theta`` through ``k = 1 / a``). The mean of ``h h^T``
    over the probes estimates ``D Sigma D^T`` (``probes`` degrees of freedom), the share of
    the variance the Bartlett sandwich reads low and ``H^-1`` lacks. The term of the
    Jacobian's own change times the residual is left out: at the measured data that residual
    also holds the recording's own pose noise, whose product with the probe's the estimator's
    variance does not have (a full refit's half-difference, which keeps it, read up to 2-4x
    off); what it drops, the current noise times the probe, left the platform stds within
    0.91-1.14 of the pose noise's spread over 35 draws (six-cable design).

    Parameters
    ----------
    st : RefitSetup
    sig : AlignedSignals
    motion : Motion
    phi : ndarray (p + 5m,)
        The output error's estimate ``(x, a, J, f_v, f_c, c)``.
    p : int
        Number of platform parameters.
    ref : ScaleReference
        Its parameter is held (no response).
    drives : DriveData or None
        The datasheet priors' source (their precision enters ``H``).
    noise : dict
        The noise levels (``position_m``, ``rotation_rad``).
    probes : int, optional
        Antithetic probes (default :data:`PROBES`; 0: none).
    seed : int, optional
        Seed of the added noise (default :func:`data_seed`).
    lin : tuple, optional
        ``(o, Jm, H)`` at the estimate (computed when not given).

    Returns
    -------
    ndarray (q, q) in ``theta`` space (``k`` in N/A), or None (no pose noise, or no probes).
    """
    probes = PROBES if probes is None else int(probes)
    start = _start(st, noise, phi, p, probes)
    if start is None:
        return None
    lv, m, theta0 = start
    sw = np.sqrt(np.asarray(st.weights, float))[None, :]
    o, Jm, H = _linearised(st, sig, motion, phi, p, ref, drives) if lin is None else lin
    rng = np.random.default_rng(data_seed(sig) if seed is None else seed)
    n, out = len(sig.t), []
    for _ in range(probes):
        e = _draw(rng, n, m, lv)
        rs = []
        for sgn in (1.0, -1.0):
            st2, s2, mo = _renoised(st, sig, motion, e, sgn)
            ins = _inputs(st2, s2, mo, theta0, p)
            rs.append(np.asarray(_residual_fn(*ins[:6], sw, *ins[6:])[0](phi)).reshape(-1))
        h = np.zeros(len(phi))
        h[o] = -np.linalg.solve(H, Jm.T @ (0.5 * (rs[0] - rs[1])))
        out.append(0.5 * (_theta(phi + h, p, m) - _theta(phi - h, p, m)))
    out = np.array(out)
    return out.T @ out / len(out)


def pose_noise_shift(st: RefitSetup, sig, motion, phi, p: int, ref, drives, noise: dict,
                     pairs: int | None = None, seed: int | None = None,
                     lin=None) -> PoseShift | None:
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
    seed : int, optional
        Seed of the added noise (default :func:`data_seed`: deterministic per recording).
    lin : tuple, optional
        ``(o, Jm, H)`` at the estimate: the refits are chord iterations with ``H``
        (:func:`_refit`); None: Gauss-Newton refits.

    Returns
    -------
    PoseShift, or None when the poses show no noise (or ``pairs`` is 0). Its ``cov_first``
    is the pairs' own (``pairs`` degrees of freedom); :func:`pose_noise_variance` gives a
    better one.
    """
    pairs = PAIRS if pairs is None else int(pairs)
    start = _start(st, noise, phi, p, pairs)
    if start is None:
        return None
    lv, m, theta0 = start
    prior = _a_prior(drives, ref, p, m)
    rng = np.random.default_rng(data_seed(sig) if seed is None else seed)
    n, means, halves = len(sig.t), [], []
    for _ in range(pairs):
        e = _draw(rng, n, m, lv)
        fits = []
        for sgn in (1.0, -1.0):
            st2, sig2, mo = _renoised(st, sig, motion, e, sgn)
            fits.append(_refit(st2, sig2, mo, phi, theta0, ref.index(p), p, prior, lin))
        means.append(0.5 * (fits[0] + fits[1]) - theta0)
        halves.append(0.5 * (fits[0] - fits[1]))
    means, halves = np.array(means), np.array(halves)
    d = means - means.mean(0)
    cov_mc = d.T @ d / max(1, len(d) - 1) / len(d)
    return PoseShift(means.mean(0), cov_mc, lv[0], lv[1], pairs, halves.T @ halves / pairs,
                     s_len=lv[2])


def pose_noise_correction(st: RefitSetup, sig, motion, phi, p: int, ref, drives,
                          noise: dict) -> PoseShift | None:
    """The pose noise's bias (:func:`pose_noise_shift`, :data:`PAIRS` refit pairs) with its
    first-order variance from :data:`PROBES` one-step probes (:func:`pose_noise_variance`),
    both seeded from the recording (:func:`data_seed`; the probes one seed further).

    Parameters
    ----------
    st, sig, motion, phi, p, ref, drives, noise
        As in :func:`pose_noise_shift`.

    Returns
    -------
    PoseShift or None (no pose noise, or ``PAIRS`` 0)
    """
    if PAIRS <= 0 or _levels(st, noise) is None:
        return None
    lin = _linearised(st, sig, motion, phi, p, ref, drives)
    sh = pose_noise_shift(st, sig, motion, phi, p, ref, drives, noise, lin=lin)
    v = pose_noise_variance(st, sig, motion, phi, p, ref, drives, noise,
                            seed=data_seed(sig) + 1, lin=lin)
    return sh if v is None else dataclasses.replace(sh, cov_first=v, probes=PROBES)


def shifted_fit(fit: dict, sh: PoseShift | None, p: int, notes: list, warns: list) -> dict:
    """``fit`` (the output error's dict of ``_currents._fit`` keys) with the pose noise's bias
    ``sh`` subtracted, its Monte-Carlo covariance added, a note with the noise levels and the
    shift in std units, and a warning when it exceeds one std; ``fit`` unchanged when ``sh``
    is None.

    The covariance: the sandwich with every std raised to at least that of the current noise's
    ``H^-1`` plus the pose noise's first-order share (``sh.cov_first``), then the shift's
    Monte-Carlo covariance added. ``compared`` keeps the covariance without either
    (``cov_uncorrected``) and the share itself (``pose_first_cov``).

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
    c0 = fit.get("compared") or {}
    cov = fit["cov"]
    if sh.cov_first is not None and "cov_sandwich" in c0:
        cov = _floored(c0["cov_sandwich"], c0["cov_model"] + sh.cov_first)
    cov_floor = cov
    cov = cov + sh.cov_mc
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(std > 0, sh.shift / std, 0.0)
    rot = "" if sh.s_rot is None else f", rotation {1e3 * sh.s_rot:.3g} mrad"
    rot += ("" if sh.s_len is None else
            f", the encoder lengths {1e3 * np.min(sh.s_len):.3g}-{1e3 * np.max(sh.s_len):.3g} mm")
    shown = ", ".join(f"{names[k]} {z[k]:+.2f}" for k in range(p))
    notes.append(f"pose noise (errors in variables): the output error refitted on the poses "
                 f"re-noised at their measured levels (position {1e3 * sh.s_pos:.3g} mm{rot}; "
                 f"{sh.pairs} antithetic pairs); their mean shift, the bias, removed (platform, "
                 f"in std: {shown}; largest over the drives "
                 f"{z[p:][np.argmax(np.abs(z[p:]))]:+.2f}), its Monte-Carlo spread in the std"
                 + ("" if sh.cov_first is None else
                    f"; the pose (and encoder) noise's own variance ({sh.probes or sh.pairs} "
                    "antithetic "
                    "probes, one Gauss-Newton step each) added to the current noise's in the "
                    "floor of every std"))
    big = [names[k] for k in np.flatnonzero(np.abs(z) > 1.0)]
    if big:
        more = f" and {len(big) - 6} more" if len(big) > 6 else ""
        enc = "" if sh.s_len is None else " (with the encoder noise)"
        warns.append(f"the pose noise biased{enc} {', '.join(big[:6])}{more} by more than one "
                     "std (removed by re-noising; the correction assumes white pose and encoder "
                     "noise of the measured levels): lower the cutoff or the pose noise to need "
                     "less of it.")
    compared = dict(c0, pose_shift=sh.shift, pose_shift_cov=sh.cov_mc,
                    pose_first_cov=sh.cov_first, cov_uncorrected=fit["cov"],
                    cov_floored=cov_floor)
    return dict(fit, theta=fit["theta"] - sh.shift, cov=cov, cov_iid=fit["cov_iid"] + sh.cov_mc,
                compared=compared)
