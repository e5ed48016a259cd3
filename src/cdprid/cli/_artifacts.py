"""``--mat`` and ``--report`` outputs shared by ``identify`` and ``diagnose`` (issue 39).

Kept out of the command modules so that each changes by a few lines.
"""

from __future__ import annotations

import shlex
from pathlib import Path

__all__ = ["add_identify_options", "check_outputs", "made_by", "write_diagnosis_outputs",
           "write_identify_outputs"]


def made_by(args) -> dict:
    """``{"command": "cdprid ...", "version": ...}`` of the running command."""
    from cdprid import __version__

    argv = getattr(args, "_argv", None)
    return {"command": "cdprid " + shlex.join(argv) if argv else "cdprid", "version": __version__}


def add_identify_options(p) -> None:
    """``identify --mat`` and ``identify --report``."""
    p.add_argument("--mat", help="write the result as a MATLAB .mat file (estimates, std, "
                   "covariance, Cramer-Rao bound, residuals with time; docs/formats.md)")
    p.add_argument("--report", help="write report.md, its figures and a self-contained "
                   "report.html into this folder")


def check_outputs(args, inputs, force: bool) -> None:
    """Refuse before the work starts: ``--mat`` existing without ``--force``, a ``--report``
    folder that may not be replaced, outputs on one path, either with ``identify --online``."""
    from cdprid.base import UserError, check_distinct, check_output

    check_distinct({"--json": getattr(args, "json", None), "--mat": getattr(args, "mat", None),
                    "--report": getattr(args, "report", None)})
    if getattr(args, "online", False) and (args.mat or args.report):
        raise UserError(f"{'--mat' if args.mat else '--report'} applies to batch identify "
                        "only; --online writes its parameter trajectory with --out-csv.")

    if getattr(args, "mat", None):
        if Path(args.mat).suffix.lower() != ".mat":
            raise UserError(f"--mat {args.mat}: the file name must end in .mat.")
        check_output(args.mat, force=force, flag="--mat", inputs=inputs)
    if getattr(args, "report", None):
        check_output(args.report, force=force, flag="--report", kind="dir", inputs=inputs)


def write_identify_outputs(args, rep, data: dict, dataset_name: str) -> None:
    """Write ``--mat`` and ``--report`` (report.md, report.html) of ``identify``."""
    from cdprid.base import atomic_dir
    from cdprid.io import write_mat
    from cdprid.report import identify_variables, save_identify_report

    who = made_by(args)
    if getattr(args, "mat", None):
        write_mat(args.mat, identify_variables(rep, data, who), force=args.force)
        print(f"wrote {args.mat}")
    if getattr(args, "report", None):
        with atomic_dir(args.report, force=args.force) as tmp:
            save_identify_report(rep, data, tmp, dataset_name=dataset_name, made_by=who)
        print(f"wrote {args.report}/report.md and {args.report}/report.html")


def write_diagnosis_outputs(args, res, data: dict) -> None:
    """Write ``--mat`` of ``diagnose`` (its ``--report`` is written by the command)."""
    from cdprid.io import write_mat
    from cdprid.report import diagnosis_variables

    if getattr(args, "mat", None):
        write_mat(args.mat, diagnosis_variables(res, data, made_by(args)), force=args.force)
        print(f"wrote {args.mat}")
