"""The verdict of a diagnosis: does the final model explain the data within its noise?

"Within its noise" is defined (issue 37): the extended model's held-out force residual RMS
``r`` is at most what the sensor noise alone predicts, ``r0``, times ``1 + margin``. ``r0`` is
the mean over replicates of the held-out force RMS of residuals simulated from the noise levels
estimated from the data (:func:`cdprid.diagnosis._base.null_residuals`: tension and position
noise through the same matched filter and differentiator); ``margin`` is
:data:`Z_ONE_SIDED` times the relative standard deviation of that statistic over the
replicates (its own sampling spread), at least :data:`MIN_MARGIN`. Otherwise the verdict says
how far above it is (``r / r0``).

The noise levels are white-noise levels (high-frequency differences): a coloured sensor noise
(an AR(1) load cell) counts as residual structure, and the text says so.
"""

from __future__ import annotations

import numpy as np

from cdprid.diagnosis._base import null_residuals

#: one-sided 95 % normal quantile
Z_ONE_SIDED = 1.6448536269514722
#: smallest relative margin (the noise levels are themselves estimates)
MIN_MARGIN = 0.05
#: replicates of the noise-only residual
N_REPLICATES = 16


def verdict(prob, noise, x, heldout_force_rms_N: float, n_findings: int, seed: int = 0) -> dict:
    """``{"within_noise", "heldout_force_rms_N", "noise_predicted_rms_N", "margin", "ratio",
    "text"}`` for ``info["verdict"]`` and the report.

    Parameters
    ----------
    prob : cdprid.diagnosis._problem.Problem
    noise : cdprid.diagnosis._base.NoiseLevels
    x : (>= 4,) platform parameters (m, m s_G) of the final model
    heldout_force_rms_N : float
        The final model's held-out force residual RMS, N.
    n_findings : int
        Effects named (the text says "the paper's model" when none).
    seed : int
        Seed of the noise replicates.
    """
    rng = np.random.default_rng(seed + 3701)
    use = prob.use if prob.test is None else prob.test
    reps = np.array([float(np.sqrt(np.mean(e[use][:, :3] ** 2)))
                     for e in null_residuals(prob, noise, np.asarray(x)[:4], N_REPLICATES, rng)])
    r0 = float(np.mean(reps))
    rel = float(np.std(reps, ddof=1) / r0) if r0 > 0 else 0.0
    margin = max(MIN_MARGIN, Z_ONE_SIDED * rel)
    r = float(heldout_force_rms_N)
    ratio = r / r0 if r0 > 0 else float("inf")
    within = bool(r <= r0 * (1.0 + margin))
    who = "the paper's model" if n_findings == 0 else "the extended model"
    if within:
        text = (f"{who} explains this data within its noise: held-out force residual "
                f"{r:.3g} N <= {r0:.3g} N predicted by the sensor noise estimated from the "
                f"data x (1 + {margin:.2g})")
    else:
        text = (f"{who} does not explain this data within its noise: the held-out force "
                f"residual, {r:.3g} N, is {ratio:.3g} times the {r0:.3g} N the sensor noise "
                "estimated from the data predicts (a white-noise level: coloured sensor noise, "
                "effects outside the vocabulary or effects too small to name make up the rest; "
                "see unexplained)")
    return {"within_noise": within, "heldout_force_rms_N": r, "noise_predicted_rms_N": r0,
            "margin": margin, "ratio": ratio, "text": text,
            "definition": ("within the noise when the held-out force rms <= the rms predicted "
                           "by the estimated sensor noise x (1 + margin), margin = 1.645 x the "
                           f"relative std of that rms over {N_REPLICATES} noise replicates "
                           f"(at least {MIN_MARGIN:g})")}
