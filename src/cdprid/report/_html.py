"""Self-contained ``report.html`` pages: inline CSS, figures as base64 PNG, no script, no
network. One file that shows everything when copied elsewhere or opened by double-click.

The building blocks are shared by ``diagnose --report`` (:mod:`cdprid.report._html_diagnosis`)
and ``identify --report`` (:mod:`cdprid.report._html_identify`): :func:`page`, :func:`table`,
:func:`img`, :func:`timeline_figure`, :func:`list_section`.
"""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path

import numpy as np

__all__ = ["episode_bands", "estimates_table", "img", "list_section", "page", "table",
           "timeline_figure"]

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:0 auto;
max-width:1100px;padding:1.2em 2em;color:#1b1b1b;line-height:1.45}
h1{font-size:1.5em;margin-bottom:.2em}h2{font-size:1.15em;margin-top:1.6em;
border-bottom:1px solid #ddd;padding-bottom:.2em}
.verdict{border-left:6px solid #2b6cb0;background:#eef4fb;padding:.7em 1em;margin:1em 0}
.verdict.warn{border-color:#c05621;background:#fdf3ea}
.verdict.ok{border-color:#2f855a;background:#edf8f1}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1em 0}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.85em;color:#555}
.warning{color:#9c4221}.muted{color:#666;font-size:.85em}
footer{margin-top:2em;border-top:1px solid #ddd;padding-top:.6em;font-size:.85em;color:#555}
code{background:#f5f5f5;padding:0 .2em}
"""


def esc(text) -> str:
    """HTML-escaped ``str(text)``."""
    return html.escape(str(text), quote=True)


def fmt(v, digits: int = 4) -> str:
    """A number with ``digits`` significant digits ("-" for None or NaN)."""
    if v is None:
        return "-"
    try:
        f = float(v)
    except (TypeError, ValueError):
        return esc(v)
    return "-" if not np.isfinite(f) else f"{f:.{digits}g}"


def png_bytes(fig) -> bytes:
    """The figure as PNG bytes (110 dpi), figure closed."""
    from cdprid.report._figures import pyplot

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return buf.getvalue()


def img(png: bytes | Path, caption: str, alt: str | None = None) -> str:
    """A ``<figure>`` with the PNG embedded as a base64 data URI."""
    data = png.read_bytes() if isinstance(png, Path) else png
    b64 = base64.b64encode(data).decode("ascii")
    return (f'<figure><img src="data:image/png;base64,{b64}" alt="{esc(alt or caption)}">'
            f"<figcaption>{esc(caption)}</figcaption></figure>")


def table(header: list[str], rows: list[list], numeric: set[int] | None = None) -> str:
    """An HTML table; cells are escaped; columns in ``numeric`` are right-aligned."""
    numeric = numeric or set()
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f'<td class="num">{esc(c)}</td>' if i in numeric else f"<td>{esc(c)}</td>"
                         for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def list_section(title: str, items, css: str = "") -> str:
    """``<h2>`` and a bullet list (or "None.")."""
    items = list(items)
    if not items:
        return f"<h2>{esc(title)}</h2><p>None.</p>"
    lis = "".join(f'<li class="{css}">{esc(i)}</li>' for i in items)
    return f"<h2>{esc(title)}</h2><ul>{lis}</ul>"


def estimates_table(params: dict) -> str:
    """Estimates against their Cramer-Rao bound: value, std (HAC), std (i.i.d.), the bound's
    std and the efficiency std / bound (1 is the best any unbiased estimator can do)."""
    rows = []
    for k, v in params.items():
        rows.append([k, fmt(v["value"], 6), fmt(v["std"], 3), fmt(v.get("std_iid"), 3),
                     fmt(v.get("crb_std"), 3), fmt(v.get("efficiency"), 3)])
    return table(["parameter", "estimate", "std (HAC)", "std (i.i.d., eq. 20)",
                  "Cramer-Rao std", "std / bound"], rows, numeric={1, 2, 3, 4, 5})


def timeline_figure(t, residuals: dict, use=None, train=None, episodes=(), explained=None,
                    title: str = "") -> bytes:
    """The force-residual timeline: |force residual| per model over time, the held-out part
    marked, episodes shaded with their kind, and (``explained``: a pair of model names) the
    part of the residual the findings explain shaded between the two curves.

    Parameters
    ----------
    t : array (n,), s
    residuals : dict
        Model name -> residual (n, >=3); rows 0-2 are forces, N.
    use : array (n,) of bool, optional
        Samples to draw (others are gaps).
    train : array (n,) of bool, optional
        Training samples (give it only for a train/held-out split in time); the used samples
        outside it are shaded grey as held out.
    episodes : sequence of dict
        ``start_s``, ``end_s``, ``kind``.
    explained : (str, str), optional
        Names in ``residuals`` of the model before and after the findings.
    """
    from cdprid.report._figures import pyplot

    plt = pyplot()
    t = np.asarray(t, float)
    use = np.ones(len(t), bool) if use is None else np.asarray(use, bool)
    fig, ax = plt.subplots(figsize=(10, 3.6))
    norms = {}
    for name, r in residuals.items():
        n = np.linalg.norm(np.asarray(r, float)[:, :3], axis=1)
        norms[name] = np.where(use, n, np.nan)
        rms = np.sqrt(np.nanmean(norms[name] ** 2) / 3)
        ax.plot(t, norms[name], lw=0.7, label=f"{name} (rms per force axis {rms:.3g} N)")
    if explained is not None and all(k in norms for k in explained):
        a, b = norms[explained[0]], norms[explained[1]]
        ax.fill_between(t, a, b, where=np.isfinite(a) & np.isfinite(b) & (a > b),
                        color="tab:green", alpha=0.35, lw=0, label="explained by the findings")
    if train is not None:
        held = np.r_[False, use & ~np.asarray(train, bool), False].astype(int)
        edges = np.flatnonzero(np.diff(held))
        for i0, i1 in zip(edges[::2], edges[1::2], strict=True):
            ax.axvspan(t[i0], t[i1 - 1], color="0.6", alpha=0.15, lw=0)
        if len(edges):
            ax.axvspan(np.nan, np.nan, color="0.6", alpha=0.15, label="held out")
    episode_bands(ax, episodes)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|force residual| [N]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=7, ncol=3)
    ax.set_title(title, fontsize=9)
    return png_bytes(fig)


#: colours of the episode bands, one per kind (sorted by name)
EPISODE_COLOURS = ("tab:purple", "tab:orange", "tab:red", "tab:brown", "tab:pink", "tab:olive")


def episode_bands(ax, episodes) -> list:
    """Shade each episode on ``ax`` (a band from ``start_s`` to ``end_s``, s, one colour per
    kind, a legend entry per kind) and label it at the top with its number and kind.

    Parameters
    ----------
    ax : matplotlib Axes
        Time on its x axis, s.
    episodes : sequence of dict
        ``start_s``, ``end_s`` (s) and ``kind``.

    Returns
    -------
    list of (Polygon, Text)
        The band and the label of each episode, in the order given.
    """
    kinds = sorted({str(e.get("kind", "")) for e in episodes})
    out = []
    for i, e in enumerate(episodes, 1):
        kind = str(e.get("kind", ""))
        c = EPISODE_COLOURS[kinds.index(kind) % len(EPISODE_COLOURS)]
        a, b = float(e["start_s"]), float(e["end_s"])
        band = ax.axvspan(a, b, color=c, alpha=0.25, lw=0)
        text = ax.text(0.5 * (a + b), 0.98, f"{i}: {kind or 'unnamed'}", color="0.15",
                       fontsize=7, ha="center", va="top", rotation=90, clip_on=True,
                       transform=ax.get_xaxis_transform(),
                       bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": c,
                             "alpha": 0.85})
        out.append((band, text))
    for k in kinds:
        ax.axvspan(np.nan, np.nan, color=EPISODE_COLOURS[kinds.index(k) % len(EPISODE_COLOURS)],
                   alpha=0.25, label=f"episode: {k or 'unnamed'}")
    return out


def page(title: str, verdict_html: str, body: list[str], made_by: dict, tone: str = "") -> str:
    """The whole HTML document: title, verdict first, the sections, the footer with the
    command and version that made it."""
    cmd = esc(made_by.get("command", "cdprid"))
    ver = esc(made_by.get("version", "?"))
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{esc(title)}</title><style>{CSS}</style></head><body>"
            f"<h1>{esc(title)}</h1><div class=\"verdict {tone}\">{verdict_html}</div>"
            + "".join(body)
            + f"<footer>Made by <code>{cmd}</code> with cdprid {ver}. This page is one file: "
            "the figures are embedded, it loads nothing from the network.</footer>"
            "</body></html>\n")
