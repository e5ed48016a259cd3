"""``cdprid import FORMAT``: convert another format into a spec-v1 dataset.

Formats: UACDPR recordings, pose and tension tables, ROS bags, C3D, CASPR robot models
(:mod:`cdprid.cli._import_caspr`).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["configure", "swivel_axis", "uacdpr_inputs"]


def _cmd_import_uacdpr(args) -> int:
    """Convert -> calibrate -> nuisance fit; progress on stderr, the dataset written at once."""
    import sys

    import tomllib

    from cdprid.identify import import_calibrated_uacdpr
    from cdprid.io import import_uacdpr

    def say(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    if args.no_calibrate:
        out = import_uacdpr(args.vicon, args.robot_log, args.config, args.out,
                            overwrite=args.force, swivel_axis=swivel_axis(args))
    else:
        out = import_calibrated_uacdpr(args.vicon, args.robot_log, args.config, args.out,
                                       force=args.force, swivel_axis=swivel_axis(args),
                                       subsample=args.subsample, nuisance=not args.no_nuisance,
                                       progress=say)
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
    elif "error" in nu:
        print(f"nuisance fit failed: {nu['error']}")
    return 0


# ----------------------------------------------------------- table, rosbag, c3d (issue 18)


def _names(text: str | None) -> list[str] | None:
    return None if text is None else [n.strip() for n in text.split(",") if n.strip()]


def _report_import(out: Path) -> int:
    import tomllib

    with open(out / "meta.toml", "rb") as fh:
        imp = tomllib.load(fh).get("import", {})
    print(f"wrote {out} (SI units; what the importer assumed is in {out / 'meta.toml'} [import])")
    for note in imp.get("notes", []):
        print(f"note: {note}")
    if imp.get("pose_rows_dropped") or imp.get("tension_rows_dropped"):
        print(f"dropped rows with empty/non-numeric fields: pose {imp['pose_rows_dropped']}, "
              f"tensions {imp['tension_rows_dropped']} (not interpolated)")
    if "frames_without_pose" in imp:
        print(f"marker fit RMS {imp['fit_rms_mm']:.3f} mm; {imp['frames_without_pose']} of "
              f"{imp['frames']} frames without a pose (fewer than {imp['min_markers']} markers) "
              f"in {len(imp['gaps'])} gap(s), dropped and not bridged")
        print(f"pose: {imp['pose_frame']}")
    return 0


def _cmd_import_table(args) -> int:
    from cdprid.io import import_table

    out = import_table(args.pose, args.tensions, args.robot, args.out,
                       pose_columns=args.pose_columns, tension_columns=args.tension_columns,
                       euler=args.euler, pose_units=args.pose_units,
                       tension_units=args.tension_units,
                       tension_time_offset=args.tension_time_offset, force=args.force)
    return _report_import(out)


def _cmd_import_rosbag(args) -> int:
    from cdprid.base import UserError
    from cdprid.io import import_rosbag, list_topics

    if args.list:
        for topic, typ, count in list_topics(args.bag):
            print(f"{topic}\t{typ}\t{count}")
        return 0
    missing = [o for o, v in (("--robot", args.robot), ("--pose-topic", args.pose_topic),
                              ("--tension-topic", args.tension_topic), ("--out", args.out))
               if not v]
    if missing:
        raise UserError(f"{missing[0]}: is required to import a bag (only --list works without).")
    frames = _names(args.frames)
    if frames is not None and len(frames) != 2:
        raise UserError(f"--frames: {args.frames!r} should be two frame names, parent,child.")
    out = import_rosbag(args.bag, args.robot, args.out, args.pose_topic, args.tension_topic,
                        frames=tuple(frames) if frames else None, joints=_names(args.joints),
                        wrench_component=args.wrench_component, force=args.force)
    return _report_import(out)


def _cmd_import_c3d(args) -> int:
    from cdprid.io import import_c3d

    out = import_c3d(args.c3d, args.robot, args.out, markers=_names(args.markers),
                     analog_tensions=_names(args.analog_tensions), layout=args.layout,
                     layout_units=args.layout_units, origin_marker=args.origin_marker,
                     min_markers=args.min_markers, analog_units=args.analog_units,
                     tensions=args.tensions, tension_columns=args.tension_columns,
                     tension_units=args.tension_units,
                     tension_time_offset=args.tension_time_offset, force=args.force)
    return _report_import(out)


def _tension_table_options(p, required: bool) -> None:
    p.add_argument("--tensions", required=required,
                   help="tension table (CSV/TSV; delimiter auto-detected)")
    p.add_argument("--tension-columns", dest="tension_columns",
                   help="t=COL,tau_1=COL,...,tau_m=COL in robot.toml's cable order "
                   "(default t,tau_1..tau_m)")
    p.add_argument("--tension-units", dest="tension_units",
                   help="e.g. time=ms,force=kN (default time=s,force=N)")
    p.add_argument("--tension-time-offset", dest="tension_time_offset", type=float, default=0.0,
                   help="seconds added to the tension clock to put it on the pose clock")


def _add_generic_formats(fmt) -> None:
    """``import table``, ``import rosbag`` and ``import c3d``."""
    t = fmt.add_parser("table", help="pose and tension CSV/TSV tables from any logger",
                       description="Pose and tension tables (comma, tab, semicolon or "
                       "whitespace delimited; BOM and quoted headers handled) -> spec-v1 "
                       "dataset in SI units; every assumption is written to meta.toml.")
    t.add_argument("--pose", required=True, help="pose table (CSV/TSV)")
    t.add_argument("--pose-columns", dest="pose_columns",
                   help="t=COL,x=COL,y=COL,z=COL plus qw=,qx=,qy=,qz= or e1=,e2=,e3= "
                   "(default the spec names t,x,y,z[,qw,qx,qy,qz])")
    t.add_argument("--euler", help="Euler sequence of e1,e2,e3 as scipy Rotation.from_euler: "
                   "upper case intrinsic (ZYX), lower case extrinsic (xyz)")
    t.add_argument("--pose-units", dest="pose_units",
                   help="e.g. time=ms,length=mm,angle=deg (default s, m, rad)")
    _tension_table_options(t, required=True)
    t.add_argument("--robot", required=True, help="robot.toml of the robot")
    t.add_argument("--out", required=True, help="dataset folder to create")
    t.add_argument("--force", action="store_true", help="replace an existing --out")
    t.set_defaults(func=_cmd_import_table)

    r = fmt.add_parser("rosbag", help="ROS 1 .bag or ROS 2 bag (SQLite or MCAP)",
                       description="Pose and tension topics of a ROS 1 or ROS 2 bag -> spec-v1 "
                       "dataset. Times are header stamps (receipt times only for messages "
                       "without a header, stated in meta.toml).")
    r.add_argument("bag", help="ROS 1 .bag file or ROS 2 bag folder")
    r.add_argument("--list", action="store_true", help="print the topics and types, and exit")
    r.add_argument("--robot", help="robot.toml of the robot")
    r.add_argument("--pose-topic", dest="pose_topic",
                   help="PoseStamped, PoseWithCovarianceStamped, Odometry, TransformStamped "
                   "or tf2_msgs/TFMessage topic")
    r.add_argument("--frames", help="parent,child frame pair of a TransformStamped/TFMessage "
                   "topic (parent = robot base, child = platform)")
    r.add_argument("--tension-topic", dest="tension_topic", action="append",
                   help="JointState (effort) or Float64MultiArray topic with one value per "
                   "cable; or repeat once per cable (Float64 or WrenchStamped) in robot.toml order")
    r.add_argument("--joints", help="JointState names in robot.toml's cable order")
    r.add_argument("--wrench-component", dest="wrench_component", default="norm",
                   choices=["norm", "x", "y", "z"],
                   help="what a WrenchStamped tension topic gives (default the force's norm)")
    r.add_argument("--out", help="dataset folder to create")
    r.add_argument("--force", action="store_true", help="replace an existing --out")
    r.set_defaults(func=_cmd_import_rosbag)

    c = fmt.add_parser("c3d", help="C3D motion capture (Vicon, Qualisys, OptiTrack)",
                       description="Platform markers of a C3D file -> pose by a rigid-body "
                       "(Kabsch) fit; tensions from analog channels or a table. Marker gaps "
                       "are dropped and reported, never bridged.")
    c.add_argument("c3d", help="C3D file")
    c.add_argument("--robot", required=True, help="robot.toml of the robot")
    c.add_argument("--out", required=True, help="dataset folder to create")
    c.add_argument("--markers", help="platform marker names, comma-separated (default all)")
    c.add_argument("--layout", help="CSV name,x,y,z: markers in the platform frame (default: "
                   "estimated from the data, giving a marker frame)")
    c.add_argument("--layout-units", dest="layout_units", default="m",
                   help="length unit of --layout (default m)")
    c.add_argument("--origin-marker", dest="origin_marker",
                   help="marker at the marker-frame origin when the layout is estimated")
    c.add_argument("--min-markers", dest="min_markers", type=int, default=3,
                   help="frames with fewer seen markers get no pose (default 3)")
    c.add_argument("--analog-tensions", dest="analog_tensions",
                   help="analog channels holding the tensions, in robot.toml's cable order")
    c.add_argument("--analog-units", dest="analog_units",
                   help="force unit of those channels when ANALOG:UNITS gives none (e.g. N)")
    _tension_table_options(c, required=False)
    c.add_argument("--force", action="store_true", help="replace an existing --out")
    c.set_defaults(func=_cmd_import_c3d)


def uacdpr_inputs(p) -> None:
    """The UACDPR recording's options (``import uacdpr`` and ``calibrate``)."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)

    p.add_argument("--vicon", required=True, type=V.existing_file,
                   help="raw Vicon trajectories export (.txt/.csv)")
    p.add_argument("--robot-log", required=True, type=V.existing_file,
                   help="robot log _exp.mat (struct st_out)")
    p.add_argument("--config", required=True, type=V.existing_file,
                   help="robot configuration .mat (struct s)")
    p.add_argument("--swivel-axis", choices=["first", "third"], default=None,
                   help="which FixedFrame vector is the swivel axis (default: the importer's)")


def swivel_axis(args) -> str:
    """``--swivel-axis``, or the importer's default (read only when a command runs, so that the
    parser imports no JAX)."""
    from cdprid.io import DEFAULT_SWIVEL_AXIS

    return args.swivel_axis or DEFAULT_SWIVEL_AXIS


def configure(p) -> None:
    """Give the ``import`` parser its description and formats (the command registry,
    :mod:`cdprid.cli._commands`, creates it)."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)

    p.description = "Convert recordings of other labs into spec-v1 datasets."
    fmt = p.add_subparsers(dest="format", metavar="FORMAT")
    fmt.required = True
    u = fmt.add_parser("uacdpr", help="UACDPR (Bologna): Vicon export + robot _exp.mat + config",
                       description="Pose by a rigid-body fit of the raw Vicon markers, then "
                       "the geometric calibration: platform frame in the robot base frame "
                       "(--no-calibrate: marker frame in the Vicon frame), then the nuisance fit "
                       "(meta.toml [nuisance]); tensions at 1 kHz, swivel and inclinometer "
                       "streams, robot.toml from the configuration .mat. Progress on stderr; "
                       "the folder appears whole or not at all.")
    uacdpr_inputs(u)
    u.add_argument("--out", required=True, help="dataset folder to create")
    u.add_argument("--force", action="store_true", help="overwrite an existing dataset")
    u.add_argument("--no-calibrate", action="store_true",
                   help="keep the raw frames (marker frame in the Vicon frame); by default the "
                   "geometric calibration runs and the pose is the platform's in the base frame")
    u.add_argument("--subsample", type=V.positive_int, default=4,
                   help="calibration uses every k-th Vicon frame (default 4)")
    u.add_argument("--no-nuisance", action="store_true",
                   help="skip the informational dynamic nuisance estimate (offsets, delay) "
                   "written to meta.toml [nuisance]")
    u.set_defaults(func=_cmd_import_uacdpr)
    _add_generic_formats(fmt)
    from cdprid.cli._import_caspr import add_format

    add_format(fmt)
