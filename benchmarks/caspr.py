"""CASPR's single-link spatial robots through `cdprid import caspr` and `cdprid excite --gentle`.

Usage: python -m benchmarks.caspr [--library PATH]  -> prints a table, writes results/caspr.md.

Each model folder (default: the snapshot of CASPR's library in tests/io/data/caspr, or the
``data/model_config/models`` folder of a CASPR checkout given by ``--library``) is imported with
every cable set (`cdprid.io.read_caspr`, as `cdprid import caspr --cable-set ID` does), then the
gentle first run of `cdprid excite --gentle` is evaluated (`cdprid.excitation.gentle_run`, with
the robot's own limits and the CLI's defaults: orbit family, translation model, cond objective,
home moved to a robust rest point when the workspace centre fails). A row says the number of
cables, the mass, the gentle orbit's condition number of W_ID and whether the run is certified,
or the one-sentence reason the import or the certificate refuses it.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SNAPSHOT = ROOT / "tests" / "io" / "data" / "caspr"


def models(library: Path) -> list[tuple[str, Path, Path]]:
    """(name, bodies, cables) of every single-link SPATIAL model below ``library``."""
    out = []
    for b in sorted(library.rglob("*_bodies.xml")):
        try:
            links = list(ET.parse(b).getroot().find("links"))
        except (ET.ParseError, TypeError):
            continue
        joint = links[0].find("joint") if len(links) == 1 else None
        if joint is None or not joint.get("type", "").startswith("SPATIAL"):
            continue
        c = b.with_name(b.name.replace("_bodies.xml", "_cables.xml"))
        if c.is_file():
            out.append((b.parent.name, b, c))
    return out


def cable_sets(cables: Path) -> list[str]:
    root = ET.parse(cables).getroot()
    default = root.get("default_cable_set")
    ids = [s.get("id") for s in root.findall("cable_set")]
    return [default] + [i for i in ids if i != default]


def one_row(name, bodies, cables, cset) -> dict:
    """Import, then evaluate the gentle run; a dict of the table's columns."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import cdprid.excitation as ex
    from cdprid.base import UserError
    from cdprid.io import read_caspr
    from cdprid.model import robot_from_dict

    row = {"robot": name, "cable set": cset, "cables": "-", "mass kg": "-", "cond": "-"}
    try:
        imp = read_caspr(bodies, cables, cable_set=cset)
        robot = robot_from_dict(imp.robot)
    except UserError as exc:
        row["result"] = "import refused: " + str(exc).split(": ", 1)[-1]
        return row
    row["cables"] = str(robot.n_cables) + (" (pulleys)" if robot.has_pulleys else "")
    row["mass kg"] = f"{imp.robot['platform']['mass']:g}"
    t0 = time.perf_counter()
    try:
        prob = ex.make_problem(robot, "orbit", "cond")
        res = ex.gentle_run(prob, move_home=True)
        row["cond"] = f"{res.initial.cond:.3g}"
        row["result"] = "certified" + (f" ({res.note.split(' Home', 1)[1].strip()})"
                                       if " Home moved" in (res.note or "") else "")
    except UserError as exc:
        row["result"] = "not certified: " + str(exc)
    row["s"] = f"{time.perf_counter() - t0:.1f}"
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--library", type=Path, default=SNAPSHOT,
                    help="folder holding CASPR models (default the test snapshot)")
    ap.add_argument("--out", type=Path, default=ROOT / "results" / "caspr.md")
    args = ap.parse_args(argv)
    rows = []
    for name, b, c in models(args.library):
        for cset in cable_sets(c):
            rows.append(one_row(name, b, c, cset))
            print(" | ".join(str(v) for v in rows[-1].values()), flush=True)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                            capture_output=True, text=True).stdout.strip()
    lib = args.library.relative_to(ROOT) if args.library.is_relative_to(ROOT) else args.library
    cmd = "python -m benchmarks.caspr" + ("" if args.library == SNAPSHOT else f" --library {lib}")
    lines = ["# CASPR's single-link spatial robots", "",
             f"Command: `{cmd}` at commit {commit}; models from `{lib}` (CASPR commit "
             "a6971eeb, BSD 3-Clause; see its README.md).", "",
             "Each cable set is imported by `cdprid import caspr` (P = CASPR's joint frame "
             "origin) and the gentle first run of `cdprid excite --gentle` (orbit family, "
             "translation model, the robot's own force limits and workspace box from CASPR, the "
             "CLI's default limits otherwise) is certified or refused with its reason. cond is "
             "the raw condition number of W_ID over the gentle orbit (the `cond` column of "
             "`cdprid excite`); s is the wall time of the certificate.", "",
             "| robot | cable set | cables | mass kg | cond | certified or why not | s |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['robot']} | {r['cable set']} | {r['cables']} | {r['mass kg']} | "
                     f"{r['cond']} | {r['result']} | {r.get('s', '-')} |")
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
