"""Compatibility module: the diagnosis now lives in the package :mod:`cdprid.diagnosis`.

Kept for ``from cdprid.diagnose import ...`` in earlier code and notebooks (new code imports
:mod:`cdprid.diagnosis` and :mod:`cdprid.report.diagnosis`).
"""

from __future__ import annotations

from .diagnosis import CANDIDATE_EFFECTS, DiagnosisResult, Finding, diagnose, estimate_noise
from .report.diagnosis import save_report

__all__ = ["CANDIDATE_EFFECTS", "DiagnosisResult", "Finding", "diagnose", "estimate_noise",
           "save_report"]
