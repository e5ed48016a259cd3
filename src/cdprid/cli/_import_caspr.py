"""``cdprid import caspr``: a CASPR robot model (bodies + cables XML) -> robot.toml.

Registered by :func:`cdprid.cli._import.configure` (one line there).
"""

from __future__ import annotations

__all__ = ["add_format"]


def _cmd_import_caspr(args) -> int:
    from cdprid.base import check_distinct, check_output, write_text
    from cdprid.io import read_caspr, robot_toml
    from cdprid.model import robot_from_dict

    check_distinct({"--out": args.out})
    check_output(args.out, force=args.force, flag="--out", inputs=[args.bodies, args.cables])
    imp = read_caspr(args.bodies, args.cables, cable_set=args.cable_set)
    robot = robot_from_dict(imp.robot, source=f"{args.cables} (mapped)")  # reads back whole
    for note in imp.notes:
        print(f"note: {note}")
    plat = imp.robot["platform"]
    pulleys = int((robot.pulley_radius > 0).sum())
    print(f"{robot.name}: {robot.n_cables} cables ({pulleys} over swivel pulleys), mass "
          f"{plat['mass']:g} kg, P = the joint frame's origin")
    header = (f"# imported by `cdprid import caspr {args.bodies} {args.cables}"
              + (f" --cable-set {args.cable_set}" if args.cable_set else "")
              + f"` (CASPR cable set {imp.cable_set!r})\n")
    write_text(args.out, header + robot_toml(imp.robot), force=args.force)
    print(f"wrote {args.out}")
    return 0


def add_format(fmt) -> None:
    """Add the ``caspr`` format to the ``cdprid import`` subparsers ``fmt``."""
    from cdprid.cli import _types as V  # option validators (cdprid.cli._types)

    p = fmt.add_parser("caspr", help="CASPR robot model (bodies + cables XML) -> robot.toml",
                       description="A single-link spatial CASPR model -> robot.toml (spec "
                       "1.1): exits, attachments (P = CASPR's joint frame origin), "
                       "base_rotating_pulley as swivel pulleys, force limits, workspace box, "
                       "mass, centre of mass, inertia. Several links, elastic cables or "
                       "screw-drive pulleys are refused (exit 2).")
    p.add_argument("bodies", type=V.existing_file, help="CASPR *_bodies.xml")
    p.add_argument("cables", type=V.existing_file, help="CASPR *_cables.xml")
    p.add_argument("--cable-set", dest="cable_set", default=None,
                   help="cable_set id (default the file's default_cable_set)")
    p.add_argument("--out", required=True, help="robot.toml to write")
    p.add_argument("--force", action="store_true", help="replace an existing --out")
    p.set_defaults(func=_cmd_import_caspr)
