"""Model-discrepancy diagnosis: what the paper's model gets wrong, why, and what fixing it gains.

A package of named stages (see ``docs/diagnosis.md``): :mod:`.problem` (data, masks, held-out
criterion), :mod:`.model` (one forward model for every effect), :mod:`.base` (base fit, noise,
null model), :mod:`.candidates` (effect x cable and their vocabulary form), :mod:`.testing`
(HAC Wald tests), :mod:`.selection` (forward steps, swap, backward elimination), :mod:`.refit`
(Gauss-Newton), :mod:`.unexplained` (residual structure), :mod:`.result` and :mod:`._parts`
(frozen, typed results that read also as their JSON objects), :mod:`._context` (what the
checks read besides the fit) and :mod:`.pipeline` (:func:`diagnose`, the stages in order).
The report writer is :func:`cdprid.report._diagnosis.save_report`.
"""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.diagnosis._base import base_fit as base_fit
from cdprid.diagnosis._base import noise_levels as noise_levels
from cdprid.diagnosis._base import null_residuals as null_residuals
from cdprid.diagnosis._budget import subset as subset
from cdprid.diagnosis._candidates import CANDIDATE_EFFECTS as CANDIDATE_EFFECTS
from cdprid.diagnosis._candidates import Candidate as Candidate
from cdprid.diagnosis._info import DiagnosisInfo as DiagnosisInfo
from cdprid.diagnosis._info import EpisodeRecord as EpisodeRecord
from cdprid.diagnosis._candidates import candidate_list as candidate_list
from cdprid.diagnosis._context import DiagnosisContext as DiagnosisContext
from cdprid.diagnosis._model import ThetaLayout as ThetaLayout
from cdprid.diagnosis._model import rotvec_from_quat as rotvec_from_quat
from cdprid.diagnosis._parts import CompetingModel as CompetingModel
from cdprid.diagnosis._parts import NotNamed as NotNamed
from cdprid.diagnosis._parts import ParameterEstimate as ParameterEstimate
from cdprid.diagnosis._parts import ParameterEstimates as ParameterEstimates
from cdprid.diagnosis._parts import RankedCandidate as RankedCandidate
from cdprid.diagnosis._parts import Unexplained as Unexplained
from cdprid.diagnosis._pipeline import diagnose as diagnose
from cdprid.diagnosis._problem import design as design
from cdprid.diagnosis._problem import force_heldout_rms as force_heldout_rms
from cdprid.diagnosis._problem import prepare as prepare
from cdprid.diagnosis._result import DiagnosisResult as DiagnosisResult
from cdprid.diagnosis._result import Finding as Finding
from cdprid.diagnosis._selection import start as start
from cdprid.diagnosis._testing import estimate_noise as estimate_noise
from cdprid.diagnosis._unexplained import decimate_runs as decimate_runs
from cdprid.diagnosis._unexplained import periodogram as periodogram
