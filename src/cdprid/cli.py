"""The ``cdprid`` command line.

Every subcommand reads spec-v1 datasets. Bad input gives one sentence on stderr and exit code
2, never a traceback (``CDPRID_DEBUG=1`` shows tracebacks of internal errors).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

__all__ = ["main", "UserError"]


from .errors import UserError  # noqa: E402  (re-exported: cdprid.cli.UserError)


def _enable_x64() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)


def load_json_object(text: str, flag: str, expect: str) -> dict:
    """A JSON object given inline or as a file path; one-sentence UserError otherwise."""
    p = Path(text)
    if not text.lstrip().startswith("{") and p.is_file():
        text = p.read_text()
    try:
        val = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"{flag}: not valid JSON ({exc.msg} at position {exc.pos}).") from None
    if not isinstance(val, dict):
        raise UserError(f"{flag}: must be {expect}.")
    return val


def _parse_params(text: str | None, flag: str = "--params") -> dict:
    if not text:
        return {}
    val = load_json_object(text, flag, "a JSON object such as '{\"cutoff_hz\": 4}'")
    # accept the output of `cdprid tune --json` directly
    if "params" in val and isinstance(val["params"], dict) and "method" in val:
        val = val["params"]
    return val


def write_json(path, data: dict, force: bool = True) -> Path:
    """Write ``data`` as indented JSON atomically (creating the parent folder); returns the path.

    Check the path with :func:`cdprid.outputs.check_output` before the work starts.
    """
    from .outputs import write_json as _write

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    return _write(out, data, force=force)


# ----------------------------------------------------------------------------- identify


def _cmd_identify(args) -> int:
    from .io import read_dataset
    from .pipeline import format_table, identify_dataset

    ds = read_dataset(args.dataset)
    params = _parse_params(args.params)
    if args.online:
        from .online import run_online_cli

        if args.differentiator is None:
            args.differentiator = "sihd2-cascade"
        return run_online_cli(ds, args, params)
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
        weighting=args.weighting,
    )
    print(format_table(rep))
    if args.json:
        write_json(args.json, rep.as_json())
        print(f"wrote {args.json}")
    return 0


def _add_identify(sub) -> None:
    from .pipeline import DEFAULT_TRIM_S

    p = sub.add_parser("identify", help="identify the platform's dynamic parameters (least squares)",
                       description="Identify m, m s_G (and the inertia with --model full) from a "
                       "spec-v1 dataset, and print a table like the paper's Table 1.")
    p.add_argument("dataset", help="dataset folder (spec v1)")
    p.add_argument("--model", choices=["translation", "full"], default="translation",
                   help="4-parameter translation model (paper eq. 10) or 10-parameter model")
    p.add_argument("--differentiator", default=None,
                   help="differentiation method (default euler-filtfilt; sihd2-cascade with "
                   "--online); see `cdprid differentiate --help`")
    p.add_argument("--params", help="differentiator parameters as JSON (or a JSON file)")
    p.add_argument("--t-start", type=float, default=None, help="start of the time window, s")
    p.add_argument("--t-end", type=float, default=None, help="end of the time window, s")
    p.add_argument("--trim", type=float, default=DEFAULT_TRIM_S,
                   help=f"seconds dropped at both ends after differentiation (default {DEFAULT_TRIM_S})")
    p.add_argument("--weighting", choices=["none", "groups"], default="none",
                   help="'groups': weighted LS with separate force/moment row weights")
    p.add_argument("--online", action="store_true",
                   help="online identification: causal SIHD-2 cascade + recursive least squares, "
                   "per-sample parameter trajectory (CSV and PNG)")
    p.add_argument("--forgetting", type=float, default=1.0,
                   help="forgetting factor lambda in (0, 1] for --online (memory dt/(1-lambda))")
    p.add_argument("--out-csv", dest="out_csv", default=None,
                   help="parameter trajectory CSV for --online (a PNG is written beside it)")
    p.add_argument("--wrench-filter", dest="wrench_filter", choices=["matched", "delay", "none"],
                   default="matched", help="--online: filter W tau like the accelerations")
    p.add_argument("--json", help="write the result as JSON to this file")
    p.set_defaults(func=_cmd_identify)


# ----------------------------------------------------------------------------- main


_OPTIONAL_COMMANDS = (
    # (module, function adding the subparser): commands of later issues register here
    ("cdprid.cli_differentiate", "add_parser"),
    ("cdprid.cli_simulate", "add_parser"),
    ("cdprid.cli_diagnose", "add_parser"),
    ("cdprid.cli_excite", "add_parser"),
    ("cdprid.cli_import", "add_parser"),
    ("cdprid.cli_example", "add_parser"),
    ("cdprid.cli_tune", "add_parser"),
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``cdprid`` command."""
    import importlib

    parser = argparse.ArgumentParser(
        prog="cdprid",
        description="Dynamic identification of cable-driven parallel robots.",
    )
    from . import __version__

    parser.add_argument("--version", action="version", version=f"cdprid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    _add_identify(sub)
    for mod, fn in _OPTIONAL_COMMANDS:
        try:
            module = importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name == mod:
                continue
            raise
        getattr(module, fn)(sub)
    return parser


def main(argv=None) -> int:
    """Entry point of the ``cdprid`` console script; returns the exit code."""
    from .geometry import RobotFileError
    from .io import DatasetError

    parser = build_parser()
    args = parser.parse_args(argv)
    _enable_x64()
    try:
        return int(args.func(args) or 0)
    except (UserError, DatasetError, RobotFileError, FileExistsError, ValueError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"cdprid: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("cdprid: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001
        if os.environ.get("CDPRID_DEBUG"):
            raise
        print(f"cdprid: internal error: {type(exc).__name__}: {exc} "
              "(set CDPRID_DEBUG=1 for a traceback and please report it)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
