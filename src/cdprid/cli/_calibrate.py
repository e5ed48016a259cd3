"""``cdprid calibrate``: geometric calibration of a locked-winch UACDPR recording.

Estimates the Vicon->base and marker->platform transforms, the cable lengths and the swivel
offsets.
"""

from __future__ import annotations

from cdprid.base import InputError
from cdprid.cli._import import swivel_axis, uacdpr_inputs

__all__ = ["configure", "run"]


def run(args) -> int:
    """Run ``cdprid calibrate`` with parsed arguments (see :func:`configure`)."""
    from cdprid.base import check_distinct, check_output
    from cdprid.identify import calibrate_geometry, calibration_data, write_calibrated_dataset
    from cdprid.io import load_uacdpr
    from cdprid.report import calibration_figures

    inputs = [args.vicon, args.robot_log, args.config, getattr(args, "dataset", None)]
    check_distinct({"--json": args.json, "--out": args.out})
    if args.json:  # before the minute of calibration: an existing file needs --force
        check_output(args.json, force=args.force, flag="--json", inputs=inputs)
    if args.out:
        check_output(args.out, force=args.force, flag="--out", kind="dir", inputs=inputs)
    rec = load_uacdpr(args.vicon, args.robot_log, args.config, swivel_axis=swivel_axis(args))
    data = calibration_data(rec).subsample(args.subsample)
    from cdprid.base import Progress

    prog = Progress("calibrate")
    prog.say(f"geometric calibration on {len(data.t)} Vicon frames (about a minute) ...")
    res = calibrate_geometry(rec.robot, data, anchors=args.anchors,
                             swivel_sign=args.swivel_sign, yaw_starts=args.yaw_starts,
                             progress=prog.say)
    prog.say("calibration done")
    print(f"samples {res.n_samples}, condition {res.condition:.3g}")
    print(f"RMS before: {res.rms_before}")
    print(f"RMS after:  {res.rms_after}")
    print(f"cable lengths, m: {[round(float(v), 4) for v in res.lengths]} "
          f"+- {[round(float(v), 4) for v in res.sigma['length']]}")
    if args.json:
        from cdprid.base import write_json

        write_json(args.json, res.as_dict(), force=args.force)
        print(f"wrote {args.json}")
    if args.out:
        if not args.dataset:
            raise InputError("--out needs --dataset, the folder written by `cdprid import uacdpr`.")
        write_calibrated_dataset(args.dataset, res, args.out, overwrite=args.force)
        print(f"wrote {args.out}")
    if args.figures:
        for p in calibration_figures(rec.robot, data, res, args.figures):
            print(f"wrote {p}")
    return 0


def configure(c) -> None:
    """Give the ``calibrate`` parser its description and options (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)

    c.description = ("Estimate the Vicon->base transform, the marker->platform transform (or "
                     "the attachments), the constant cable lengths and the swivel offsets by "
                     "nonlinear least squares.")
    uacdpr_inputs(c)
    c.add_argument("--anchors", choices=["config", "free"], default="config")
    c.add_argument("--swivel-sign", type=float, default=1.0, choices=[1.0, -1.0])
    c.add_argument("--yaw-starts", type=V.positive_int, default=4)
    c.add_argument("--subsample", type=V.positive_int, default=2, help="use every k-th Vicon frame")
    c.add_argument("--dataset", type=V.existing_dir,
                   help="imported dataset to rewrite in the base frame (--out)")
    c.add_argument("--out", help="write the calibrated dataset here")
    c.add_argument("--force", action="store_true")
    c.add_argument("--json", help="write the estimate as JSON")
    c.add_argument("--figures", help="folder for sanity figures")
    c.set_defaults(func=run)
