"""Model-discrepancy diagnosis: what the paper's model gets wrong, why, and what fixing it gains.

A package of named stages (see ``docs/diagnosis.md``): :mod:`.problem` (data, masks, held-out
criterion), :mod:`.model` (one forward model for every effect), :mod:`.base` (base fit, noise,
null model), :mod:`.candidates` (effect x cable and their vocabulary form), :mod:`.testing`
(HAC Wald tests), :mod:`.selection` (forward steps, swap, backward elimination), :mod:`.refit`
(Gauss-Newton), :mod:`.unexplained` (residual structure), :mod:`.result` (frozen results) and
:mod:`.pipeline` (:func:`diagnose`, the stages in order). The report writer is
:func:`cdprid.report.diagnosis.save_report`.
"""

from cdprid.diagnosis.candidates import CANDIDATE_EFFECTS, Candidate
from cdprid.diagnosis.pipeline import diagnose
from cdprid.diagnosis.result import DiagnosisResult, Finding
from cdprid.diagnosis.testing import estimate_noise

__all__ = ["CANDIDATE_EFFECTS", "Candidate", "DiagnosisResult", "Finding", "diagnose",
           "estimate_noise"]
