"""``cdprid identify``: the platform's dynamic parameters by least squares.

From a spec-v1 dataset: batch, ``--online`` (:mod:`cdprid.cli._online`), or without load
cells, ``--source currents | free-motion`` (:mod:`cdprid.cli._sources`).
"""

from __future__ import annotations

from pathlib import Path

from cdprid.base import UserError
from cdprid.cli import _artifacts  # --mat, --report
from cdprid.cli._json_args import parse_params, write_json
from cdprid.cli._sources import add_source_options, run_source

__all__ = ["configure", "run"]


def run(args) -> int:
    """Run ``cdprid identify`` with parsed arguments (see :func:`configure`): output checks
    before any work, the batch or online identification, the table on stdout, warnings on
    stderr, ``--json``, ``--mat``, ``--report``."""
    from cdprid.core import check_geometry
    from cdprid.io import read_dataset

    if getattr(args, "source", "tensions") != "tensions":  # issue 41: no load cells
        return run_source(args, parse_params, write_json)
    if getattr(args, "estimator", None) is not None:
        raise UserError("--estimator applies to --source currents only.")
    _refuse_before_work(args)
    ds = read_dataset(args.dataset)
    check_geometry(ds.robot, ds.pose_t, ds.position, ds.quaternion)
    params = parse_params(args.params)
    if args.online:
        from cdprid.cli._online import run_online_cli

        if args.differentiator is None:
            args.differentiator = "sihd2-cascade"
        return run_online_cli(ds, args, params)
    return _run_batch(ds, args, params)


def _refuse_before_work(args) -> None:
    """Outputs that may not be written and options that do not go together: one sentence
    (exit 2) before the dataset is read."""
    from cdprid.base import check_distinct, check_output
    from cdprid.io import dataset_inputs

    force = getattr(args, "force", False)
    inputs = dataset_inputs(args.dataset)
    png = Path(args.out_csv).with_suffix(".png") if args.out_csv else None
    check_distinct({"--json": args.json, "--out-csv": args.out_csv,
                    "--out-csv (its figure)": png if args.online else None})
    if args.json:
        check_output(args.json, force=force, flag="--json", inputs=inputs)
    _artifacts.check_outputs(args, inputs, force)  # --mat, --report (batch only)
    if args.online:
        if args.out_csv:
            check_output(args.out_csv, force=force, flag="--out-csv", inputs=inputs)
            check_output(png, force=force, flag="--out-csv", inputs=inputs)
    elif args.out_csv:
        raise UserError("--out-csv is the parameter trajectory of --online; batch identify "
                        "writes --json.")
    if args.online:  # batch-only options are refused, not silently ignored
        ignored = [flag for flag, on in (("--physical", getattr(args, "physical", False)),
                                         (f"--weighting {args.weighting}",
                                          args.weighting is not None),
                                         ("--std iid", args.std != "hac"))
                   if on]
        if ignored:
            raise UserError(f"{ignored[0]} applies to batch identify only; --online uses "
                            "recursive least squares with its own (HAC) std: drop it or drop "
                            "--online.")
    elif args.wrench_filter == "delay":
        raise UserError("--wrench-filter delay exists only with --online (a fixed delay of W tau "
                        "in the stream); batch identify offers matched or none.")


def _run_batch(ds, args, params: dict) -> int:
    """Batch identification: the table on stdout, warnings on stderr, the outputs."""
    from cdprid.cli._echo import echo_warnings
    from cdprid.identify import format_table, identify_dataset

    if args.differentiator is None:
        args.differentiator = "euler-filtfilt"
    rep = identify_dataset(
        ds,
        model=args.model,
        differentiator=args.differentiator,
        params=params,
        t_start=args.t_start,
        t_end=args.t_end,
        trim=args.trim,
        weighting=args.weighting or "eiv",
        covariance=args.std,
        wrench_filter=args.wrench_filter or "matched",
        inertia_about=args.inertia_about, keep_episodes=args.keep_episodes)
    if getattr(args, "physical", False):
        from cdprid.identify import physical_report

        rep = physical_report(rep)
    rep = _with_guards(ds, rep)
    print(format_table(rep))
    echo_warnings(rep.warnings)
    if args.json:
        write_json(args.json, rep.as_json(), force=getattr(args, "force", False))
        print(f"wrote {args.json}")
    _artifacts.write_identify_outputs(args, rep, rep.as_json(), str(args.dataset))
    return 0


def _with_guards(ds, rep):
    """The report with the plausibility guards' sentences added to its warnings (issue 25)."""
    import dataclasses

    import numpy as np

    from cdprid.core import input_warnings, result_warnings
    from cdprid.identify import swapped_columns_warning

    if not np.all(np.isfinite(rep.parameters().values)):
        raise UserError("the identification gave non-finite estimates: the data do not "
                        "determine the parameters (check the geometry, the excitation and "
                        "--model).")
    acc = np.asarray(rep.motion.acceleration)
    acc = acc if len(acc) == len(rep.signals.t) else None  # reuse, do not differentiate again
    new = input_warnings(ds, rep.signals, rep.differentiator, rep.params, acc)
    new += result_warnings(ds.robot, rep.result.names, rep.result.x, rep.result.sigma_rho,
                           ds.tension)
    swap = swapped_columns_warning(ds.robot, rep, ds.tension)
    if swap:
        new.append(swap)
    new = [w for w in new if w not in rep.warnings]
    return dataclasses.replace(rep, warnings=tuple(rep.warnings) + tuple(new)) if new else rep


def configure(p) -> None:
    """Give the ``identify`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.base import TRIM_S

    p.description = ("Identify m, m s_G (and the inertia with the full model) from a spec-v1 "
                     "dataset, and print a table like the paper's Table 1. The std is HAC "
                     "(autocorrelation-consistent) by default; eq. 20's value is in the JSON as "
                     "std_iid. Warnings (model mismatch, lag, physics, excitation) go to stderr, "
                     "the table and the JSON 'warnings' list.")
    p.add_argument("dataset", help="dataset folder (spec v1)")
    p.add_argument("--model", choices=["auto", "translation", "full"], default="auto",
                   help="4-parameter translation model (paper eq. 10), 10-parameter model with "
                   "inertia, or auto (default): full when the quaternions show more than 1 deg "
                   "of rotation, else translation")
    p.add_argument("--differentiator", default=None,
                   help="differentiation method (default euler-filtfilt; sihd2-cascade with "
                   "--online); see `cdprid differentiate --help`")
    p.add_argument("--params", help="differentiator parameters as JSON (or a JSON file); "
                   "without cutoff_hz, euler-filtfilt's cutoff is chosen from the data (the "
                   "widest of 1-4 Hz whose predicted errors-in-variables attenuation is "
                   "below 1e-3; a note names it)")
    p.add_argument("--t-start", type=float, default=None, help="start of the time window, s")
    p.add_argument("--t-end", type=float, default=None, help="end of the time window, s")
    p.add_argument("--trim", type=float, default=TRIM_S,
                   help=f"seconds dropped at both ends after differentiation (default {TRIM_S})")
    p.add_argument("--weighting", choices=["eiv", "none", "groups"], default=None,
                   help="batch identify: 'eiv' (default) errors-in-variables GLS, each sample "
                   "whitened by its residual covariance (tension and pose noise estimated from "
                   "the data); 'none' the paper's ordinary least squares; 'groups' separate "
                   "force/moment row weights")
    p.add_argument("--std", choices=["hac", "iid"], default="hac",
                   help="standard deviation shown as 'std': hac (default; accounts for the "
                   "autocorrelation of filtered residuals) or iid (the paper's eqs. 19-21)")
    p.add_argument("--inertia-about", dest="inertia_about", choices=["P", "G"], default="P",
                   help="reference point of the inertia (platform frame): P, the platform's "
                   "reference point (default), or G, the centre of mass")
    p.add_argument("--physical", action="store_true",
                   help="full model constrained to a physically realisable body (m > 0, "
                   "positive definite inertia obeying the triangle inequalities)")
    p.add_argument("--online", action="store_true",
                   help="online identification: causal SIHD-2 cascade + recursive least squares, "
                   "per-sample parameter trajectory (CSV and PNG)")
    p.add_argument("--forgetting", type=float, default=1.0,
                   help="forgetting factor lambda in (0, 1] for --online (memory dt/(1-lambda))")
    p.add_argument("--out-csv", dest="out_csv", default=None,
                   help="parameter trajectory CSV for --online; a PNG of the same name "
                   "(.png) is written beside it")
    p.add_argument("--wrench-filter", dest="wrench_filter", choices=["matched", "delay", "none"],
                   default=None, help="filter W tau like the accelerations: matched (default; "
                   "the differentiator's own low-pass, batch and online), none, or delay "
                   "(--online only)")
    p.add_argument("--keep-episodes", action="store_true", help="keep the located episodes "
                   "(pushes, load-cell steps, glitches; --online: pushes, payload steps) in fits")
    p.add_argument("--json", help="write the result as JSON to this file")
    _artifacts.add_identify_options(p)  # --mat, --report
    p.add_argument("--force", action="store_true",
                   help="overwrite existing --json / --mat / --report / --out-csv outputs")
    add_source_options(p)
    p.set_defaults(func=run)
