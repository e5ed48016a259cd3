"""Stage 6 of the diagnosis: what the extended model leaves unexplained.

The residual is tested against generic signals that are not effects of the vocabulary (sign
of the cable velocity, tension level, pose, slow drift); what is significant is reported
under ``unexplained`` and takes part in the backward elimination, so that a vocabulary effect
fitting part of a structure it does not explain is not named as its cause.
"""

from __future__ import annotations

import math

import numpy as np

from cdprid.base import chi2_sf, f_sf
from cdprid.diagnosis._testing import partial_wald

#: generic signals the residual of the extended model is tested against (unexplained stage)
STRUCTURE_SIGNALS = ("sign of cable velocity", "tension level", "pose", "time (slow drift)")


def structure_features(W_all, v, om, tension, position, t, use, slide=None) -> dict:
    """Generic residual-structure regressors, unfiltered, ``(n, 6, q)`` each.

    These are not effects of the vocabulary: they describe what a remaining residual is
    *like*. ``sign of cable velocity`` is ``W_i sign(dl_i/dt)`` per cable (a Coulomb-like
    force along each cable, with ``dl/dt = -W^T [v; omega]``); ``tension level`` is
    ``W_i (z_i^2 - 1)`` with z_i the standardised tension (a load cell that is not linear);
    ``pose`` is a force linear in the position, per force axis; ``time (slow drift)`` is a
    force that drifts as Legendre polynomials of degree 1-3 in time, per force axis.
    ``slide`` (n, m), if given, replaces ``sign(dl/dt)`` (the expected sign of
    :func:`cdprid.diagnosis._problem.sliding_sign`, which the friction effects use).

    Parameters
    ----------
    W_all : (n, 6, m) nominal wrench matrices
    v, om : (n, 3) platform velocity and angular rate
    tension : (n, m) tensions at the pose times
    position : (n, 3)
    t : (n,)
    use : (n,) bool, the samples that are fitted

    Returns
    -------
    dict
        Signal name (one of :data:`STRUCTURE_SIGNALS`) -> array ``(n, 6, q)``.
    """
    n = W_all.shape[0]
    twist = np.concatenate([v, om], axis=1)
    ldot = -np.einsum("nim,ni->nm", W_all, twist)
    tz = (tension - tension[use].mean(0)) / np.maximum(tension[use].std(0), 1e-9)
    pc = position - position[use].mean(0)
    tu = t[use]
    s = 2.0 * (t - tu[0]) / max(tu[-1] - tu[0], 1e-9) - 1.0
    legendre = [s, 0.5 * (3 * s**2 - 1), 0.5 * (5 * s**3 - 3 * s)]
    P = np.zeros((n, 6, 9))
    D = np.zeros((n, 6, 9))
    for j in range(3):
        for k in range(3):
            P[:, j, 3 * j + k] = pc[:, k]
            D[:, j, 3 * j + k] = legendre[k]
    return {
        "sign of cable velocity": W_all * (np.sign(ldot) if slide is None
                                           else np.asarray(slide))[:, None, :],
        "tension level": W_all * (tz**2 - 1.0)[:, None, :],
        "pose": P,
        "time (slow drift)": D,
    }


def _where(name: str, beta, V) -> str:
    """Which cables / force axes a structure sits on (coefficients with |t| > 3)."""
    tstat = np.abs(beta) / np.sqrt(np.clip(np.diag(V), 1e-300, None))
    if name in ("sign of cable velocity", "tension level", "sign of tension rate"):
        idx = [i + 1 for i in np.nonzero(tstat > 3)[0]]
        return ("load cells of cables " + ", ".join(map(str, idx))) if idx else "all cables"
    axes = sorted({"xyz"[i // 3] for i in np.nonzero(tstat > 3)[0]})
    return ("force along " + ", ".join(axes)) if axes else "force rows"


def structure_tests(feats: dict, Z, y, wrow, lags: int, alpha: float,
                    n_tests: int | None = None) -> list:
    """Test the residual of ``y ~ Z`` for generic structure, strongest first (stepwise).

    Each signal is tested (HAC Wald, Bonferroni over the signals) given the model and the
    signals already found significant, so that one structure is not reported again under
    the name of a correlated signal.

    Parameters
    ----------
    feats : dict
        Signal name -> weighted, matched-filtered regressors ``(n, 6, q)`` (training rows).
    Z : (n, 6, p)
        The extended model's columns (weighted, training rows).
    y : (n, 6)
        Its target (weighted, training rows).
    wrow : (6,) row weights (to give sizes in newtons)
    lags : int
        HAC lag window.
    alpha : float
        Family-wise level; every signal is returned, ``significant`` marks p < alpha.
    n_tests : int, optional
        Bonferroni multiplier of the p-values (default: the number of signals; 1 gives the
        raw p-values, for a caller that controls the family itself).

    Returns
    -------
    list of dict
        ``where``, ``size`` (RMS force in N of the fitted structure), ``correlates_with``,
        ``p_value`` (Bonferroni over the signals, or ``n_tests``), ``coefficients`` and
        ``significant``.
    """
    out: list = []
    left = dict(feats)
    while left:
        tests = _structure_step(left, Z, y, wrow, lags, alpha,
                               len(feats) if n_tests is None else n_tests)
        if not tests:
            break
        best = min(tests, key=lambda u: u["p_value"])
        if not best["significant"]:
            return out + sorted(tests, key=lambda u: u["p_value"])
        out.append(best)
        Z = np.concatenate([Z, left.pop(best["correlates_with"])], axis=2)
    return out


def _structure_step(feats, Z, y, wrow, lags, alpha, n_signals):
    n, _, p = Z.shape
    Q = np.linalg.qr(Z.reshape(-1, p))[0]

    def partial(M):
        M2 = M.reshape(n * 6, -1)
        return (M2 - Q @ (Q.T @ M2)).reshape(n, 6, -1)

    yt = partial(y)[:, :, 0]
    out = []
    for name, F in feats.items():
        Ft = partial(F)
        keep = np.linalg.norm(Ft.reshape(-1, Ft.shape[2]), axis=0) > 1e-9 * max(
            1.0, float(np.linalg.norm(F)))
        Ft = Ft[:, :, keep]
        if Ft.shape[2] == 0:
            continue
        stat, beta, V = partial_wald(Ft, yt, lags)
        pv = float(min(1.0, chi2_sf(stat, Ft.shape[2]) * n_signals))
        fit = np.einsum("niq,q->ni", Ft, beta) / wrow[None, :]
        out.append({
            "where": _where(name, beta, V),
            "size": float(np.sqrt(np.mean(fit[:, :3] ** 2))),
            "correlates_with": name,
            "p_value": pv,
            "coefficients": [float(b) for b in beta],
            "significant": bool(pv < alpha),
        })
    return out


# ----------------------------------------------------------------------------- final stage

#: a structure is material when its size is at least this fraction of the noise scale
MATERIAL_FRACTION = 0.1

#: the tests of the final stage (one Holm family): the structure signals, whiteness, spectrum
WHITENESS = "its own past (residual not white over time)"
SPECTRAL = "a periodic disturbance"


def holm(pvalues) -> np.ndarray:
    """Holm step-down adjusted p-values (family-wise error control, any dependence).

    Parameters
    ----------
    pvalues : (k,) raw p-values

    Returns
    -------
    ndarray (k,)
        ``max_{j <= rank} min(1, (k - j + 1) p_(j))`` in the original order.
    """
    p = np.asarray(pvalues, float)
    k = len(p)
    order = np.argsort(p, kind="stable")
    adj = np.minimum(1.0, np.maximum.accumulate(p[order] * (k - np.arange(k))))
    out = np.empty(k)
    out[order] = adj
    return out


def decorrelation_step(filt, n_max: int, threshold: float = 0.1) -> int:
    """Samples between residuals that the matched filter leaves nearly uncorrelated.

    The residual of the matched-filtered model is filtered noise under the null, correlated
    over the filter's length. Its autocorrelation is that of the filter's impulse response;
    the step is the smallest lag beyond which it stays below ``threshold`` in magnitude.

    Parameters
    ----------
    filt : callable
        The matched filter along time of ``(n, k)`` arrays (:meth:`Problem.filt`).
    n_max : int
        Longest step considered (samples).
    threshold : float

    Returns
    -------
    int
    """
    n = 4 * n_max + 1
    delta = np.zeros((n, 1))
    delta[n // 2, 0] = 1.0
    h = np.asarray(filt(delta))[:, 0]
    acf = np.correlate(h, h, mode="full")[n - 1:]
    acf = acf / acf[0]
    big = np.nonzero(np.abs(acf[:n_max + 1]) >= threshold)[0]
    return int(min(n_max, big[-1] + 1)) if len(big) else 1


def heldout_residuals(Z, y, wrow, use, test, n_folds: int, guard: int) -> np.ndarray:
    """Held-out force residual (N), ``(n, 3)``, NaN where a sample is not held out.

    With ``test`` (train/test split) the model fitted on the training rows predicts the test
    rows; otherwise blocked cross-validation over ``n_folds`` blocks of the used samples,
    leaving ``guard`` samples out on each side of the predicted block (the criterion of
    :func:`cdprid.diagnosis._problem.force_heldout_rms`).
    """
    from cdprid.diagnosis._testing import blocks

    n, _, p = Z.shape
    out = np.full((n, 3), np.nan)
    if test is not None:
        train = use & ~test
        beta, *_ = np.linalg.lstsq(Z[train].reshape(-1, p), y[train].reshape(-1), rcond=None)
        r = (y[test] - np.einsum("nip,p->ni", Z[test], beta)) / wrow[None, :]
        out[test] = r[:, :3]
        return out
    idx = np.nonzero(use)[0]
    for lo, hi in blocks(len(idx), n_folds):
        tr = np.ones(len(idx), bool)
        tr[max(0, lo - guard):hi + guard] = False
        beta, *_ = np.linalg.lstsq(Z[idx[tr]].reshape(-1, p), y[idx[tr]].reshape(-1),
                                   rcond=None)
        r = (y[idx[lo:hi]] - np.einsum("nip,p->ni", Z[idx[lo:hi]], beta)) / wrow[None, :]
        out[idx[lo:hi]] = r[:, :3]
    return out


def _runs(mask):
    """(start, stop) of the contiguous True runs of a boolean array."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(int))
    return list(zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0], strict=True))


def decimate_runs(x, mask, step: int):
    """Every ``step``-th sample of each contiguous run of ``mask``, and its run number.

    Parameters
    ----------
    x : numpy.ndarray (n, ...)
    mask : numpy.ndarray (n,) of bool
    step : int
        Keep every ``step``-th sample of each run.

    Returns
    -------
    values : numpy.ndarray (k, ...)
    run_id : numpy.ndarray (k,) of int
        The run (0-based, in time order) of each kept sample.
    """
    vals, run_id = [], []
    for k, (lo, hi) in enumerate(_runs(mask)):
        seg = x[lo:hi:step]
        vals.append(seg)
        run_id.append(np.full(len(seg), k))
    if not vals:
        return np.zeros((0,) + x.shape[1:]), np.zeros(0, int)
    return np.concatenate(vals), np.concatenate(run_id)


def portmanteau(x, run_id, h: int):
    """Ljung-Box-type statistic of a series made of runs, and its predictable fraction.

    ``Q = sum_k rho_k^2 n^2 / n_k`` over lags ``k = 1..h``, with ``rho_k`` the
    autocorrelation from the ``n_k`` pairs that lie in one run (``n^2 / n_k`` is Ljung-Box's
    ``n (n + 2) / (n - k)`` for one run); chi-square with h degrees of freedom for white
    noise. The predictable fraction is the R^2 of an AR(h) fit within the runs minus its
    expectation under the null, ``h / n`` (clipped at 0).

    Returns
    -------
    (Q, r2)
    """
    x = np.asarray(x, float) - np.mean(x)
    n = len(x)
    den = float(x @ x)
    Q = 0.0
    for k in range(1, h + 1):
        same = run_id[k:] == run_id[:-k]
        nk = int(same.sum())
        if nk < 2:
            continue
        rho = float(x[k:][same] @ x[:-k][same]) / den
        Q += rho * rho * n * n / nk
    rows = [i for i in range(h, n) if run_id[i - h] == run_id[i]]
    r2 = 0.0
    if len(rows) > 2 * h:
        rows = np.asarray(rows)
        X = np.column_stack([x[rows - k] for k in range(1, h + 1)])
        b, *_ = np.linalg.lstsq(X, x[rows], rcond=None)
        e = x[rows] - X @ b
        r2 = max(0.0, 1.0 - float(e @ e) / float(x[rows] @ x[rows]) - h / len(rows))
    return Q, r2


def whiteness_test(r, mask, step: int, dt: float) -> dict:
    """Whiteness over time of the held-out force residual, per force axis (worst reported).

    The residual is taken every ``step`` samples (:func:`decorrelation_step`: filtered noise
    is then nearly uncorrelated), so that the effective sample size ``n_eff`` is the number
    of those samples; :func:`portmanteau` over ``h = clip(n_eff // 10, 5, 20)`` lags; the
    p-value is Bonferroni over the three axes. ``size`` (N) is the RMS of the part of the
    residual its own past predicts (AR(h), null expectation removed).

    Parameters
    ----------
    r : (n, 3) held-out force residual, N
    mask : (n,) bool, samples held out
    step : int
    dt : float

    Returns
    -------
    dict
        ``where``, ``size``, ``correlates_with``, ``p_raw``, ``test``, ``effective_sample_size``,
        ``lags``, ``spacing_s``.
    """
    best = None
    n_eff = 0
    h = 5
    for i, axis in enumerate("xyz"):
        x, rid = decimate_runs(r[:, i], mask, step)
        n_eff = len(x)
        if n_eff < 30:
            return {}
        h = int(np.clip(n_eff // 10, 5, 20))
        Q, r2 = portmanteau(x, rid, h)
        p = float(chi2_sf(Q, h))
        size = float(np.sqrt(r2) * np.std(x))
        if best is None or p < best[0]:
            best = (p, axis, size, Q)
    p, axis, size, Q = best
    return {"where": f"force along {axis}", "size": size, "correlates_with": WHITENESS,
            "p_raw": float(min(1.0, 3 * p)), "test": "whiteness (Ljung-Box, decimated)",
            "statistic": float(Q), "effective_sample_size": n_eff, "lags": h,
            "spacing_s": float(step * dt)}


def periodogram(x, mask, dt: float):
    """Periodogram of a masked series (mean removed, zero outside the mask), ``(f, I)``.

    ``I = |FFT|^2 / n_used``: for white noise of variance s^2 its ordinates have mean s^2.

    Parameters
    ----------
    x : numpy.ndarray (n,)
    mask : numpy.ndarray (n,) of bool
        The samples used.
    dt : float
        Sample period, s.

    Returns
    -------
    f : numpy.ndarray
        Frequencies, Hz.
    I : numpy.ndarray
        Ordinates, units of ``x`` squared.
    """
    x = np.where(mask, x - np.mean(x[mask]), 0.0)
    X = np.fft.rfft(x)
    f = np.fft.rfftfreq(len(x), dt)
    return f, np.abs(X) ** 2 / max(1, int(mask.sum()))


def spectral_peak_test(r, mask, dt: float, f_lo: float, f_hi: float,
                       half_width: int = 8) -> dict:
    """The strongest narrow peak of the held-out force residual's spectrum vs its background.

    Per force axis, each periodogram ordinate ``I_k`` between ``f_lo`` and ``f_hi`` is
    compared with the mean of its neighbours ``2 <= |j - k| <= half_width`` (the nearest
    ones are left out: they hold the leakage of a peak between two frequencies). For
    Gaussian noise with a spectrum smooth over that window the ratio is F(2, 2 n_nb)
    distributed (n_nb neighbours), so a badly estimated background widens the tail instead
    of creating false peaks. The p-value is Bonferroni over the K ordinates and the three
    axes. ``size`` (N) is the RMS of the sinusoid fitted by least squares to the residual of
    that axis, at the frequency within one grid step of the peak that maximises it (the
    reported ``frequency_hz``).

    Parameters
    ----------
    r : (n, 3) held-out force residual, N (NaN outside ``mask``)
    mask : (n,) bool
    dt : float
    f_lo, f_hi : float
        Frequency band tested, Hz.
    half_width : int

    Returns
    -------
    dict
        ``where``, ``size``, ``correlates_with``, ``p_raw``, ``test``, ``frequency_hz``,
        ``peak_to_background``, ``n_frequencies``; empty when the band is too short.
    """
    best = None
    offs = np.array([o for o in range(-half_width, half_width + 1) if abs(o) >= 2])
    for i, axis in enumerate("xyz"):
        f, I = periodogram(np.nan_to_num(r[:, i]), mask, dt)
        band = np.nonzero((f >= f_lo) & (f <= f_hi))[0]
        band = band[(band + offs.min() >= 0) & (band + offs.max() < len(f))]
        if len(band) < 20:
            return {}
        q = I[band] / np.maximum(I[band[:, None] + offs[None, :]].mean(axis=1), 1e-300)
        j = int(np.argmax(q))
        K = len(band)
        p = float(min(1.0, 3 * K * f_sf(q[j], 2, 2 * len(offs))))
        if best is None or p < best[0]:
            best = (p, axis, float(f[band[j]]), float(q[j]), K, i)
    p, axis, fpk, q, K, i = best
    df = 1.0 / (len(mask) * dt)  # refine between the grid frequencies (up to 60 % loss)
    amps = [(float(np.hypot(*_sinusoid_fit(r[:, i:i + 1], mask, dt, fpk + d)[:2, 0])), fpk + d)
            for d in np.linspace(-df, df, 21)]
    amp, fpk = max(amps)
    size = amp / math.sqrt(2.0)
    return {"where": f"force along {axis}", "size": size,
            "correlates_with": f"{SPECTRAL} at {fpk:.3g} Hz", "p_raw": p,
            "test": "spectral peak (periodogram vs neighbouring frequencies, F test)",
            "frequency_hz": fpk, "peak_to_background": q, "n_frequencies": K}


def _sinusoid_fit(r, mask, dt: float, f_hz: float):
    """Least-squares cos, sin and constant coefficients ``(3, k)`` at ``f_hz`` on the mask."""
    t = np.arange(len(mask)) * dt
    X = np.column_stack([np.cos(2 * np.pi * f_hz * t), np.sin(2 * np.pi * f_hz * t),
                         np.ones(len(t))])
    b, *_ = np.linalg.lstsq(X[mask], r[mask], rcond=None)
    return b


def remove_sinusoid(r, mask, dt: float, f_hz: float):
    """The residual ``(n, k)`` minus its least-squares sinusoid at ``f_hz`` (every column)."""
    b = _sinusoid_fit(r, mask, dt, f_hz)
    t = np.arange(len(mask)) * dt
    out = np.array(r, float)
    out[mask] -= (np.outer(np.cos(2 * np.pi * f_hz * t), b[0])
                  + np.outer(np.sin(2 * np.pi * f_hz * t), b[1]))[mask]
    return out


#: per structure signal: what measurement or trajectory would tell its cause apart
SEPARATED_BY = {
    "sign of cable velocity": (
        "motion at several speeds and in both directions of each cable (a Coulomb force keeps "
        "its size and flips with the direction; pulley friction seen by a load cell on the "
        "winch side has the negative sign, in the vocabulary as pulley_friction)"),
    "tension level": ("a calibration of the load cells with known weights (a nonlinear cell "
                      "is wrong by the same amount at the same tension, whatever the pose)"),
    "pose": ("a geometric calibration (exit points, attachments) or the same poses at two "
             "pretension levels (a geometry error follows the pose, a sensor error the "
             "tension)"),
    "sign of tension rate": ("reversals of the tension at several rates and depths (a cell "
                             "that lags by a fixed band is load_cell_hysteresis; one that lags "
                             "in time with the rate is a clock offset)"),
    "time (slow drift)": ("a zero reading at rest at the start and the end of the recording "
                          "(a drift grows with the clock; per load cell it is tension_drift)"),
}


def in_own_units(u: dict, prob) -> dict:
    """A structure's size in its own units and one sentence on what would separate it:
    the Coulomb level per cable (N, in the convention of the load-cell reading: negative like
    pulley friction), the drift rate per force axis (N/s)."""
    name, coef = u.get("correlates_with"), u.get("coefficients")
    out = {}
    if name in SEPARATED_BY:
        out["separated_by"] = SEPARATED_BY[name]
    if name == "sign of cable velocity" and coef and len(coef) == prob.m:
        out["coulomb_N_per_cable"] = [float(c) for c in coef]
        sig = [c for c in coef if abs(c) > 0.1 * max(abs(x) for x in coef)]
        out["sign"] = ("like pulley friction" if all(c < 0 for c in sig) else
                       "opposite to pulley friction" if all(c > 0 for c in sig) else "mixed")
    if name == "time (slow drift)" and coef and len(coef) == 9:
        clk = np.asarray(prob.d.clock)[prob.use]
        span = float(np.ptp(clk)) if clk.size else 0.0
        if span > 0:  # the degree-1 Legendre term: s = 2 (t - t0) / T - 1
            out["rate_N_per_s"] = {ax: float(coef[3 * j] * 2.0 / span)
                                   for j, ax in enumerate("xyz")}
    return out


def finding_floor_N(tension) -> float:
    """Smallest force (RMS, N) a finding or an unexplained item may have: 1e-3 of the median
    tension. The tests decide on noisy data; this floor keeps numerical residue (noise-free
    data, a 20 um attachment error, a 4e-5 kg/m cable mass) from being named."""
    return 1e-3 * float(np.median(np.abs(tension)))


def materiality_floor(tension_noise_N, residual_rms_N: float) -> float:
    """Smallest size (N) worth reporting: :data:`MATERIAL_FRACTION` of the noise scale.

    The noise scale is the larger of the tension measurement noise (RMS over cables,
    estimated from the data) and the held-out force residual RMS of the extended model.
    """
    sig = float(np.sqrt(np.mean(np.square(tension_noise_N))))
    return MATERIAL_FRACTION * max(sig, float(residual_rms_N))


def unexplained_stage(prob, Z, y, feats: dict, hints: list, tension_noise_N,
                      alpha: float) -> tuple[list, dict]:
    """What the extended model leaves unexplained: tested, size-filtered, Holm-controlled.

    One family of tests at level ``alpha`` with Holm's step-down control: the structure
    signals (:func:`structure_tests`, stepwise, each given the model and the earlier
    signals), then, on the held-out force residual of the model plus the structures
    significant so far, :func:`spectral_peak_test` and (with a significant peak's sinusoid
    removed) :func:`whiteness_test`: whiteness is about what the listed items leave. An item is
    reported when its Holm-adjusted p-value is below ``alpha`` AND its size is at least
    :func:`materiality_floor` and 1e-3 of the median tension (a structure far below the
    noise is not worth a user's attention even when a long recording makes it significant).
    Hints of the backward elimination are kept under the same floor.

    Parameters
    ----------
    prob : cdprid.diagnosis._problem.Problem
    Z : (n, 6, p) weighted, matched-filtered columns of the extended model (all samples)
    y : (n, 6) its weighted target
    feats : dict
        Signal name -> weighted, matched-filtered structure regressors ``(n, 6, q)``.
    hints : list of dict
        Vocabulary effects removed by the backward elimination (``size`` in N).
    tension_noise_N : (m,) tension noise std estimated from the data
    alpha : float
        Family-wise level.

    Returns
    -------
    (items, rule)
        ``items``: the ``unexplained`` entries (``where``, ``size``, ``correlates_with``,
        ``p_value`` (Holm-adjusted), ``p_raw``, ``test``, ``floor_N`` and test-specific
        keys); ``rule``: the floor, the noise scale, the family and every test's outcome.
    """
    train, wrow = prob.train, prob.wrow
    struct = structure_tests({k: F[train] for k, F in feats.items()}, Z[train], y[train], wrow,
                             prob.lags, 1.0, n_tests=1)
    for u in struct:
        u["p_raw"] = u.pop("p_value")
        u["test"] = "structure regression (HAC Wald)"
    n_family = len(struct) + 2
    pre = holm([u["p_raw"] for u in struct] + [1.0, 1.0])[:len(struct)]
    cols = [feats[u["correlates_with"]] for u, p in zip(struct, pre, strict=True) if p < alpha]
    guard = prob.lags
    r_ext = heldout_residuals(Z, y, wrow, prob.use, prob.test, prob.n_folds, guard)
    mask = ~np.isnan(r_ext[:, 0])
    rms = float(np.sqrt(np.mean(r_ext[mask] ** 2))) if mask.any() else 0.0
    # never below the findings' absolute floor (noise-free data: numerical residue)
    floor = max(materiality_floor(tension_noise_N, rms),
                finding_floor_N(prob.tension[prob.use]))
    r = heldout_residuals(np.concatenate([Z] + cols, axis=2), y, wrow, prob.use, prob.test,
                          prob.n_folds, guard) if cols else r_ext
    step = decorrelation_step(prob.filt, max(1, 4 * prob.lags))
    span = mask.sum() * prob.dt
    spec = spectral_peak_test(r, mask, prob.dt, 3.0 / max(span, 1e-9), prob.cutoff_hz)
    if spec and holm([u["p_raw"] for u in struct] + [spec["p_raw"], 1.0])[-2] < alpha:
        r = remove_sinusoid(r, mask, prob.dt, spec["frequency_hz"])
    resid_tests = [spec, whiteness_test(r, mask, step, prob.dt)]
    tests = struct + [u for u in resid_tests if u]
    adj = holm([u["p_raw"] for u in tests] + [1.0] * (n_family - len(tests)))
    items = []
    for u, p in zip(tests, adj, strict=False):
        u.update(p_value=float(p), floor_N=floor,
                 significant=bool(p < alpha and u["size"] >= floor))
        if u["significant"]:
            items.append({**u, **in_own_units(u, prob)})
    kept_hints = [{**h, "floor_N": floor, "test": "backward elimination (hint)"}
                  for h in hints if h["size"] >= floor]
    rule = {
        "floor_N": floor,
        "rule": (f"reported when the Holm-adjusted p < {alpha:g} over the {n_family} tests "
                 f"and the size >= floor_N = {MATERIAL_FRACTION:g} x max(tension noise std, "
                 "held-out force residual rms)"),
        "tension_noise_N": float(np.sqrt(np.mean(np.square(tension_noise_N)))),
        "heldout_force_residual_rms_N": rms,
        "multiple_testing": f"Holm over {n_family} tests",
        "tests": [{k: v for k, v in u.items() if k not in ("coefficients",)} for u in tests],
    }
    return items + kept_hints, rule
