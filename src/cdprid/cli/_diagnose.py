"""``cdprid diagnose``: model-discrepancy diagnosis of a dataset."""

from __future__ import annotations

import sys

__all__ = ["configure"]


def _run(args) -> int:
    from cdprid.base import atomic_dir, check_distinct, check_output, check_pending, write_json
    from cdprid.cli._artifacts import check_outputs, made_by, write_diagnosis_outputs
    from cdprid.diagnosis import diagnose
    from cdprid.io import dataset_inputs, read_dataset
    from cdprid.report import format_values, save_report, write_diagnosis_html

    check_distinct({"--json": args.json, "--report": args.report, "--mat": args.mat})
    inputs = dataset_inputs(args.dataset)
    if args.json:
        check_output(args.json, force=args.force, flag="--json", inputs=inputs)
    check_outputs(args, inputs, args.force)
    source = args.source or _auto_source(args.dataset)
    ds = read_dataset(args.dataset, require_tensions=source == "tensions")
    drive_fit = None
    if source == "currents":  # the drive model is identify's; its reference checked first
        from cdprid.identify import choose_reference, identify_currents
        from cdprid.io import read_drives

        choose_reference(args.reference, ds.robot, read_drives(ds.path))
        drive_fit = identify_currents

    def progress(msg):
        check_pending()  # a safe point for a signal recorded where it could not be raised
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    res = diagnose(ds, train_until=args.train_until, alpha=args.alpha, n_null=args.n_null,
                   max_effects=args.max_effects, seed=args.seed, progress=progress,
                   keep_episodes=args.keep_episodes, source=source,
                   reference=args.reference, drive_fit=drive_fit)
    for note in res.notes:
        print(f"note: {note}")
    print(f"base model: m = {res.base_parameters['m'].value:.5g} kg, held-out force residual "
          f"rms {res.base_heldout_rms:.4g} N")
    if not res.findings:
        print("findings: none (no candidate effect passes the tests)")
    for f in res.findings:
        alias = f"  [indistinguishable here from: {', '.join(f.aliases)}]" if f.aliases else ""
        print(f"finding: {f.effect} {f.parameters}  interval {f.interval}  "
              f"p = {f.p_value:.2e}{alias}")
    for e in res.episodes:
        print(f"episode: {e['kind']} {e['start_s']:.2f}-{e['end_s']:.2f} s"
              + (f", force {e['size_N']:.3g} N" if e.get("size_N") is not None else "")
              + (f", {e['energy_J']:+.2g} J" if "energy_J" in e else "")
              + (f", p = {e['p_value']:.2g}" if e["kind"] != "pose_glitches" else ""))
    with_ep = res.extended_heldout_rms_with_episodes
    print(f"extended model: m = {res.extended_parameters['m'].value:.5g} kg, held-out force "
          f"residual rms {res.extended_heldout_rms:.4g} N"
          + (f" ({with_ep:.4g} N with the episodes)" if res.episodes and with_ep else ""))
    for c in res.competing:
        print(f"competing model: {c.by} {format_values(c.parameters)} instead of "
              f"{c.replaces}: held-out force residual rms {c.heldout_force_rms_N:.4g} N "
              f"({100 * c.relative_difference:+.2f} %, p = {c.p_worse:.2g} that it is "
              "worse): the data cannot tell the two models apart")
    w = res.info.get("weight_at_rest")
    if w:
        print(f"weight at rest ({w['n_samples']} samples): {w['raw_kg']:.4g} kg from the raw "
              f"tensions, {w['corrected_kg']:.4g} kg with the extended model's sensor "
              "corrections (compare with the identified m)")
    for u in res.unexplained:
        print(f"unexplained: {u.where}: {u.size:.3g} N rms, like {u.correlates_with} "
              f"(p = {u.p_value:.2e})")
    for u in res.not_named:
        print(f"not named: {u.effect} {format_values(u.parameters)}, 95 % interval "
              f"{format_values(u.interval)} (p = {u.p_value:.2g} alone: {u.why})")
    if args.json:
        print(f"wrote {write_json(args.json, res.as_json(), force=args.force)}")
    if args.report:
        with atomic_dir(args.report, force=args.force) as tmp:
            save_report(res, tmp, dataset_name=str(args.dataset))
            write_diagnosis_html(res, tmp, str(args.dataset), made_by(args))
        print(f"wrote {args.report}/report.md and {args.report}/report.html")
    write_diagnosis_outputs(args, res, res.as_json())
    return 0


def _auto_source(dataset) -> str:
    """``currents`` for a dataset folder with currents.csv and no tensions.csv, else
    ``tensions`` (whose absence read_dataset then reports)."""
    from pathlib import Path

    root = Path(dataset)
    if not (root / "tensions.csv").exists() and (root / "currents.csv").exists():
        return "currents"
    return "tensions"


def configure(p) -> None:
    """Give the ``diagnose`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)

    p.description = ("Fit the paper's model, test every effect of the vocabulary as an "
                     "extension (HAC Wald tests, Bonferroni, null-calibrated thresholds, blocked "
                     "held-out validation), refit the accepted effects and report the held-out "
                     "gain.")
    p.add_argument("dataset", help="dataset folder (spec v1)")
    p.add_argument("--json", help="write the diagnosis JSON here")
    p.add_argument("--report", help="write report.md, PNG figures and a self-contained "
                   "report.html into this folder")
    p.add_argument("--mat", help="write the diagnosis as a MATLAB .mat file (estimates, "
                   "residuals with time, findings, episodes; docs/formats.md)")
    p.add_argument("--train-until", type=V.finite_float, default=None,
                   help="fit on t < S, measure the held-out gain on t >= S")
    p.add_argument("--alpha", type=V.probability, default=1e-3,
                   help="family-wise false-positive rate, in (0, 1)")
    p.add_argument("--n-null", type=V.positive_int, default=30,
                   help="null replicates for calibration (>= 1)")
    p.add_argument("--max-effects", type=V.positive_int, default=8,
                   help="greedy selection stops here (>= 1)")
    p.add_argument("--seed", type=V.nonneg_int, default=0, help="seed of the null simulation")
    p.add_argument("--quiet", action="store_true", help="no progress output")
    p.add_argument("--source", choices=("tensions", "currents"), default=None,
                   help="the force stream: tensions (load cells, tensions.csv) or currents "
                   "(the winch drives' currents.csv as the datasheet's tension k i; the "
                   "drive-side effects are the candidates: docs/drives.md); default: "
                   "currents when the dataset has currents.csv and no tensions.csv")
    p.add_argument("--reference", default=None, metavar="drive:K",
                   help="--source currents: the drive whose torque constant is the scale "
                   "(default: robot.toml's drive_reference = true, else a drive with "
                   "torque_constant_tolerance = 0)")
    p.add_argument("--keep-episodes", action="store_true", help="keep the located episodes "
                   "(pushes, load-cell steps, pose glitches, outside work) in the fits; they "
                   "are reported either way")
    p.add_argument("--force", action="store_true",
                   help="replace an existing --json / --mat file or --report folder")
    p.set_defaults(func=_run)
