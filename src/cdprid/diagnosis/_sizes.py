"""Sizes of the effects the search did not name (``not_named`` in the JSON).

A real recording always holds some friction on its pulleys and some clock offset between its
streams. When the search does not name such an effect (its form has ``report_size``), the
user still gets its size: the linearised joint fit of the effect on top of the final model
(training samples, the final model partialled out), a 95 % HAC interval and the unadjusted
p-value. "Not named" then reads as "smaller than the noise can show" with the interval
saying how small, instead of silence.
"""

from __future__ import annotations

import numpy as np

from cdprid.diagnosis._candidates import vocab_interval, vocab_params
from cdprid.diagnosis._clock import clock_size
from cdprid.diagnosis._context import DiagnosisContext
from cdprid.diagnosis._selection import candidate_columns, linear_model, score_step
from cdprid.diagnosis._testing import partial_wald
from cdprid.effects import DIAGNOSIS

__all__ = ["not_named_sizes"]


def not_named_sizes(prob, base, s, candidates, extra: DiagnosisContext, thr_p: float) -> list:
    """``[{effect, parameters, interval, p_value, statistic, named: False, why}]`` of every
    ``report_size`` candidate not in the final selection ``s``; ``thr_p`` is the search's
    first-step threshold on the p-value (Bonferroni, calibrated by null replicates)."""
    want = [c for c in candidates
            if c not in s.accepted and DIAGNOSIS[c.effect].report_size]
    if not want:
        return []
    Zbase, y, _, C = linear_model(prob, s)
    cols = candidate_columns(prob, base, s, C, want)
    if not cols:
        return []
    scored, pcols, yt, _ = score_step(prob, Zbase, y, cols, (), 1.0, 1)
    out = []
    for p, c, stat, _, beta in scored:
        _, _, V = partial_wald(pcols[c], yt, prob.lags)
        idx = prob.layout.candidate_indices(c.effect, c.cable)
        th, std = np.array(s.theta, float), np.zeros(len(s.theta))
        th[idx] = beta
        std[idx] = np.sqrt(np.clip(np.diag(V), 0, None))
        interval = vocab_interval(c, th, std, prob.layout, extra)
        params = vocab_params(c, th, prob.layout, extra)
        if DIAGNOSIS[c.effect].clock:  # the joint profile, never the linearisation at 0
            js = clock_size(prob, s, c, extra)
            params, interval, p, stat = (js["parameters"], js["interval"], js["p_value"],
                                         js["statistic"])
        why = (f"not significant at the search's threshold (p < {thr_p:.2g})" if p >= thr_p else
               "significant alone but not named: it did not improve the held-out "
               "residual enough, or its refit was implausible (see the progress log)")
        # only for an effect the search's test sees (a 95 % interval excludes 0 by chance one
        # time in twenty: clean data gave -0.07 [-0.12, -0.02] N s/m)
        negative = [k for k in DIAGNOSIS[c.effect].nonneg
                    if k in interval and interval[k][1] < 0] if p < thr_p else []
        if negative:
            why += (f"; {', '.join(negative)} is negative with 95 % confidence, the sign "
                    "opposite to friction between the load cell and the platform (a load "
                    "cell on the winch side of its pulley, or another effect)")
        out.append({"effect": c.vocabulary_effect,
                    "parameters": params,
                    "interval": interval, "p_value": float(p), "statistic": float(stat),
                    "named": False, "why": why})
    return out
