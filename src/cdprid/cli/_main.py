"""The ``cdprid`` command line.

Every subcommand reads spec-v1 datasets. Bad input gives one sentence on stderr and exit code
2, never a traceback (``CDPRID_DEBUG=1`` shows tracebacks of internal errors). Building the
parser imports no JAX, SciPy or Matplotlib (``cdprid --help`` stays fast); options are
validated at parse time by :mod:`cdprid.cli._types`.

Environment variables (checked before any work; a bad value is one sentence and exit 2):

* ``CDPRID_DEBUG`` -- any non-empty value: tracebacks of internal errors.
* ``CDPRID_CACHE_DIR`` -- folder of the persistent JAX compilation cache (default
  ``$XDG_CACHE_HOME/cdprid/jax`` or ``~/.cache/cdprid/jax``); ``off`` disables it.
* ``CDPRID_SCAN_UNROLL`` -- integer >= 1, unroll factor of the SIHD scans.
* ``OPENBLAS_NUM_THREADS`` -- NumPy's BLAS threads; the ``cdprid`` executable sets 1 unless
  given (see :func:`console_main`).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import sys
from pathlib import Path

__all__ = ["main", "console_main", "UserError", "build_parser", "load_json_object", "parse_params",
           "write_json"]


from cdprid.base import OutputError, UserError, check_pending, pending
from cdprid.cli import _artifacts  # noqa: E402  (--mat, --report of identify)
from cdprid.cli._exits import _failed, _interrupted, _is_user_error  # noqa: E402,F401
from cdprid.cli._signals import install_termination_handlers, restore_handlers  # noqa: E402
from cdprid.cli._sources import add_source_options, run_source  # noqa: E402


def _check_environment() -> None:
    """Validate the environment variables the library reads (one sentence, exit 2)."""
    unroll = os.environ.get("CDPRID_SCAN_UNROLL")
    if unroll is not None:
        try:
            ok = int(unroll.strip()) >= 1
        except ValueError:
            ok = False
        if not ok:
            raise UserError(f"environment variable CDPRID_SCAN_UNROLL={unroll!r} must be an "
                            "integer of at least 1 (unset it for the default 1).")
    cache = os.environ.get("CDPRID_CACHE_DIR")
    if cache is not None and cache.strip().lower() not in ("off", "0", "none", ""):
        p = Path(cache).expanduser()
        if p.exists() and not p.is_dir():
            raise UserError(f"environment variable CDPRID_CACHE_DIR={cache!r} names a file, "
                            "not a folder (use a folder, or 'off' to disable the cache).")


def jax_cache_dir() -> Path | None:
    """The folder of the persistent JAX compilation cache, or None when disabled.

    ``CDPRID_CACHE_DIR`` overrides the default ``$XDG_CACHE_HOME/cdprid/jax`` (or
    ``~/.cache/cdprid/jax``); ``CDPRID_CACHE_DIR=off`` disables the cache.
    """
    env = os.environ.get("CDPRID_CACHE_DIR")
    if env is not None:
        if env.strip().lower() in ("off", "0", "none", ""):
            return None
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "cdprid" / "jax"


def _enable_x64() -> None:
    import jax

    jax.config.update("jax_enable_x64", True)
    cache = jax_cache_dir()
    if cache is None:
        return
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:
        return  # an unwritable cache only costs compile time; never fail a command for it
    if not os.access(cache, os.W_OK | os.X_OK):
        return
    jax.config.update("jax_compilation_cache_dir", str(cache))
    # every compiled kernel is kept: loading one costs ~10 ms, compiling the small ones ~40 ms
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def load_json_object(text: str, flag: str, expect: str) -> dict:
    """A JSON object given inline or as a file path; one-sentence UserError otherwise.

    Parameters
    ----------
    text : str
        Inline JSON (starting with ``{``) or the path of a JSON file.
    flag : str
        The option name, used in messages.
    expect : str
        What the object should be, e.g. ``"a JSON object such as '{\"cutoff_hz\": 4}'"``.

    Returns
    -------
    dict

    Raises
    ------
    UserError
        The file does not exist or cannot be read, the text is not JSON, or not an object.
    """
    src = "the value"
    if not text.lstrip().startswith(("{", "[")):
        p = Path(text)
        if not p.exists():
            raise UserError(f"{flag} {text}: the file does not exist (give a JSON file or an "
                            "inline JSON object).")
        if p.is_dir():
            raise UserError(f"{flag} {text}: is a folder, expected a JSON file.")
        try:
            text = p.read_text(encoding="utf-8-sig")
        except UnicodeDecodeError:
            raise UserError(f"{flag} {p}: not UTF-8 text.") from None
        except OSError as exc:
            raise UserError(f"{flag} {p}: cannot be read ({exc.strerror}).") from None
        src = str(p)
    try:
        val = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"{flag}: {src} is not valid JSON ({exc.msg} at line {exc.lineno}, "
                        f"column {exc.colno}).") from None
    if not isinstance(val, dict):
        raise UserError(f"{flag}: must be {expect}.")
    return val


def parse_params(text: str | None, flag: str = "--params") -> dict:
    if not text:
        return {}
    val = load_json_object(text, flag, "a JSON object such as '{\"cutoff_hz\": 4}'")
    # accept the output of `cdprid tune --json` directly
    if "params" in val and isinstance(val["params"], dict) and "method" in val:
        val = val["params"]
    return val


def write_json(path, data: dict, force: bool = True) -> Path:
    """Write ``data`` as indented JSON atomically (creating the parent folder); returns the path.

    Check the path with :func:`cdprid.base.check_output` before the work starts.
    """
    from cdprid.base import write_json as _write

    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{out}: cannot create its folder ({exc.strerror}).") from None
    return _write(out, data, force=force)


# ----------------------------------------------------------------------------- identify


def _cmd_identify(args) -> int:
    from cdprid.base import check_distinct, check_output
    from cdprid.identify import format_table, identify_dataset
    from cdprid.io import dataset_inputs, read_dataset

    if getattr(args, "source", "tensions") != "tensions":  # issue 41: no load cells
        return run_source(args, parse_params, write_json)
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
    from cdprid.core import check_geometry

    ds = read_dataset(args.dataset)
    check_geometry(ds.robot, ds.pose_t, ds.position, ds.quaternion)
    params = parse_params(args.params)
    if args.online:
        from cdprid.cli._online import run_online_cli

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
        weighting=args.weighting or "eiv",
        covariance=args.std,
        wrench_filter=args.wrench_filter or "matched",
        inertia_about=args.inertia_about, keep_episodes=args.keep_episodes)
    if getattr(args, "physical", False):
        from cdprid.identify import physical_report

        rep = physical_report(rep)
    rep = _with_guards(ds, rep)
    print(format_table(rep))
    from cdprid.cli._echo import echo_warnings

    echo_warnings(rep.warnings)
    if args.json:
        write_json(args.json, rep.as_json(), force=force)
        print(f"wrote {args.json}")
    _artifacts.write_identify_outputs(args, rep, rep.as_json(), str(args.dataset))
    return 0


def _with_guards(ds, rep):
    """The report with the plausibility guards' sentences added to its warnings (issue 25)."""
    import dataclasses

    import numpy as np

    from cdprid.core import input_warnings, result_warnings
    from cdprid.identify import swapped_columns_warning

    names, x, _, _ = rep.estimates()
    if not np.all(np.isfinite(np.asarray(x, float))):
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


def _add_identify(sub) -> None:
    from cdprid.base import TRIM_S

    p = sub.add_parser("identify",
                       help="identify the platform's dynamic parameters (least squares)",
                       description="Identify m, m s_G (and the inertia with the full model) from a "
                       "spec-v1 dataset, and print a table like the paper's Table 1. The std is "
                       "HAC (autocorrelation-consistent) by default; eq. 20's value is in the "
                       "JSON as std_iid. Warnings (model mismatch, lag, physics, excitation) go "
                       "to stderr, the table and the JSON 'warnings' list.")
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
    p.set_defaults(func=_cmd_identify)


# ----------------------------------------------------------------------------- main


_OPTIONAL_COMMANDS = (
    # (module, function adding the subparser): commands of later issues register here
    ("cdprid.cli._differentiate", "add_parser"),
    ("cdprid.cli._simulate", "add_parser"),
    ("cdprid.cli._diagnose", "add_parser"),
    ("cdprid.cli._excite", "add_parser"),
    ("cdprid.cli._import", "add_parser"),
    ("cdprid.cli._example", "add_parser"),
    ("cdprid.cli._tune", "add_parser"),
)


def _option_rules() -> dict:
    """Validators applied by :func:`build_parser` to options still typed as bare float/int."""
    from cdprid.cli import _types as V

    return {
        "t_start": V.finite_float, "t_end": V.finite_float, "train_until": V.finite_float,
        "trim": V.nonneg_float, "forgetting": V.unit_interval_open_closed,
        "alpha": V.probability, "weight": V.float_in(0.0, 1.0),
        "n_null": V.positive_int, "max_effects": V.positive_int, "yaw_starts": V.positive_int,
        "subsample": V.positive_int, "starts": V.positive_int, "seeds": V.positive_int,
        "max_steps": V.positive_int, "seed": V.nonneg_int,
        "noise_pos": V.nonneg_float, "noise_tension": V.nonneg_float,
        "noise_rot": V.nonneg_float, "noise_std": V.positive_float, "zeta_min": V.nonneg_float,
        "rate_pose": V.float_in(1.0, 1e5), "rate_tension": V.float_in(1.0, 1e5),
        "duration": V.positive_float, "params": V.json_or_file, "initial": V.json_or_file,
    }


def _harden(parser: argparse.ArgumentParser, rules: dict) -> None:
    """Give every option a parse-time validator (a safety net under the commands' own types).

    Options typed ``float`` become finite (no nan/inf); options named in ``rules`` get that
    range check when they still have a bare ``float``/``int``/no type. Validators a command set
    itself are kept.
    """
    from cdprid.cli import _types as V

    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sp in action.choices.values():
                _harden(sp, rules)
            continue
        rule = rules.get(action.dest)
        bare = action.type in (None, float, int)
        if rule is not None and bare and action.nargs in (None, "?") and not action.choices \
                and not (action.type is None and action.dest not in ("params", "initial")):
            action.type = rule
        elif action.type is float:
            action.type = V.finite_float


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line: ``cdprid: error: CMD: argument ...``."""

    def error(self, message: str):
        cmd = self.prog.split(" ", 1)[1] + ": " if " " in self.prog else ""
        self.exit(2, f"cdprid: error: {cmd}{message.rstrip('.')}. See `{self.prog} --help`.\n")


# Commands listed by `cdprid --help` without importing their modules (which load JAX, SciPy):
# name -> (module registering it, or None for identify here; its one-line help). The help
# strings must equal those the modules register (tests/cli/test_robustness.py checks it).
COMMANDS: dict[str, tuple[str | None, str]] = {
    "identify": (None, "identify the platform's dynamic parameters (least squares)"),
    "differentiate": ("cdprid.cli._differentiate",
                      "estimate first and second derivatives of CSV columns"),
    "simulate": ("cdprid.cli._simulate",
                 "write a synthetic dataset (spec v1) with optional injected effects"),
    "diagnose": ("cdprid.cli._diagnose",
                 "find what the paper's model misses, name the cause, measure the gain"),
    "excite": ("cdprid.cli._excite",
               "optimise a safe excitation trajectory (condition number of W_ID)"),
    "import": ("cdprid.cli._import", "convert another format into a spec-v1 dataset"),
    "calibrate": ("cdprid.cli._import", "geometric calibration of a locked-winch recording"),
    "example": ("cdprid.cli._example", "write a sample dataset (simulated, with its truth)"),
    "tune": ("cdprid.cli._tune", "tune a differentiator's parameters for the data's noise level"),
}


def _requested_command(argv) -> str | None:
    """The subcommand named in ``argv`` (first token not starting with '-'), if any."""
    for tok in argv:
        if not tok.startswith("-"):
            return tok
    return None


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The argument parser of the ``cdprid`` command.

    Parameters
    ----------
    argv : list of str, optional
        When given, only the subcommand it names is built in full; the others are listed with
        their one-line help from :data:`COMMANDS` without importing their modules, so that
        ``cdprid --help`` stays fast. None builds every subcommand.
    """
    import importlib

    parser = _Parser(
        prog="cdprid",
        description="Dynamic identification of cable-driven parallel robots.",
    )
    from cdprid import __version__

    parser.add_argument("--version", action="version", version=f"cdprid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    wanted = None if argv is None else _requested_command(argv)
    everything = argv is None or (wanted is not None and wanted not in COMMANDS)
    known = {m for m, _ in COMMANDS.values()}
    full = {m for m, _ in _OPTIONAL_COMMANDS if everything or m not in known}
    if wanted in COMMANDS:
        full.add(COMMANDS[wanted][0])
    if everything or wanted == "identify":
        _add_identify(sub)
    else:
        sub.add_parser("identify", help=COMMANDS["identify"][1], add_help=False)
    for mod, fn in _OPTIONAL_COMMANDS:
        if mod not in full:
            for name, (m, helptext) in COMMANDS.items():
                if m == mod:
                    sub.add_parser(name, help=helptext, add_help=False)
            continue
        try:
            module = importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name == mod:
                continue
            raise
        getattr(module, fn)(sub)
    _harden(parser, _option_rules())
    return parser


def main(argv=None) -> int:
    """Entry point of the ``cdprid`` console script; returns the exit code.

    Exit codes: 0 success, 2 a problem in the user's input (one sentence on stderr), 1 an
    internal error (please report it), 130 interrupted (Ctrl-C; outputs are written whole or
    not at all).
    """
    try:
        _check_environment()
    except UserError as exc:
        print(f"cdprid: error: {exc}", file=sys.stderr)
        return 2
    try:
        argv = list(sys.argv[1:] if argv is None else argv)
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        args._argv = argv  # the command line, for the outputs that say what made them
    except SystemExit as exc:  # --help, --version, or an invalid option (argparse printed it)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    except KeyboardInterrupt:
        print("cdprid: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # noqa: BLE001  (a bug in a command's parser)
        if os.environ.get("CDPRID_DEBUG"):
            raise
        print(f"cdprid: internal error: {type(exc).__name__}: {exc} "
              "(set CDPRID_DEBUG=1 for a traceback and please report it)", file=sys.stderr)
        return 1
    previous = install_termination_handlers()
    try:
        _enable_x64()
        rc = int(args.func(args) or 0)
        check_pending()  # a signal swallowed where it could not be raised still ends the run
        return rc
    except KeyboardInterrupt as exc:
        return _interrupted(getattr(exc, "signum", signal.SIGINT))
    except BaseException:
        if pending() is not None:  # an error while unwinding from a signal: the signal wins
            return _interrupted(pending())
        return _failed(sys.exc_info()[1])
    finally:
        restore_handlers(previous)


def console_main() -> int:
    """The ``cdprid`` executable: :func:`main`, and after an interruption (exit code >= 128)
    the process ends at once (``os._exit``) once the streams are flushed: the command has
    already removed its partial outputs, and skipping the interpreter's teardown avoids
    tearing down XLA's worker threads while they may still run (a Ctrl-C during
    ``import uacdpr``'s calibration once ended in a segmentation fault).

    NumPy's OpenBLAS runs single-threaded unless ``OPENBLAS_NUM_THREADS`` is set: its
    worker threads spin while waiting, and on a machine shared with other jobs that spin
    took the cores XLA needed (``cdprid diagnose`` 56-60 s instead of 30-32 s beside two
    busy processes on 2 cores; on a quiet machine the same wall time and 15 % less CPU;
    ``benchmarks/speed.py --only diagnose --baseline 47722e3 [--load 2]``). Set before
    NumPy is imported, which the parser does not do."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    rc = main()
    if rc >= 128:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(rc)
    return rc


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
