"""``cdprid identify --report DIR``: ``report.md`` with two PNG figures and a self-contained
``report.html`` (verdict, residual timeline with episodes shaded, the estimates against their
Cramer-Rao bound, notes and warnings, the command and version)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cdprid.report._html import (
    estimates_table,
    fmt,
    img,
    list_section,
    page,
    png_bytes,
    table,
    timeline_figure,
)
from cdprid.report._mat import episodes_of

__all__ = ["save_identify_report"]


def _crb_figure(params: dict) -> bytes:
    """Each parameter's std (HAC and i.i.d.) beside its Cramer-Rao bound, log scale."""
    from cdprid.report._figures import pyplot

    plt = pyplot()
    names = list(params)
    y = np.arange(len(names))
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(names) + 1.4))
    for dy, key, label in ((-0.25, "std", "std (HAC)"), (0.0, "std_iid", "std (i.i.d.)"),
                           (0.25, "crb_std", "Cramer-Rao bound")):
        v = np.array([params[n].get(key) if params[n].get(key) is not None else np.nan
                      for n in names], float)
        ax.barh(y + dy, np.where(v > 0, v, np.nan), height=0.25, label=label)
    ax.set_yticks(y, names)
    ax.set_xscale("log")
    ax.invert_yaxis()
    ax.set_xlabel("standard deviation (units of each parameter)")
    ax.legend(fontsize=7, loc="best")
    ax.set_title("Estimates' std against the Cramer-Rao bound", fontsize=9)
    fig.tight_layout()
    return png_bytes(fig)


def _residual(rep) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(rep.regression.t, float)
    r = np.asarray(rep.result.residual, float)
    return t, r.reshape(len(t), -1)


def _verdict(data: dict) -> tuple[str, str]:
    p = data["parameters"]
    eff = [v["efficiency"] for v in p.values() if v.get("efficiency") is not None]
    m = p.get("m")
    text = (f"<b>{len(p)} parameters identified ({data['model']} model)</b> from "
            f"{data['n_samples']} samples; cond(W_ID) {fmt(data['cond'])}, scaled "
            f"{fmt(data['cond_scaled'])}.")
    if m is not None:
        text += f" Mass m = {fmt(m['value'], 6)} &plusmn; {fmt(m['std'], 2)} kg (1 std, HAC)."
    if eff:
        text += (f" The std are {fmt(min(eff), 3)} to {fmt(max(eff), 3)} times the Cramer-Rao "
                 "bound of this recording (1 is the best possible).")
    else:
        text += " The Cramer-Rao bound was not computed for this recording."
    warns = data.get("warnings") or []
    if warns:
        text += f" <b>{len(warns)} warning(s)</b>: read them below before using the numbers."
    return text, "warn" if warns else "ok"


def _markdown(data: dict, dataset_name: str, made_by: dict) -> str:
    lines = [f"# Identification of {dataset_name}", "",
             f"Made by `{made_by['command']}` with cdprid {made_by['version']}.", "",
             "| parameter | estimate | std (HAC) | std (i.i.d.) | Cramer-Rao std | std / bound |",
             "|---|---|---|---|---|---|"]
    for k, v in data["parameters"].items():
        lines.append(f"| {k} | {fmt(v['value'], 6)} | {fmt(v['std'], 3)} | "
                     f"{fmt(v['std_iid'], 3)} | {fmt(v['crb_std'], 3)} | "
                     f"{fmt(v['efficiency'], 3)} |")
    lines += ["", f"sigma_rho = {fmt(data['sigma_rho'])}, cond(W_ID) = {fmt(data['cond'])}, "
              f"scaled {fmt(data['cond_scaled'])}, {data['n_samples']} samples.", ""]
    lines += ["## Warnings", ""] + [f"- {w}" for w in data["warnings"] or ["none"]]
    lines += ["", "## Notes", ""] + [f"- {n}" for n in data["notes"] or ["none"]]
    lines += ["", "## Figures", "", "![residual_time](residual_time.png)", "",
              "![estimates_crb](estimates_crb.png)", ""]
    return "\n".join(lines)


def save_identify_report(rep, data: dict, out_dir, dataset_name: str, made_by: dict) -> Path:
    """Write ``report.md``, ``residual_time.png``, ``estimates_crb.png`` and ``report.html``.

    Parameters
    ----------
    rep : cdprid.identify.IdentificationReport
    data : dict
        ``rep.as_json()`` after the CLI's guards (the numbers shown).
    out_dir : path
        Folder (created; the CLI hands a fresh temporary folder of ``atomic_dir``).
    dataset_name : str
    made_by : dict
        ``command`` and ``version``.

    Returns
    -------
    Path
        ``out_dir / "report.html"``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t, r = _residual(rep)
    eps = episodes_of(rep) or episodes_of(data)
    fig_t = timeline_figure(t, {"identified model": r}, episodes=eps,
                            title="force residual Y_ID - W_ID x of the identified model")
    fig_c = _crb_figure(data["parameters"])
    (out / "residual_time.png").write_bytes(fig_t)
    (out / "estimates_crb.png").write_bytes(fig_c)
    (out / "report.md").write_text(_markdown(data, dataset_name, made_by), encoding="utf-8")
    rms = np.sqrt(np.mean(r**2, axis=0))
    axes = ["fx [N]", "fy [N]", "fz [N]", "mx [N m]", "my [N m]", "mz [N m]"][:r.shape[1]]
    body = [
        "<h2>Residual timeline</h2>" + img(
            fig_t, "Norm of the force residual over time (unweighted, after the matched "
            "filter)" + ("; coloured bands, episodes." if eps else
                         "; no episodes in this result.")),
        "<p>Residual rms per wrench axis:</p>"
        + table(axes, [[fmt(v) for v in rms]], numeric=set(range(len(axes)))),
        "<h2>Estimates against their Cramer-Rao bound</h2>" + estimates_table(
            data["parameters"]) + img(fig_c, "std of each estimate beside the bound."),
        list_section("Warnings", data.get("warnings") or [], css="warning"),
        list_section("Notes", data.get("notes") or []),
    ]
    verdict, tone = _verdict(data)
    html_text = page(f"Identification of {dataset_name}", verdict, body, made_by, tone)
    (out / "report.html").write_text(html_text, encoding="utf-8")
    return out / "report.html"
