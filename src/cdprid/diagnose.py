"""Compatibility module: the diagnosis now lives in the package :mod:`cdprid.diagnosis`.

Kept for ``from cdprid.diagnose import ...`` in earlier code and notebooks; new code imports
:mod:`cdprid.diagnosis` (and :func:`cdprid.report.diagnosis.save_report` for the report).
``save_report`` is resolved on first use from the report layer (this alias is not a
computation module importing figures); to be removed once notebooks and ``tuning`` import the
new names.
"""

from __future__ import annotations

import importlib

from .diagnosis import CANDIDATE_EFFECTS, DiagnosisResult, Finding, diagnose, estimate_noise

__all__ = ["CANDIDATE_EFFECTS", "DiagnosisResult", "Finding", "diagnose", "estimate_noise"]


def __getattr__(name: str):
    if name == "save_report":  # deprecated alias of cdprid.report.diagnosis.save_report
        return importlib.import_module("cdprid.report.diagnosis").save_report
    raise AttributeError(f"module 'cdprid.diagnose' has no attribute {name!r}")
