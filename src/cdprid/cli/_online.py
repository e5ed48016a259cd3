"""``cdprid identify DATASET --online``: the command-line side of online identification.

The computation lives in :mod:`cdprid.identify._online`; this module reads options, writes the
CSV, the
figure and the JSON, and prints the table.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from cdprid.base import UserError, atomic_file, write_json
from cdprid.effects import EXTERNAL_WRENCH
from cdprid.identify import SIHD_METHOD as _SIHD
from cdprid.identify import OnlineResult, online_identify
from cdprid.report import plot_online
from cdprid.signal import METHODS

__all__ = ["format_online_table", "run_online_cli", "write_online_csv"]


def format_online_table(res: OnlineResult) -> str:
    """Plain-text table of the final online estimate (like the paper's Table 1)."""
    lines = [
        f"model: {res.model}   online RLS, lambda = {res.forgetting:g}   wrench filter: "
        f"{res.wrench_filter}   samples: {res.n_samples}",
        f"{'parameter':<10} {'estimate':>14} {'sigma':>12} {'%sigma':>9}",
    ]
    for e in res.parameters():
        lines.append(f"{e.name:<10} {e.value:>14.6g} {e.std:>12.4g} {e.rel_std_percent:>9.3g}")
    lines.append(f"sigma_rho = {float(res.sigma_rho[-1]):.4g}   cond(W_ID) = {res.cond:.4g}   "
                 f"cond scaled = {res.cond_scaled:.4g}   exciting at the end: "
                 f"{'yes' if res.excitation_ok[-1] else 'no'} "
                 f"({100 * res.excitation_ok[res.used].mean() if res.used.any() else 0:.0f} % "
                 "of the used samples)")
    return "\n".join(lines)


def describe_online_episode(e) -> str:
    """One line for an episode flagged online: when, what, how large."""
    what = f"{e.size_N:.3g} N, {e.size_Nm:.3g} N m (mean over the episode)"
    if e.kind == "payload_step" and "mass_change_kg" in e.detail:
        what = (f"mass {e.detail['mass_before_kg']:.4g} -> {e.detail['mass_after_kg']:.4g} kg "
                f"({e.detail['mass_change_kg']:+.3g} kg); the estimate restarted")
    tail = " (still open at the end)" if e.detail.get("open") else ""
    return f"{e.kind} {e.start_s:.2f}-{e.end_s:.2f} s: {what}{tail}"


def episode_notes(episodes, kept: bool) -> list[str]:
    """The note saying what the online detector did with its episodes (empty when none)."""
    if not episodes:
        return []
    n = sum(e.kind == EXTERNAL_WRENCH for e in episodes)
    k = len(episodes) - n
    how = ("reported, the update kept running (--keep-episodes)" if kept else
           "the update frozen during each (its rows left out), restarted at each payload step")
    return [f"{n} external-wrench episode(s) and {k} payload step(s) flagged online: {how}"]


def write_online_csv(res: OnlineResult, path) -> Path:
    """CSV ``t, <names>, sigma_<names>, sigma_rho, excitation, excitation_ok`` (one row/sample)."""
    path = Path(path)
    cols = ["t", *res.names, *(f"sigma_{n}" for n in res.names), "sigma_rho", "excitation",
            "excitation_ok"]
    vals = np.column_stack([res.t, res.x, res.sigma, res.sigma_rho, res.excitation,
                            res.excitation_ok.astype(float)])
    with atomic_file(path, "w") as fh:
        fh.write(",".join(cols) + "\n")
        np.savetxt(fh, vals, delimiter=",", fmt="%.12g")
    return path


def _free_path(path: Path) -> Path:
    """``path`` if it does not exist, else ``stem-1.suffix``, ``stem-2.suffix``, ..."""
    if not path.exists():
        return path
    k = 1
    while (cand := path.with_name(f"{path.stem}-{k}{path.suffix}")).exists():
        k += 1
    return cand


def run_online_cli(ds, args, params) -> int:
    """``cdprid identify DATASET --online``: online identification of a dataset.

    Uses ``args.model``, ``args.differentiator`` (a SIHD-2 cascade; the identify default
    ``euler-filtfilt`` is not causal and is replaced by it, with a note), ``args.t_start``,
    ``args.t_end``, ``args.json``, and, when present, ``args.forgetting`` (default 1.0),
    ``args.out_csv``, ``args.wrench_filter``. Writes the parameter trajectory CSV
    (``args.out_csv``, else ``<json stem>.online.csv`` beside ``args.json``, else
    ``online.csv`` in the working directory; an existing file the user did not name is never
    overwritten: ``-1``, ``-2``... are appended), a PNG of the parameters with +-2 sigma bands
    beside it, prints the final table and writes the JSON of ``cdprid identify --json`` plus
    ``"online": {"forgetting", "csv", "figure", ...}``.

    Parameters
    ----------
    ds : Dataset
    args : argparse.Namespace
        The parsed ``identify`` options.
    params : dict or None
        The SIHD-2 cascade's parameters (ignored when another differentiator was asked for).

    Returns
    -------
    int
        Exit code 0.
    """
    from cdprid.io import align

    method = getattr(args, "differentiator", None) or _SIHD
    notes = []
    if method != _SIHD:
        if METHODS.get(method) is not None and method != "euler-filtfilt":
            raise UserError(f"--online runs the causal SIHD-2 cascade (sihd2-cascade); the "
                             f"differentiator {method!r} is not available on line.")
        notes.append(f"differentiator {method!r} is not causal; the online identification uses "
                     "sihd2-cascade")
        params = {}
    forgetting = getattr(args, "forgetting", None)
    forgetting = 1.0 if forgetting is None else float(forgetting)
    wfilt = getattr(args, "wrench_filter", None) or "matched"
    sig = align(ds, getattr(args, "t_start", None), getattr(args, "t_end", None))
    from cdprid.identify import ROTATION_WARN_DEG, rotation_angle_deg

    rot = rotation_angle_deg(sig.quaternion) if sig.has_rotation else 0.0
    warns = []
    if args.model == "auto":
        args.model = "full" if rot > ROTATION_WARN_DEG else "translation"
    elif args.model == "translation" and rot > ROTATION_WARN_DEG:
        warns.append(f"the platform rotates by up to {rot:.2g} deg but the translation model "
                     "ignores rotation (its inertia and rotating first moment bias m s_G): use "
                     "--model full or auto.")
    if wfilt == "none":
        warns.append("the causal SIHD cascade lags the accelerations but W tau is not filtered "
                     "the same way (--wrench-filter none): m s_G is biased towards zero.")
    if args.model == "full" and not sig.has_rotation:
        raise UserError(f"{ds.path}: the full model needs orientations (qw, qx, qy, qz in "
                         "pose.csv) to identify the inertia; this dataset has none.")
    from cdprid.base import Progress

    prog = Progress("identify --online")
    prog.say(f"recursive identification of {len(sig.t)} samples ({args.model} model) ...")
    keep = bool(getattr(args, "keep_episodes", False))
    res = online_identify(sig, ds.robot, model=args.model, forgetting=forgetting,
                          gains=dict(params or {}), wrench_filter=wfilt,
                          episodes={"freeze": not keep})
    notes += episode_notes(res.episodes, keep)
    prog.say("done; writing the outputs")

    out_csv = getattr(args, "out_csv", None)
    json_path = getattr(args, "json", None)
    if out_csv:
        csv_path = Path(out_csv)
    elif json_path:
        jp = Path(json_path)
        csv_path = _free_path(jp.with_name(jp.stem + ".online.csv"))
    else:
        csv_path = _free_path(Path("online.csv"))
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []  # one transaction: an interrupted run removes what it wrote
    try:
        write_online_csv(res, csv_path)
        written.append(csv_path)
        png_path = csv_path.with_suffix(".png")
        if not out_csv:
            png_path = _free_path(png_path)
        truth = None
        tr = getattr(ds, "truth", {}) or {}
        if "mass" in tr and "first_moment" in tr and args.model == "translation":
            truth = np.r_[tr["mass"], tr["first_moment"]]
        plot_online(res, png_path, truth=truth)
        written.append(png_path)

        from cdprid.core import physical_warnings
        from cdprid.identify import excitation_warnings

        w3, n3 = physical_warnings(res.x_final, res.model, res.hac_cov_final()[0])
        warns += w3
        notes += n3
        A_used = np.asarray(res.A)[np.asarray(res.used, bool)]
        if len(A_used):
            warns += excitation_warnings(res.names, np.linalg.norm(
                A_used.reshape(-1, A_used.shape[-1]), axis=0), res.cond_scaled)
        from cdprid.cli._echo import echo_warnings
        from cdprid.core import input_warnings, result_warnings

        warns += input_warnings(ds, sig, _SIHD, dict(params or {}), res.acceleration)
        warns += result_warnings(ds.robot, res.names, res.x_final, float("nan"), ds.tension)
        print(format_online_table(res))
        for e in res.episodes:
            print(f"episode: {describe_online_episode(e)}")
        for n in (*sig.notes, *notes):
            print(f"note: {n}")
        for w in warns:
            print(f"warning: {w}")
        echo_warnings(warns)
        print(f"wrote {csv_path}")
        print(f"wrote {png_path}")
        if json_path:
            data = res.as_json()
            data.update({"differentiator": _SIHD, "differentiator_params": dict(params or {}),
                         "wrench_filter": res.wrench_filter, "rotation_deg": rot,
                         "notes": [*sig.notes, *notes], "warnings": warns})
            if res.model == "full":
                data["inertia_about"] = "P, platform frame"
            data["online"] = {
                "forgetting": forgetting,
                "csv": str(csv_path),
                "figure": str(png_path),
                "wrench_filter": res.wrench_filter,
                "excitation_ok_final": bool(res.excitation_ok[-1]),
                "excitation_ok_fraction": float(res.excitation_ok[res.used].mean())
                if res.used.any() else 0.0,
            }
            data["episodes"] = [e.as_json() for e in res.episodes]
            write_json(json_path, data)
            print(f"wrote {json_path}")
    except BaseException:
        for path in written:
            with contextlib.suppress(OSError):
                path.unlink()
        raise
    return 0
