"""Former location of the figure helpers, kept for the modules not yet switched: everything
lives in :mod:`cdprid.report.figures` (the report layer)."""

from __future__ import annotations

from .report.figures import diagnosis_figures, pyplot, save_fig

__all__ = ["diagnosis_figures", "pyplot", "save_fig"]

