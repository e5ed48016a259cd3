"""Report of a diagnosis: ``report.md`` with tables, findings, what remains unexplained, figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def not_named_lines(result) -> list[str]:
    """The ``Checked and not named`` section of report.md.

    The sizes of the effects a real recording always holds (friction on every pulley, a clock
    offset) when the search did not name them.

    Parameters
    ----------
    result : DiagnosisResult
        Its ``not_named`` items are listed.

    Returns
    -------
    list of str
        Markdown lines; [] when there is nothing to list.
    """
    items = result.not_named
    if not items:
        return []
    lines = ["", "## Checked and not named", "",
             "Fitted on top of the extended model (linearised, training samples); the interval "
             "is 95 % (HAC) and p is that of the effect alone, before any multiple-testing "
             "correction.", "", "| effect | size | 95 % interval | p | why not named |",
             "|---|---|---|---|---|"]
    for u in items:
        lines.append(f"| {u.effect} | {format_values(u.parameters)} | "
                     f"{format_values(u.interval)} | {u.p_value:.2g} | {u.why} |")
    return lines + [""]


def competing_lines(result) -> list[str]:
    """The ``Competing models`` section: complete alternatives within the noise of the final
    model (one finding replaced by one of its aliases, or the model of the search's second
    start, everything refitted)."""
    items = getattr(result, "competing", None) or []
    tried = result.info.get("competing_models_tried", 0)
    if not items:
        return ["", "## Competing models", "",
                f"None: {tried} alternative model(s) (a finding replaced by one of its aliases, "
                "or the model of the search's other start, refitted) predict the held-out data "
                "worse than the final model."
                if tried else "No finding has an alias to try.", ""]
    lines = ["", "## Competing models", "",
             f"{len(items)} of {tried} alternative complete models (a finding replaced by one of "
             "its aliases, or the model the search reached from its other start, every effect "
             "refitted) predict the held-out data as well as the final "
             "model: the held-out RMS differs by less than the search's gate, or a "
             "Diebold-Mariano test does not find the alternative worse (p_worse > 0.05). The "
             "data cannot choose between them; a recording that separates the effects can.", "",
             "| instead of | this model has | with | held-out force rms, N | difference | "
             "p_worse |", "|---|---|---|---|---|---|"]
    for m in items:
        lines.append(f"| {m.replaces} | {m.by} | {format_values(m.parameters)} | "
                     f"{m.heldout_force_rms_N:.4g} | {100 * m.relative_difference:+.2f} % "
                     f"| {m.p_worse:.2g} |")
    return lines + [""]


def format_values(d: dict) -> str:
    """``key value, key [lo, hi]`` with 3 significant digits.

    Numbers and lists of them; a nested dict, e.g. the parameters of each effect of a
    competing model, in parentheses.

    Parameters
    ----------
    d : dict
        Values by name (units as the caller's).

    Returns
    -------
    str
    """
    def one(v):
        if isinstance(v, dict):
            return "(" + format_values(v) + ")"
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(one(x) for x in v) + "]"
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)
    return ", ".join(f"{k} {one(v)}" for k, v in d.items())


def unexplained_lines(result) -> list[str]:
    """The ``What remains unexplained`` section of report.md (items, rule, every test)."""
    lines = ["", "## What remains unexplained", ""]
    rule = result.info.get("unexplained_rule")
    if rule:
        lines += [f"Tests of the extended model's residual: structure regressions (sign of "
                  "cable velocity, tension level, pose, slow drift; HAC Wald), a spectral peak "
                  "of the held-out force residual and its whiteness over time; "
                  f"{rule['multiple_testing']}. An item is {rule['rule']} "
                  f"(floor {rule['floor_N']:.3g} N: tension noise {rule['tension_noise_N']:.3g} "
                  f"N, held-out force residual rms {rule['heldout_force_residual_rms_N']:.3g} "
                  "N).", ""]
    if not result.unexplained:
        lines += ["Nothing: no test finds a material structure in the residual of the "
                  "extended model.", ""]
    else:
        lines += ["These are not findings: no effect of the vocabulary explains them. A "
                  "vocabulary effect listed here fitted part of a structure without "
                  "explaining it and was removed.", "",
                  "| where | size [N rms] | correlates with | p (Holm) |", "|---|---|---|---|"]
        for u in result.unexplained:
            lines.append(f"| {u.where} | {u.size:.3g} | {u.correlates_with} | "
                         f"{u.p_value:.2e} |")
        lines.append("")
    if rule:
        lines += ["Every test:", "", "| test | correlates with | where | size [N] | p raw | "
                  "p (Holm) | listed |", "|---|---|---|---|---|---|---|"]
        for u in rule["tests"]:
            extra = (f" (n_eff {u['effective_sample_size']}, {u['lags']} lags, spacing "
                     f"{u['spacing_s']:.3g} s)" if "effective_sample_size" in u else "")
            lines.append(f"| {u['test']}{extra} | {u['correlates_with']} | {u['where']} | "
                         f"{u['size']:.3g} | {u['p_raw']:.2e} | {u['p_value']:.2e} | "
                         f"{'yes' if u['significant'] else 'no'} |")
        lines.append("")
    return lines


def unexplained_figure(result, out: Path) -> Path:
    """Extended residual over time, its spectrum (peak marked) and autocorrelation."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cdprid.diagnosis import decimate_runs, periodogram
    from cdprid.report._figures import save_fig

    A = result.arrays
    t, r, use = A["t"], A["residual_extended"], A["use"]
    dt = float(np.median(np.diff(t)))
    tests = (result.info.get("unexplained_rule") or {}).get("tests", [])
    fig, axs = plt.subplots(3, 1, figsize=(10, 9))
    for i, c in enumerate("xyz"):
        axs[0].plot(t[use], r[use, i], lw=0.6, label=f"f{c}")
    axs[0].set_ylabel("extended residual [N]")
    axs[0].set_xlabel("t [s]")
    axs[0].legend(fontsize=8)
    axs[0].set_title("; ".join(f"{u.correlates_with[:40]} ({u.size:.2g} N)"
                               for u in result.unexplained[:3]) or "nothing unexplained",
                     fontsize=8)
    for i, c in enumerate("xyz"):
        f, P = periodogram(r[:, i], use, dt)
        axs[1].semilogy(f[1:], P[1:] + 1e-300, lw=0.6, label=f"f{c}")
    for u in tests:
        if "frequency_hz" in u:
            axs[1].axvline(u["frequency_hz"], color="k", ls="--", lw=0.8,
                           label=f"peak {u['frequency_hz']:.3g} Hz (p {u['p_value']:.1e})")
    axs[1].set_xlim(0, min(10.0, 0.5 / dt))
    axs[1].set_xlabel("frequency [Hz]")
    axs[1].set_ylabel("periodogram [N^2]")
    axs[1].legend(fontsize=8)
    white = [u for u in tests if "spacing_s" in u]
    step = max(1, int(round(white[0]["spacing_s"] / dt))) if white else 1
    h = white[0]["lags"] if white else 20
    for i, c in enumerate("xyz"):
        x, rid = decimate_runs(r[:, i], use, step)
        x = x - x.mean()
        acf = [float(x[k:][rid[k:] == rid[:-k]] @ x[:-k][rid[k:] == rid[:-k]] / (x @ x))
               for k in range(1, h + 1)]
        axs[2].plot(np.arange(1, h + 1) * step * dt, acf, "o-", ms=3, lw=0.8, label=f"f{c}")
    if white:
        band = 1.96 / np.sqrt(white[0]["effective_sample_size"])
        axs[2].axhspan(-band, band, color="0.85", label="95 % band of white noise")
    axs[2].set_xlabel("lag [s] (residual taken every %.3g s)" % (step * dt))
    axs[2].set_ylabel("autocorrelation")
    axs[2].legend(fontsize=8)
    fig.suptitle("What remains unexplained after the extended model")
    fig.tight_layout()
    return save_fig(fig, out / "unexplained.png")


def clock_figure(result, out: Path) -> Path | None:
    """The clock stage's held-out profile over tension clock offsets (None without one)."""
    prof = result.info.get("clock_profile") or {}
    if not prof.get("delay_s"):
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from cdprid.report._figures import save_fig

    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    d = 1e3 * np.asarray(prof["delay_s"])
    ax.plot(d, prof["heldout_rms"], "-", color="tab:blue")
    ax.axvline(1e3 * prof["minimum_s"], color="tab:red", ls="--",
               label=f"profile minimum {1e3 * prof['minimum_s']:+.1f} ms")
    for f in result.findings:
        if "delay_s" in f.parameters:
            lo, hi = (1e3 * v for v in f.interval["delay_s"])
            ax.axvspan(lo, hi, color="tab:green", alpha=0.3, label="finding (95 %)")
    ax.set_xlabel("tension clock offset (ms)")
    ax.set_ylabel("held-out rms (weighted)")
    ax.set_title("clock stage: base model with the tension stream shifted")
    ax.legend(loc="best", fontsize=8)
    return save_fig(fig, out / "clock_profile.png")


def episode_lines(result) -> list:
    """The ``## Episodes`` section of report.md.

    What happened only at times and was left out of the fits (:mod:`cdprid.episodes`), and the
    held-out figure with and without it.

    Parameters
    ----------
    result : DiagnosisResult
        Its ``episodes`` (dicts: ``kind``, ``start_s``, ``end_s``, sizes in N, N m, J or m,
        ``p_value``).

    Returns
    -------
    list of str
        Markdown lines; [] when there are no episodes.
    """
    eps = list(getattr(result, "episodes", []) or [])
    if not eps:
        return []
    lines = ["## Episodes", "", "Located in time and left out of every fit (unless "
             "`--keep-episodes`); sizes are means over the episode (force on the platform, base "
             "frame; work done from outside for `energy`).", "",
             "| kind | start (s) | end (s) | size | p |", "|---|---|---|---|---|"]
    for e in eps:
        size = (f"{e['energy_J']:+.3g} J" if "energy_J" in e
                else f"{e.get('n_samples')} samples, up to {1e3 * e.get('largest_m', 0):.0f} mm"
                if e["kind"] == "pose_glitches"
                else f"{e['size_N']:.3g} N, {e['size_Nm']:.3g} N m")
        lines.append(f"| {e['kind']} | {e['start_s']:.2f} | {e['end_s']:.2f} | {size} | "
                     f"{e['p_value']:.2g} |")
    w = getattr(result, "extended_heldout_rms_with_episodes", None)
    if w is not None:
        lines += ["", f"Held-out force residual RMS of the extended model: "
                  f"{result.extended_heldout_rms:.4g} N outside the episodes, {w:.4g} N with "
                  "them.", ""]
    return lines + [""]


def save_report(result, out_dir, dataset_name: str = "dataset") -> Path:
    """Write ``report.md`` and PNG figures of a diagnosis into ``out_dir``.

    Parameters
    ----------
    result : cdprid.diagnosis.DiagnosisResult
    out_dir : path
        Folder (created; the CLI hands a fresh temporary folder of ``atomic_dir``).
    dataset_name : str

    Returns
    -------
    Path
        ``out_dir / "report.md"``.
    """
    from cdprid.report._figures import diagnosis_figures

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    from cdprid.report._timeline import timeline_png

    tl = timeline_png(result, out)  # the residual timeline, episodes shaded and labelled
    figs = ([tl] if tl is not None else []) + diagnosis_figures(result, out)
    figs.append(unexplained_figure(result, out))
    clk = clock_figure(result, out)
    if clk is not None:
        figs.append(clk)
    lines = [f"# Diagnosis of {dataset_name}", ""]
    for note in result.notes:
        lines += [f"**Note:** {note}", ""]
    bp = result.base_parameters
    kind = ("full 10-parameter model: the platform rotates"
            if result.info.get("base_model") == "full" else "paper, translation only")
    lines += [f"## Base model ({kind}, matched filtering)", "",
              "| parameter | estimate | std (HAC) | %std |", "|---|---|---|---|"]
    for k, v in bp.items():
        lines.append(f"| {k} | {v.value:.6g} | {v.std:.3g} | {v.rel_std_percent:.3g} |")
    lines += ["", "Residual RMS per wrench axis (fx, fy, fz [N], mx, my, mz [N m]): "
              + ", ".join(f"{r:.4g}" for r in result.base_residual_rms), ""]
    lines += ["## Findings", ""]
    verdict = result.info.get("verdict")
    if not result.findings:
        lines.append("No effect passes the tests (every candidate of the vocabulary was "
                     "tested): " + (verdict["text"] if verdict else "the held-out residual was not "
                                    "compared with the noise") + ".")
    for f in result.findings:
        lines.append(f"- **{f.effect}** {f.parameters}; 95 % interval {f.interval}; "
                     f"held-out rms {f.heldout_rms_before:.4g} -> {f.heldout_rms_after:.4g} "
                     f"(weighted units); p (Bonferroni) = {f.p_value:.2e}"
                     + (f"; indistinguishable on this data from: {', '.join(f.aliases)}"
                        if f.aliases else ""))
    lines += (competing_lines(result) + not_named_lines(result) + unexplained_lines(result)
              + episode_lines(result))
    lines += ["## Extended model", "", "| parameter | estimate | std (HAC) | change vs base |",
              "|---|---|---|---|"]
    for k, v in result.extended_parameters.items():
        ch = (f"{v.value - bp[k].value:+.4g}" if k in bp
              else "not in the base model")  # never "+nan" in a report
        lines.append(f"| {k} | {v.value:.6g} | {v.std:.3g} | {ch} |")
    lines += ["", f"Held-out force residual RMS: base {result.base_heldout_rms:.4g} N -> "
              f"extended {result.extended_heldout_rms:.4g} N ({result.info['heldout']}).", ""]
    if verdict:
        lines += [f"Verdict: {verdict['text']} ({verdict['definition']}).", ""]
    w = result.info.get("weight_at_rest")
    if w:
        lines += [f"Weight at rest ({w['n_samples']} samples from t = {w['t_first']:.3g} s): "
                  f"{w['raw_kg']:.4g} kg from the raw tensions, {w['corrected_kg']:.4g} kg with "
                  "the extended model's sensor corrections; a common load-cell gain is "
                  "indistinguishable from the mass, so compare m with the latter.", ""]
    ic = result.info["information_criterion"]
    lines += [f"Information criterion ({ic['kind']}): base {ic['base']:.1f}, extended "
              f"{ic['extended']:.1f}.", ""]
    lines += ["## Candidate ranking (first step)", "",
              "| candidate | statistic | dof | p | p Bonferroni |", "|---|---|---|---|---|"]
    for r in result.ranking:
        lines.append(f"| {r.candidate} | {r.statistic:.1f} | {r.dof} | "
                     f"{r.p_value:.2e} | {r.p_bonferroni:.2e} |")
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figs]
    (out / "report.md").write_text("\n".join(lines) + "\n")
    return out / "report.md"
