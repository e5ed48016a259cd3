"""The residual timeline of ``report.md`` (``diagnose --report``): the figure of the HTML
report (:func:`cdprid.report._html.timeline_figure`), episodes shaded and labelled, written as
a PNG beside the Markdown."""

from __future__ import annotations

from pathlib import Path

from cdprid.report._html import timeline_figure
from cdprid.report._mat import episodes_of

__all__ = ["TIMELINE_PNG", "timeline_png"]

#: file name of the figure in the report folder
TIMELINE_PNG = "residual_timeline.png"


def timeline_png(result, out_dir) -> Path | None:
    """Write the force-residual timeline of a diagnosis (base and extended model, held-out
    part grey, the findings' share green, every episode shaded by kind and labelled with its
    number and kind) to ``out_dir / TIMELINE_PNG``.

    Parameters
    ----------
    result : cdprid.diagnosis.DiagnosisResult
        Its ``arrays`` (``t`` in s, residuals in N and N m, ``use``, ``train``) and its
        ``episodes`` (``start_s``, ``end_s`` in s, ``kind``).
    out_dir : path
        The report folder.

    Returns
    -------
    Path or None
        The PNG written, None when the result holds no time axis.
    """
    A = result.arrays
    if "t" not in A:
        return None
    eps = episodes_of(result)
    resid = {"base model": A["residual_base"]}
    if result.findings:
        resid["extended model"] = A["residual_extended"]
    split = result.info.get("train_until") is not None
    png = timeline_figure(A["t"], resid, use=A.get("use"),
                          train=A.get("train") if split else None, episodes=eps,
                          explained=("base model", "extended model") if result.findings
                          else None,
                          title="force residual of the base and the extended model"
                          + (f"; {len(eps)} episode(s) shaded" if eps else ""))
    path = Path(out_dir) / TIMELINE_PNG
    path.write_bytes(png)
    return path
