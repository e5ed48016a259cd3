"""Stage 3 and 5 of the diagnosis: model selection that can take back a pick.

Swap (replace a finding by a better alternative) and backward elimination (a finding stays
only if removing it worsens held-out prediction given the others), with the same held-out
criterion as the forward steps.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from cdprid.base import Status, chi2_logsf, chi2_sf
from cdprid.diagnosis._base import BaseFit
from cdprid.diagnosis._candidates import (
    Candidate,
    alias_label,
    implausible,
    separated_by,
    swap_alternatives,
    vocab_interval,
    vocab_params,
)
from cdprid.diagnosis._context import DiagnosisContext
from cdprid.diagnosis._model import ThetaLayout
from cdprid.diagnosis._parts import RankedCandidate
from cdprid.diagnosis._problem import Problem, design, heldout_rms, seed_design
from cdprid.diagnosis._profile import clock_index, clock_removal_test, joint_delay
from cdprid.diagnosis._refit import refit_gauss_newton
from cdprid.diagnosis._result import Finding
from cdprid.diagnosis._signature import OWN_SIGNATURE, without_own_signature
from cdprid.diagnosis._testing import aliases_of, partial_wald, partial_wald_many
from cdprid.diagnosis._unexplained import structure_tests
from cdprid.effects import DIAGNOSIS


def extends_base(c: Candidate) -> bool:
    """The candidate extends the base model itself (its form's ``base_model``, e.g. the
    rotational dynamics: the full inertial parameters) instead of adding theta blocks."""
    return DIAGNOSIS[c.effect].base_model


def finding_columns(c: Candidate, layout: ThetaLayout, active_idx: list, n_model: int) -> list:
    """Columns of the linearised extended model ``[A, C_active]`` that belong to a finding."""
    if extends_base(c):
        return list(range(4, n_model))
    idx = layout.candidate_indices(c.effect, c.cable)
    # a parameter held at its bound (see :func:`refit`) has no column
    return [n_model + active_idx.index(i) for i in idx if i in active_idx]


def wald_given_others(Z, y, cols: list, lags: int) -> tuple[float, float]:
    """HAC Wald statistic and p-value of the columns ``cols`` of ``Z`` given all its other
    columns (both partialled out of ``y``), on the rows given (the training samples)."""
    rest = [j for j in range(Z.shape[2]) if j not in cols]
    n = Z.shape[0]
    Q = np.linalg.qr(Z[:, :, rest].reshape(-1, len(rest)))[0]
    Ct = Z[:, :, cols].reshape(-1, len(cols))
    Ct = (Ct - Q @ (Q.T @ Ct)).reshape(n, 6, -1)
    yt = y.reshape(-1, 1)
    yt = (yt - Q @ (Q.T @ yt)).reshape(n, 6)
    stat, _, _ = partial_wald(Ct, yt, lags)
    return float(stat), float(chi2_sf(stat, len(cols)))


def weakest_finding(accepted: list, Z, y, cols_of, heldout_rms, train, lags: int,
                    min_gain: float, thr_p: float, structure: tuple = (),
                    exact: dict | None = None):
    """Backward step: the finding whose removal hurts held-out prediction least, if it fails.

    A finding stays when removing it (given every other column of ``Z``: the other
    findings, and the unexplained structure ``structure`` when there is one) worsens the
    held-out RMS by more than ``min_gain`` (relative) AND its HAC Wald test given the others
    passes ``thr_p``. A structure signal (``(n, 6, q)`` each, appended to ``Z``) that is the
    finding's own signature is used only where it is not
    (:func:`cdprid.diagnosis._signature.without_own_signature`): a signal that spans an
    effect's form does not displace it. Returns ``(index, reason, p)`` of the worst failing
    finding (p: its Wald p-value given the others), or ``(None, '', 1.0)``. ``exact`` maps a
    finding's index to its ``(gain, p)`` found otherwise (the clock offset by exact shifts:
    :func:`cdprid.diagnosis._profile.clock_removal_test`), used instead of the linear ones.
    """
    Z0 = Z
    Z = np.concatenate([Z0, *structure], axis=2) if structure else Z0
    p = Z.shape[2]
    rms_full = heldout_rms(Z, y)
    worst, worst_gain, reason, worst_p = None, np.inf, "", 1.0
    for k, c in enumerate(accepted):
        cols = cols_of(c)
        if not cols:  # every parameter held at its bound: nothing left of it
            return k, f"{c.label}: every parameter at its bound", 1.0
        if structure:  # the signals with the finding's own signature projected out
            Z = np.concatenate([Z0] + [without_own_signature(Z0[:, :, cols], F, train)[0]
                                       for F in structure], axis=2)
        if exact and k in exact:
            gain, pv = exact[k]
        else:
            rest = [j for j in range(p) if j not in cols]
            gain = 1.0 - rms_full / heldout_rms(Z[:, :, rest], y)
            _, pv = wald_given_others(Z[train], y[train], cols, lags)
        fails = gain < min_gain or not pv < thr_p
        if fails and gain < worst_gain:
            worst, worst_gain, worst_p = k, gain, pv
            reason = (f"{c.label}: removing it changes the held-out rms by {100 * gain:.2f} % "
                      f"(p = {pv:.2e}) given the others")
    return worst, reason, worst_p


def best_swap(accepted: list, alts: dict, Z, y, cols_of, alt_cols, heldout_rms,
              min_gain: float, near: dict | None = None):
    """Swap step: replace one finding by an alternative when that predicts held-out better.

    Returns ``(k, alternative, ties)``: the finding index and its better replacement (or
    ``None``), and for every finding the alternatives within ``min_gain`` of it (the data
    cannot tell them apart: reported as aliases); with ``near`` (finding -> alternatives),
    only those can be ties.
    """
    p = Z.shape[2]
    rms_now = heldout_rms(Z, y)
    best, best_rms = (None, None), rms_now * (1.0 - min_gain)
    ties = {}
    for k, c in enumerate(accepted):
        if extends_base(c):
            continue
        rest = [j for j in range(p) if j not in cols_of(c)]
        ties[c] = []
        for a in alts[c]:
            r = heldout_rms(np.concatenate([Z[:, :, rest], alt_cols(a)], axis=2), y)
            if r < best_rms:
                best, best_rms = (k, a), r
            elif r < rms_now * (1.0 + min_gain) and (near is None or a in near[c]):
                ties[c].append(a)
    return best[0], best[1], ties


# ----------------------------------------------------------------------------- stages


@dataclasses.dataclass(frozen=True)
class Selection:
    """The current extended model: effect parameters, x, and the findings behind them."""

    theta: np.ndarray
    x: np.ndarray  # (10,) m, m s_G, inertia (the last six used only when rotational)
    rotational: bool
    active_idx: tuple
    accepted: tuple  # Candidate, one per finding
    findings: tuple  # Finding
    th_cov: np.ndarray
    status: Status = Status.CONVERGED  # how the last nonlinear refit ended


def start(prob: Problem, base: BaseFit) -> Selection:
    """The base model as a selection without findings.

    Parameters
    ----------
    prob : Problem
    base : BaseFit

    Returns
    -------
    Selection
        Theta zero (``prob.theta0`` when set: the drive model on currents), x the base fit's
        (padded to 10), no finding.
    """
    size = prob.layout.size
    x = np.concatenate([base.x, np.zeros(10 - len(base.x))])
    theta = np.zeros(size) if prob.theta0 is None else np.array(prob.theta0, float)
    return Selection(theta, x, base.rotational, (), (), (), np.zeros((size, size)))


def linear_model(prob: Problem, s: Selection):
    """Weighted columns ``[A, C_active]``, target, number of model columns, all columns C."""
    y_now, Am, C = design(prob, s.theta, s.x, s.rotational)
    ai = list(s.active_idx)
    Ca = C[:, :, ai]
    Z = np.concatenate([Am, Ca], axis=2) * prob.wrow[None, :, None]
    y = (y_now + np.einsum("nij,j->ni", Ca, s.theta[ai])) * prob.wrow
    return Z, y, Am.shape[2], C


def refit(prob: Problem, s: Selection, theta=None, active_idx=None, rotational=None,
          x=None) -> Selection:
    """Nonlinear refit (Gauss-Newton) of the active effects with x, from the given start.

    A parameter that must be >= 0 (friction, drag, cable mass, pulley radius) and refits
    negative is held at its bound 0 and the others refitted (an active-set step, at most
    three): a coefficient that is zero in truth (a friction without viscous part) then does
    not make its effect implausible or pull the others. When the clock offset is active it
    starts from its joint profile (:func:`cdprid.diagnosis._profile.joint_delay`: every other
    parameter of this model re-solved at each exact shift), never from the previous model's
    value.
    """
    theta = np.array(s.theta if theta is None else theta, float)
    active = list(s.active_idx if active_idx is None else active_idx)
    rot = s.rotational if rotational is None else rotational
    x0 = s.x if x is None else x
    di = clock_index(prob)
    if di is not None and di in active:  # the clock offset profiled jointly, every refit
        theta[di] = joint_delay(prob, theta, x0, rot, active)
    for _ in range(4):
        th, x_new, th_cov, lin, status = refit_gauss_newton(functools.partial(design, prob), theta,
                                                    x0, active, rot, prob.wrow, prob.train,
                                                    prob.lags)
        neg = [i for i in active if i in prob.layout.nonneg and th[i] < 0]
        if not neg:
            break
        theta = np.array(th, float)
        theta[neg] = 0.0
        active = [i for i in active if i not in neg]
    if lin is not None:
        seed_design(prob, th, x_new, rot, lin)
    return dataclasses.replace(s, theta=th, x=x_new, rotational=rot,
                               active_idx=tuple(active), th_cov=th_cov, status=status)


def with_vocabulary(prob: Problem, s: Selection, extra: DiagnosisContext) -> Selection:
    """Findings' parameters and intervals recomputed from the current theta."""
    std = np.sqrt(np.clip(np.diag(s.th_cov), 0, None))
    fs = tuple(dataclasses.replace(
        f, parameters=vocab_params(c, s.theta, prob.layout, extra, s.th_cov),
        interval=vocab_interval(c, s.theta, std, prob.layout, extra))
        for c, f in zip(s.accepted, s.findings, strict=True))
    return dataclasses.replace(s, findings=fs)


def candidate_columns(prob: Problem, base: BaseFit, s: Selection, C, candidates) -> dict:
    """Weighted linearised columns of every candidate not yet in the model."""
    out = {}
    for c in candidates:
        if c in s.accepted:
            continue
        if extends_base(c):
            if s.rotational:
                continue
            K = np.einsum("nij,j->ni", base.A10[:, :, :4] - base.A4, s.x[:4])[:, :, None]
            cols = np.concatenate([K, base.A10[:, :, 4:]], axis=2)
        else:
            cols = C[:, :, prob.layout.candidate_indices(c.effect, c.cable)]
        out[c] = cols * prob.wrow[None, :, None]
    return out


def score_step(prob: Problem, Zbase, y_target, cand_cols: dict, null_gen, alpha: float,
               n_tests: int):
    """Wald statistics of every candidate (base partialled out) and the step's threshold.

    The threshold is the stricter of Bonferroni and the alpha-quantile of the smallest
    p-value over candidates on the null replicates. Returns ``(scored, pcols, yt, thr_p)``,
    ``scored`` sorted best first as ``(p, candidate, stat, dof, beta)``.
    """
    train = prob.train
    Q = np.linalg.qr(Zbase[train].reshape(-1, Zbase.shape[2]))[0]
    ntr = int(train.sum())

    def partial(M):
        M2 = M.reshape(ntr * 6, -1)
        return (M2 - Q @ (Q.T @ M2)).reshape(ntr, 6, -1)

    yt = partial(y_target[train])[:, :, 0]
    pcols = {c: partial(cols[train]) for c, cols in cand_cols.items()}
    scored = []
    for c, Ct in pcols.items():
        stat, beta, _ = partial_wald(Ct, yt, prob.lags)
        scored.append((float(chi2_sf(stat, Ct.shape[2])), c, stat, Ct.shape[2], beta))
    # rank by the log p-value (no underflow: at p = 0 a raw statistic would favour the
    # candidates with more degrees of freedom)
    scored.sort(key=lambda r: (float(chi2_logsf(r[2], r[3])), -r[2]))
    Yn = [partial((e * prob.wrow)[train])[:, :, 0] for e in null_gen]
    thr_p = alpha / n_tests
    if Yn:
        Yn = np.stack(Yn, axis=-1)
        null_p = np.ones(Yn.shape[-1])
        for Ct in pcols.values():
            st = partial_wald_many(Ct, Yn, prob.lags)
            null_p = np.minimum(null_p, chi2_sf(st, Ct.shape[2]))
        thr_p = min(thr_p, float(np.quantile(null_p, alpha)))
    return scored, pcols, yt, thr_p


def effect_size_N(prob: Problem, s: Selection, c) -> float:
    """The wrench a candidate adds to the model at ``s``, as a force (RMS over the used
    samples, N): its linearised columns times its parameters; the larger of the force rows
    and the moment rows divided by the platform's radius (an attachment error acts through
    the moment)."""
    idx = [i for i in prob.layout.candidate_indices(c.effect, c.cable) if i in s.active_idx]
    if not idx:
        return 0.0
    _, _, C = design(prob, s.theta, s.x, s.rotational)
    w = np.einsum("nij,j->ni", C[prob.use][:, :, idx], s.theta[idx])
    radius = max(float(np.median(np.linalg.norm(np.asarray(prob.d.robot.P_b), axis=1))), 1e-3)
    return float(max(np.sqrt(np.mean(w[:, :3] ** 2)), np.sqrt(np.mean(w[:, 3:] ** 2)) / radius))


#: the extended model's mass may differ from the base model's by this factor at most (an
#: effect that needs more is compensating something else, not explaining it)
MASS_RATIO = 2.0


def implausible_findings(prob: Problem, t: Selection, extra: DiagnosisContext):
    """``(k, reason)`` for every finding of ``t`` whose refitted parameters lie outside their
    vocabulary range (:func:`cdprid.diagnosis._candidates.implausible`), in model order."""
    for k, c in enumerate(t.accepted):
        why = implausible(c.effect, vocab_params(c, t.theta, prob.layout, extra, t.th_cov))
        if why:
            yield k, why


def model_implausible(prob: Problem, t: Selection, extra: DiagnosisContext) -> str:
    """A reason when the jointly refitted model is implausible, else '': an earlier
    finding pushed outside its plausible range, or a mass changed by more than
    :data:`MASS_RATIO` from the base model's."""
    for k, why in implausible_findings(prob, t, extra):
        return f"{t.accepted[k].label} becomes {why}"
    m0 = DiagnosisContext.of(extra).base_mass_kg
    if m0 and not (m0 / MASS_RATIO < t.x[0] < m0 * MASS_RATIO):
        return f"the mass becomes {t.x[0]:.3g} kg (base model {m0:.3g} kg)"
    return ""


def refit_rejected(prob: Problem, t: Selection, c, extra: DiagnosisContext) -> str:
    """Why candidate ``c``, refitted in ``t``, may not be named ('' when it may): its own
    parameters or the joint model implausible, or its force below the finding floor."""
    why = implausible(c.effect, vocab_params(c, t.theta, prob.layout, extra, t.th_cov)) \
        or model_implausible(prob, t, extra)
    if why:
        return f"refits to an implausible value ({why})"
    if not extends_base(c):
        size, floor = effect_size_N(prob, t, c), DiagnosisContext.of(extra).finding_floor_N
        if size < floor:
            return f"its force, {size:.2g} N rms, is below the detection floor {floor:.2g} N"
    return ""


def try_candidate(prob: Problem, s: Selection, c, rms_before: float, min_gain: float,
                  extra: DiagnosisContext):
    """Add one candidate, refit, and check plausibility and the held-out gain after the refit.

    Returns ``(selection, parameters, rms_after, '')`` or ``(None, None, nan, reason)``.
    """
    layout = prob.layout
    if extends_base(c):
        t = refit(prob, s, rotational=True)
    else:
        # Gauss-Newton from the current linearisation (already computed: its first
        # iteration is the joint linear fit, whose new coefficients are ``beta``)
        idx = layout.candidate_indices(c.effect, c.cable)
        t = refit(prob, s, active_idx=sorted(set(s.active_idx) | set(idx)))
        if not set(idx) & set(t.active_idx):
            return None, None, float("nan"), "refits to its bounds (every parameter at 0)"
    why = refit_rejected(prob, t, c, extra)
    if t.status is Status.FAILED:
        why = "refit finds no step that lowers the training cost (not converged)"
    if why:
        return None, None, float("nan"), why
    vocab = vocab_params(c, t.theta, layout, extra, t.th_cov)
    Z, y, _, _ = linear_model(prob, t)
    rms_after = heldout_rms(prob, Z, y)
    if rms_after > rms_before * (1 - min_gain):
        return None, None, rms_after, (f"after the nonlinear refit improves the held-out "
                                       f"residual too little ({rms_before:.4f} -> "
                                       f"{rms_after:.4f})")
    return t, vocab, rms_after, ""


def forward_step(prob, base, s, candidates, null_gen, alpha, min_gain, extra, say, step,
                 thr_floor: float = 1.0):
    """One greedy forward step; returns ``(selection or None, ranking, thr_p)``.

    ``null_gen`` yields the null residual replicates that calibrate the threshold (may be
    empty: Bonferroni alone); ``thr_floor`` caps the threshold (the first step's calibrated
    threshold, reused by the later steps).
    """
    n_tests = len(candidates)
    Zbase, y_target, _, C = linear_model(prob, s)
    rms_before = heldout_rms(prob, Zbase, y_target)
    cand_cols = candidate_columns(prob, base, s, C, candidates)
    say(f"step {step}: testing {len(cand_cols)} candidates, "
        + ("thresholds from null replicates simulated from the fitted base model"
           if thr_floor >= 1.0 else "the first step's calibrated threshold"))
    scored, pcols, yt, thr_p = score_step(prob, Zbase, y_target, cand_cols, null_gen, alpha,
                                          n_tests)
    thr_p = min(thr_p, thr_floor)
    ranking = [RankedCandidate(candidate=c.label, statistic=float(st), dof=int(q),
                               p_value=float(p), p_bonferroni=float(min(1.0, p * n_tests)))
               for p, c, st, q, _ in scored[:15]]
    # the significant leaders, tried in order of their (linearised) held-out prediction
    leaders = []
    for p_best, c, stat, q, _ in scored[:6]:
        say(f"step {step}: candidate {c.label}: statistic {stat:.1f} (dof {q}), "
            f"p = {p_best:.2e}, threshold p < {thr_p:.2e}")
        if not p_best < thr_p:
            break
        rms_lin = heldout_rms(prob, np.concatenate([Zbase, cand_cols[c]], axis=2), y_target)
        leaders.append((rms_lin, p_best, c, stat))
    leaders.sort(key=lambda r: r[0])
    for rms_lin, p_best, c, stat in leaders:
        if rms_lin > rms_before * (1 - min_gain):
            say(f"step {step}: {c.label} does not improve the held-out residual enough "
                f"({rms_before:.4f} -> {rms_lin:.4f}); stop")
            break
        t, vocab, rms_after, why = try_candidate(prob, s, c, rms_before, min_gain, extra)
        if t is None:
            say(f"step {step}: {c.label} {why}; rejected, trying the next candidate")
            continue
        std = np.sqrt(np.clip(np.diag(t.th_cov), 0, None))
        f = Finding(effect=c.vocabulary_effect, parameters=vocab,
                    interval=vocab_interval(c, t.theta, std, prob.layout, extra),
                    aliases=aliases_of(c, [(r[0], r[1], r[2]) for r in scored], pcols),
                    heldout_rms_before=float(rms_before), heldout_rms_after=float(rms_after),
                    p_value=float(min(1.0, p_best * n_tests)), statistic=float(stat),
                    threshold=float(thr_p))
        say(f"step {step}: accepted {c.label}: {vocab}; held-out rms {rms_before:.4f} -> "
            f"{rms_after:.4f} (weighted units)")
        return (dataclasses.replace(t, accepted=t.accepted + (c,), findings=t.findings + (f,)),
                ranking, thr_p)
    return None, ranking, thr_p


def swap_stage(prob: Problem, s: Selection, candidates, min_gain: float,
               extra: DiagnosisContext, say):
    """Replace findings by better alternatives; ties within ``min_gain`` become aliases."""
    layout = prob.layout
    ties: dict = {}
    for _ in range(len(s.accepted)):
        Z, y, n_model, C = linear_model(prob, s)
        cols_of = functools.partial(finding_columns, layout=layout,
                                    active_idx=list(s.active_idx), n_model=n_model)
        near = {c: swap_alternatives(c, candidates, list(s.accepted)) for c in s.accepted}
        alts = {c: [a for a in candidates if a not in s.accepted and a.effect in
                    {b.effect for b in near[c]} | {c.effect}] for c in s.accepted}

        def alt_cols(a, C=C):
            return C[:, :, layout.candidate_indices(a.effect, a.cable)] * prob.wrow[None, :, None]

        k, alt, ties = best_swap(list(s.accepted), alts, Z, y, cols_of, alt_cols,
                                 functools.partial(heldout_rms, prob), min_gain, near)
        if k is None:
            break
        old = s.accepted[k]
        idx_old = layout.candidate_indices(old.effect, old.cable)
        theta = s.theta.copy()
        theta[idx_old] = 0.0
        active = sorted((set(s.active_idx) - set(idx_old))
                        | set(layout.candidate_indices(alt.effect, alt.cable)))
        t = refit(prob, s, theta=theta, active_idx=active)
        if refit_rejected(prob, t, alt, extra):
            break
        say(f"swap: {old.label} -> {alt.label} predicts the held-out data better")
        f = s.findings[k]
        f = dataclasses.replace(f, effect=alt.vocabulary_effect,
                                aliases=sorted(set(f.aliases) | {alias_label(old)}))
        s = dataclasses.replace(
            t, accepted=s.accepted[:k] + (alt,) + s.accepted[k + 1:],
            findings=s.findings[:k] + (f,) + s.findings[k + 1:])
    s = with_vocabulary(prob, s, extra)
    fs = tuple(dataclasses.replace(
        f, aliases=sorted(set(f.aliases) | {alias_label(a) for a in ties.get(c, [])}),
        separated_by={**f.separated_by, **{alias_label(a): separated_by(c.effect, a.effect)
                                           for a in ties.get(c, [])}})
        for c, f in zip(s.accepted, s.findings, strict=True))
    return dataclasses.replace(s, findings=fs)


def backward_stage(prob: Problem, s: Selection, feats: dict, alpha: float, min_gain: float,
                   thr_p: float, extra: DiagnosisContext, say):
    """Backward elimination given the others and the unexplained structure.

    Returns the selection and the hints (findings removed because an unexplained structure
    explains them better) for ``unexplained``.
    """
    train, use, wrow = prob.train, prob.use, prob.wrow
    hints = []
    while s.accepted:
        Z, y, n_model, _ = linear_model(prob, s)
        struct = structure_tests({k: F[train] for k, F in feats.items()}, Z[train], y[train],
                                 wrow, prob.lags, alpha)
        sig_names = [u["correlates_with"] for u in struct if u["significant"]]
        Zs = np.concatenate([Z] + [feats[k] for k in sig_names], axis=2)
        cols_of = functools.partial(finding_columns, layout=prob.layout,
                                    active_idx=list(s.active_idx), n_model=n_model)
        _say_signatures(s.accepted, Z, {k: feats[k] for k in sig_names}, cols_of, train, say)
        k, why, p_given = weakest_finding(list(s.accepted), Z, y, cols_of,
                                          functools.partial(heldout_rms, prob), train,
                                          prob.lags, min_gain, thr_p,
                                          tuple(feats[k] for k in sig_names),
                                          exact=_clock_exact(prob, s, Z, y, cols_of))
        if k is None:
            break
        c, f = s.accepted[k], s.findings[k]
        say(f"backward elimination: {why}; removed")
        if sig_names:  # a vocabulary effect that only fits part of a structure: a hint
            cols = cols_of(c)
            b, *_ = np.linalg.lstsq(Zs[train].reshape(-1, Zs.shape[2]), y[train].reshape(-1),
                                    rcond=None)
            part = np.einsum("nip,p->ni", Zs[use][:, :, cols], b[cols]) / wrow[None, :]
            hints.append({
                "where": c.label, "size": float(np.sqrt(np.mean(part[:, :3] ** 2))),
                "correlates_with": f"the vocabulary effect {c.effect} {f.parameters} fits part "
                "of the residual but is not needed given the other findings and the "
                "unexplained structure (" + ", ".join(sig_names) + ")",
                "p_value": p_given})
        s = withdraw(prob, s, k, extra)
    return s, hints


def _clock_exact(prob: Problem, s: Selection, Z, y, cols_of) -> dict:
    """``{index: (gain, p)}`` of the clock offset finding by exact shifts of the tension
    stream (:func:`cdprid.diagnosis._profile.clock_removal_test`); empty without one."""
    di = clock_index(prob)
    for k, c in enumerate(s.accepted):
        cols = cols_of(c)
        if di is not None and DIAGNOSIS[c.effect].clock and len(cols) == 1:
            return {k: clock_removal_test(prob, Z, y, cols[0], float(s.theta[di]),
                                          float(s.th_cov[di, di]),
                                          functools.partial(heldout_rms, prob))}
    return {}


def _say_signatures(accepted, Z, sigs: dict, cols_of, train, say) -> None:
    """One progress line per finding whose own signature a significant structure signal is."""
    for c in accepted:
        cols = cols_of(c)
        for name, F in sigs.items():
            rho = without_own_signature(Z[:, :, cols], F, train)[1] if cols else 0.0
            if rho >= OWN_SIGNATURE:
                say(f"backward elimination: {name} reproduces {c.label} (canonical correlation "
                    f"{rho:.3f}): {c.label} is tested only against the rest of it")


def withdraw(prob: Problem, s: Selection, k: int, extra: DiagnosisContext) -> Selection:
    """The model refitted without its finding ``k`` (the backward, stability, geometry and
    plausibility stages take findings back with it)."""
    c = s.accepted[k]
    theta, x = s.theta.copy(), s.x.copy()
    rot, active = s.rotational, list(s.active_idx)
    if extends_base(c):
        rot = False
        x[4:] = 0.0
    else:
        idx = prob.layout.candidate_indices(c.effect, c.cable)
        theta[idx] = 0.0
        active = [i for i in active if i not in idx]
    t = refit(prob, s, theta=theta, active_idx=active, rotational=rot, x=x)
    return with_vocabulary(prob, dataclasses.replace(
        t, accepted=s.accepted[:k] + s.accepted[k + 1:],
        findings=s.findings[:k] + s.findings[k + 1:]), extra)
