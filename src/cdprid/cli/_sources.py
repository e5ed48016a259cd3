"""``cdprid identify --source currents | free-motion``: identification without load cells
(issue 41; ``docs/drives.md``)."""

from __future__ import annotations

__all__ = ["add_source_options", "run_source"]

SOURCES = ("tensions", "currents", "free-motion")


def add_source_options(p) -> None:
    """The ``--source`` and ``--reference`` options of ``identify``."""
    p.add_argument("--source", choices=SOURCES, default="tensions",
                   help="what measures the cable forces: tensions (load cells, default), "
                   "currents (motor currents and winch encoders: the platform and every drive, "
                   "no load cell needed) or free-motion (fewer than 6 cables, winches locked: "
                   "the poses alone)")
    p.add_argument("--reference", default=None,
                   help="--source currents / free-motion: the scale reference, drive:K (drive "
                   "K's datasheet constant and its tolerance), mass (robot.toml [platform] mass "
                   "and mass_uncertainty), mass:KG[:STD_KG] or (currents) "
                   "payload:DIR:KG[:STD_KG] (a second recording DIR with KG added to the "
                   "platform); default: a drive marked "
                   "drive_reference = true, else the stated reference of least relative std")
    p.add_argument("--estimator", choices=("oe", "cls"), default=None,
                   help="--source currents: oe (default; output error: the currents as the "
                   "response, Gauss-Newton from cls, HAC sandwich floored at the current "
                   "noise's own std; docs/currents-estimator.md) or cls (corrected least "
                   "squares: the currents inside the regressor, their noise removed from the "
                   "normal equations)")


def run_source(args, parse_params, write_json) -> int:
    """Run ``identify --source currents | free-motion``: output checks before any work, the
    identification, the table on stdout, warnings on stderr, ``--json`` (written by
    ``write_json``; ``parse_params`` reads ``--params``: both from :mod:`cdprid.cli._json_args`)."""
    from cdprid.base import UserError, check_output
    from cdprid.cli._echo import echo_warnings
    from cdprid.io import dataset_inputs, read_dataset

    force = getattr(args, "force", False)
    if args.json:
        check_output(args.json, force=force, flag="--json", inputs=dataset_inputs(args.dataset))
    bad = [f for f, on in (("--online", args.online), ("--out-csv", args.out_csv),
                           ("--physical", getattr(args, "physical", False)),
                           ("--weighting", args.weighting is not None),
                           ("--std iid", args.std != "hac"),
                           ("--wrench-filter", args.wrench_filter is not None),
                           ("--mat", getattr(args, "mat", None)),
                           ("--report", getattr(args, "report", None))) if on]
    if getattr(args, "estimator", None) is not None and args.source != "currents":
        raise UserError(f"--estimator applies to --source currents only, not --source "
                        f"{args.source}.")
    if bad:
        raise UserError(f"{bad[0]} applies to --source tensions only; drop it or the --source "
                        f"{args.source} option.")
    ds = read_dataset(args.dataset, require_tensions=False)
    kw = dict(reference=args.reference, model=args.model, params=parse_params(args.params),
              t_start=args.t_start, t_end=args.t_end, trim=args.trim)
    if args.source == "currents" and getattr(args, "estimator", None) is not None:
        kw["estimator"] = args.estimator
    if args.differentiator not in (None, "euler-filtfilt"):
        raise UserError(f"--source {args.source} uses the differentiator euler-filtfilt, not "
                        f"{args.differentiator}.")
    if args.source == "currents" and (args.reference or "").startswith("payload:"):
        from cdprid.identify import identify_currents_payload, parse_payload

        other, kg, std = parse_payload(args.reference)
        kw.pop("reference")
        rep = identify_currents_payload(ds, read_dataset(other, require_tensions=False), kg,
                                        std, **kw)
    elif args.source == "currents":
        from cdprid.base import Progress
        from cdprid.identify import identify_currents

        rep = identify_currents(ds, progress=Progress("identify").say, **kw)
    else:
        from cdprid.identify import identify_free_motion

        rep = identify_free_motion(ds, **kw)
    print(rep.table())
    echo_warnings(rep.warnings)
    if args.json:
        write_json(args.json, rep.as_json(), force=force)
        print(f"wrote {args.json}")
    return 0
