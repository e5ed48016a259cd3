"""``report.html`` of ``cdprid diagnose --report``: verdict, residual timeline (findings and
episodes shaded), findings with their held-out gain, competing models, estimates, what
remains unexplained, notes and warnings, the figures of report.md, the command and version."""

from __future__ import annotations

from pathlib import Path

from cdprid.report._html import esc, fmt, img, list_section, page, table, timeline_figure
from cdprid.report._mat import episodes_of

__all__ = ["diagnosis_html", "write_diagnosis_html"]

_FIGURES = {  # report.md's figures, in this order, with their captions
    "residual_time.png": "Residual W tau - A x per wrench axis, base and extended model.",
    "residual_signals.png": "Base residual against candidate signals, its autocorrelation "
                            "and spectrum.",
    "ranking.png": "Candidate effects at the first step (Wald statistic).",
    "unexplained.png": "What remains unexplained after the extended model.",
    "clock_profile.png": "Clock stage: held-out profile over tension clock offsets.",
}


def _gain(before: float, after: float) -> str:
    """``12.3 % lower`` (or higher) of ``after`` against ``before``."""
    if not before > 0:
        return "-"
    g = 100 * (1 - after / before)
    return f"{abs(g):.1f} % {'lower' if g >= 0 else 'higher'}"


def _verdict(res) -> tuple[str, str]:
    b, e = res.base_heldout_rms, res.extended_heldout_rms
    if not res.findings:
        text = ("<b>No finding.</b> No effect of the vocabulary passes the tests: the paper's "
                f"model explains these data within their noise (held-out force residual rms "
                f"{fmt(b)} N).")
        tone = "ok"
    else:
        names = ", ".join(f.effect for f in res.findings)
        text = (f"<b>{len(res.findings)} finding(s): {esc(names)}.</b> The extended model "
                f"predicts the held-out data with force residual rms {fmt(e)} N instead of "
                f"{fmt(b)} N ({_gain(b, e)}).")
        tone = "warn"
    if res.competing:
        text += (f" {len(res.competing)} competing model(s) fit as well: the data cannot "
                 "choose between them (below).")
    if res.unexplained:
        text += (f" {len(res.unexplained)} structure(s) of the residual remain unexplained "
                 "(below).")
    return text, tone


def _findings(res) -> str:
    if not res.findings:
        return "<h2>Findings</h2><p>None: every candidate of the vocabulary was tested.</p>"
    rows = []
    for f in res.findings:
        rows.append([f.effect, _values(f.parameters), _values(f.interval),
                     f"{fmt(f.heldout_rms_before)} -> {fmt(f.heldout_rms_after)}",
                     _gain(f.heldout_rms_before, f.heldout_rms_after), f"{f.p_value:.2e}",
                     ", ".join(f.aliases) or "-"])
    return ("<h2>Findings and their held-out gain</h2>" + table(
        ["effect", "estimate", "95 % interval", "held-out rms before -> after (weighted)",
         "gain", "p (Bonferroni)", "indistinguishable here from"], rows, numeric={4, 5}))


def _values(d: dict) -> str:
    from cdprid.report._diagnosis import format_values

    return format_values(d)


def _competing(res) -> str:
    tried = res.info.get("competing_models_tried", 0)
    if not res.competing:
        return ("<h2>Competing models</h2><p>" + (
            f"None: {tried} alternative complete model(s) (a finding replaced by one of its "
            "aliases, or the model of the search's other start, refitted) predict the "
            "held-out data worse than the final model." if tried
            else "None: no finding has an alias to try.") + "</p>")
    rows = [[m.replaces, m.by, _values(m.parameters), fmt(m.heldout_force_rms_N),
             f"{100 * m.relative_difference:+.2f} %", fmt(m.p_worse, 2)]
            for m in res.competing]
    return ("<h2>Competing models</h2><p>Complete alternatives within the noise of the final "
            "model: the data cannot choose between them.</p>" + table(
                ["instead of", "this model has", "with", "held-out force rms, N", "difference",
                 "p_worse"], rows, numeric={3, 4, 5}))


def _estimates(res) -> str:
    bp, ep = res.base_parameters, res.extended_parameters
    rows = []
    for k in dict.fromkeys(list(bp) + list(ep)):
        b, e = bp.get(k), ep.get(k)
        rows.append([k, fmt(None if b is None else b.value, 6),
                     fmt(None if b is None else b.std, 3),
                     fmt(None if e is None else e.value, 6),
                     fmt(None if e is None else e.std, 3)])
    return ("<h2>Estimates</h2>" + table(
        ["parameter", "base model", "std (HAC)", "extended model", "std (HAC)"], rows,
        numeric={1, 2, 3, 4})
            + "<p class=\"muted\">The diagnosis computes no Cramer-Rao bound; "
            "<code>cdprid identify --report</code> shows the estimates against it.</p>")


def _unexplained(res) -> str:
    rows = [[u.where, fmt(u.size, 3), u.correlates_with, f"{u.p_value:.2e}"]
            for u in res.unexplained]
    out = "<h2>What remains unexplained</h2>"
    out += (table(["where", "size [N rms]", "correlates with", "p (Holm)"], rows, numeric={1, 3})
            if rows else "<p>Nothing: no test finds a material structure in the residual of "
            "the extended model.</p>")
    nn = res.not_named
    if nn:
        out += "<p>Checked and not named:</p>" + table(
            ["effect", "size", "95 % interval", "p", "why not named"],
            [[u.effect, _values(u.parameters), _values(u.interval),
              fmt(u.p_value, 2), u.why] for u in nn], numeric={3})
    return out


def diagnosis_html(res, out_dir: Path, dataset_name: str, made_by: dict) -> str:
    """The HTML text of a diagnosis report (figures read from ``out_dir``'s PNG files);
    parameters as :func:`write_diagnosis_html`."""
    A = res.arrays
    eps = episodes_of(res) or episodes_of(res.as_json())  # an attribute or a JSON key
    body = []
    if "t" in A:
        resid = {"base model": A["residual_base"]}
        if res.findings:
            resid["extended model"] = A["residual_extended"]
        body.append("<h2>Residual timeline</h2>" + img(
            timeline_figure(A["t"], resid, use=A.get("use"), train=A.get("train")
                            if res.info.get("train_until") is not None else None,
                            episodes=eps, explained=("base model", "extended model")
                            if res.findings else None,
                            title="force residual of the base and the extended model"),
            "Norm of the force residual over time (matched-filtered): green, the part the "
            f"findings explain; held-out data: {res.info.get('heldout', '?')}"
            + ("; coloured bands, episodes." if eps else "; no episodes in this result.")))
    body += [_findings(res), _competing(res), _estimates(res), _unexplained(res)]
    warnings = list(getattr(res, "warnings", []) or [])
    body.append(list_section("Notes", res.notes))
    body.append(list_section("Warnings", warnings, css="warning"))
    figs = [img(out_dir / n, cap) for n, cap in _FIGURES.items() if (out_dir / n).is_file()]
    body.append("<h2>Figures of report.md</h2>" + "".join(figs))
    verdict, tone = _verdict(res)
    return page(f"Diagnosis of {dataset_name}", verdict, body, made_by, tone)


def write_diagnosis_html(res, out_dir, dataset_name: str, made_by: dict) -> Path:
    """Write ``out_dir/report.html`` after :func:`cdprid.report.save_report`, whose
    PNG files it embeds.

    Parameters
    ----------
    res : cdprid.diagnosis.DiagnosisResult
        The diagnosis; an ``episodes`` attribute (list of objects or dicts with ``start_s``,
        ``end_s`` in s and ``kind``) is shaded on the residual timeline when present.
    out_dir : path
        The report folder holding report.md's PNG figures.
    dataset_name : str
    made_by : dict
        ``command`` and ``version`` shown in the footer.

    Returns
    -------
    Path
        ``out_dir / "report.html"``.
    """
    out = Path(out_dir) / "report.html"
    out.write_text(diagnosis_html(res, Path(out_dir), dataset_name, made_by), encoding="utf-8")
    return out

