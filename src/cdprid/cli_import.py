"""``cdprid import`` (convert other formats into spec-v1) and ``cdprid calibrate``.

Registered by :mod:`cdprid.cli` through ``("cdprid.cli_import", "add_parser")``.
"""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["add_parser"]


def _cmd_import_uacdpr(args) -> int:
    import sys

    from .io.uacdpr import import_uacdpr

    out = import_uacdpr(args.vicon, args.robot_log, args.config, args.out,
                        overwrite=args.force, swivel_axis=args.swivel_axis,
                        calibrate=not args.no_calibrate, subsample=args.subsample,
                        dynamics=not args.no_nuisance,
                        progress=lambda msg: print(msg, file=sys.stderr))
    import tomllib

    with open(out / "meta.toml", "rb") as fh:
        meta = tomllib.load(fh)
    fit = meta["marker_fit"]
    print(f"wrote {out} (marker fit RMS {fit['rms_mm']:.3f} mm, max {fit['max_mm']:.2f} mm)")
    if "calibration" in meta:
        c = meta["calibration"]["rms_after"]
        print(f"pose in the robot base frame (calibration RMS: lengths "
              f"{1e3 * c['length_m']:.3f} mm, swivel {1e3 * c.get('swivel_rad', 0.0):.2f} mrad)")
    else:
        print("pose of the marker frame in the Vicon frame (--no-calibrate)")
    nu = meta.get("nuisance", {})
    if "delay_s" in nu:
        print(f"nuisances (informational, tensions not corrected): delay "
              f"{1e3 * nu['delay_s']:.1f} +- {1e3 * nu['delay_std_s']:.1f} ms, offsets "
              f"{[round(v, 2) for v in nu['offset_N']]} N")
    return 0


def _cmd_calibrate(args) -> int:
    from .calibration import calibrate_geometry, calibration_figures, write_calibrated_dataset
    from .io.uacdpr import load_uacdpr

    rec = load_uacdpr(args.vicon, args.robot_log, args.config, swivel_axis=args.swivel_axis)
    data = rec.calibration_data().subsample(args.subsample)
    res = calibrate_geometry(rec.robot, data, anchors=args.anchors,
                             swivel_sign=args.swivel_sign, yaw_starts=args.yaw_starts)
    print(f"samples {res.n_samples}, condition {res.condition:.3g}")
    print(f"RMS before: {res.rms_before}")
    print(f"RMS after:  {res.rms_after}")
    print(f"cable lengths, m: {[round(float(v), 4) for v in res.lengths]} "
          f"+- {[round(float(v), 4) for v in res.sigma['length']]}")
    if args.json:
        Path(args.json).write_text(json.dumps(res.as_dict(), indent=2) + "\n")
        print(f"wrote {args.json}")
    if args.out:
        if not args.dataset:
            raise ValueError("--out needs --dataset, the folder written by `cdprid import uacdpr`.")
        write_calibrated_dataset(args.dataset, res, args.out, overwrite=args.force)
        print(f"wrote {args.out}")
    if args.figures:
        for p in calibration_figures(rec.robot, data, res, args.figures):
            print(f"wrote {p}")
    return 0


def _inputs(p) -> None:
    p.add_argument("--vicon", required=True, help="raw Vicon trajectories export (.txt/.csv)")
    p.add_argument("--robot-log", required=True, help="robot log _exp.mat (struct st_out)")
    p.add_argument("--config", required=True, help="robot configuration .mat (struct s)")
    p.add_argument("--swivel-axis", choices=["first", "third"], default=None,
                   help="which FixedFrame vector is the swivel axis (default: the importer's)")


def add_parser(sub) -> None:
    """Add ``import`` (with the ``uacdpr`` format) and ``calibrate`` to the subparsers."""
    from .io.uacdpr import DEFAULT_SWIVEL_AXIS

    p = sub.add_parser("import", help="convert another format into a spec-v1 dataset",
                       description="Convert recordings of other labs into spec-v1 datasets.")
    fmt = p.add_subparsers(dest="format", metavar="FORMAT")
    fmt.required = True
    u = fmt.add_parser("uacdpr", help="UACDPR (Bologna): Vicon export + robot _exp.mat + config",
                       description="Pose by a rigid-body fit of the raw Vicon markers, then "
                       "the geometric calibration: platform frame in the robot base frame "
                       "(--no-calibrate: marker frame in the Vicon frame); tensions at 1 kHz, swivel and inclinometer "
                       "streams, robot.toml from the configuration .mat.")
    _inputs(u)
    u.add_argument("--out", required=True, help="dataset folder to create")
    u.add_argument("--force", action="store_true", help="overwrite an existing dataset")
    u.add_argument("--no-calibrate", action="store_true",
                   help="keep the raw frames (marker frame in the Vicon frame); by default the "
                   "geometric calibration runs and the pose is the platform's in the base frame")
    u.add_argument("--subsample", type=int, default=4,
                   help="calibration uses every k-th Vicon frame (default 4)")
    u.add_argument("--no-nuisance", action="store_true",
                   help="skip the informational dynamic nuisance estimate (offsets, delay) "
                   "written to meta.toml [nuisance]")
    u.set_defaults(func=_cmd_import_uacdpr, swivel_axis=DEFAULT_SWIVEL_AXIS)

    c = sub.add_parser("calibrate", help="geometric calibration of a locked-winch recording",
                       description="Estimate the Vicon->base transform, the marker->platform "
                       "transform (or the attachments), the constant cable lengths and the "
                       "swivel offsets by nonlinear least squares.")
    _inputs(c)
    c.add_argument("--anchors", choices=["config", "free"], default="config")
    c.add_argument("--swivel-sign", type=float, default=1.0, choices=[1.0, -1.0])
    c.add_argument("--yaw-starts", type=int, default=4)
    c.add_argument("--subsample", type=int, default=2, help="use every k-th Vicon frame")
    c.add_argument("--dataset", help="imported dataset to rewrite in the base frame (--out)")
    c.add_argument("--out", help="write the calibrated dataset here")
    c.add_argument("--force", action="store_true")
    c.add_argument("--json", help="write the estimate as JSON")
    c.add_argument("--figures", help="folder for sanity figures")
    c.set_defaults(func=_cmd_calibrate, swivel_axis=DEFAULT_SWIVEL_AXIS)
