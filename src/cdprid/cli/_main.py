"""The ``cdprid`` entry point and its parser, built from the command registry.

Every subcommand reads spec-v1 datasets. Bad input gives one sentence on stderr and exit code
2, never a traceback (``CDPRID_DEBUG=1`` shows tracebacks of internal errors). The commands are
listed once, in :mod:`cdprid.cli._commands`; each lives in its own module, imported only when
that command is asked for, so ``cdprid --help`` and ``cdprid COMMAND --help`` import no JAX,
SciPy or Matplotlib (except where a command's help lists a registry of the library: the
differentiators of ``differentiate``, the effects and presets of ``simulate``). Options are
validated at parse time by :mod:`cdprid.cli._types`; exit codes are decided in
:mod:`cdprid.cli._exits`.

Environment variables (checked before any work; a bad value is one sentence and exit 2): see
:mod:`cdprid.cli._environment` (``CDPRID_DEBUG``, ``CDPRID_CACHE_DIR``,
``CDPRID_SCAN_UNROLL``), and ``OPENBLAS_NUM_THREADS``, NumPy's BLAS threads: the ``cdprid``
executable sets 1 unless given (see :func:`console_main`).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

from cdprid.cli._commands import COMMANDS
from cdprid.cli._environment import environment_error

__all__ = ["main", "console_main", "build_parser"]


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


def _requested_command(argv) -> str | None:
    """The subcommand named in ``argv`` (first token not starting with '-'), if any."""
    for tok in argv:
        if not tok.startswith("-"):
            return tok
    return None


def build_parser(argv=None) -> argparse.ArgumentParser:
    """The argument parser of the ``cdprid`` command, built from :data:`COMMANDS`.

    Parameters
    ----------
    argv : list of str, optional
        When given, only the command it names is built in full (its module imported and its
        ``configure`` run); the others are listed with their one-line help without importing
        their modules, so that ``cdprid --help`` stays fast. None builds every command.

    Returns
    -------
    argparse.ArgumentParser
    """
    import importlib

    from cdprid import __version__

    parser = _Parser(
        prog="cdprid",
        description="Dynamic identification of cable-driven parallel robots.",
    )
    parser.add_argument("--version", action="version", version=f"cdprid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    wanted = None if argv is None else _requested_command(argv)  # an unknown name: argparse
    built = False  # refuses it from the bare entries ("invalid choice"), importing nothing
    for cmd in COMMANDS:
        if argv is None or cmd.name == wanted:
            importlib.import_module(cmd.module).configure(sub.add_parser(cmd.name, help=cmd.help))
            built = True
        else:
            sub.add_parser(cmd.name, help=cmd.help, add_help=False)
    if built:
        _harden(parser, _option_rules())
    return parser


def main(argv=None) -> int:
    """Entry point of the ``cdprid`` console script; returns the exit code.

    Exit codes: 0 success, 2 a problem in the user's input (one sentence on stderr), 1 an
    internal error (please report it), 130 interrupted (Ctrl-C; outputs are written whole or
    not at all), 128 + N another termination signal N.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after ``cdprid`` (default ``sys.argv[1:]``).

    Returns
    -------
    int
    """
    bad_env = environment_error()
    if bad_env is not None:
        print(f"cdprid: error: {bad_env}", file=sys.stderr)
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
    return _run(args)


def _run(args) -> int:
    """Run the parsed command with the termination handlers installed; its exit code."""
    import signal

    from cdprid.base import check_pending, pending
    from cdprid.cli._environment import enable_x64
    from cdprid.cli._exits import failed, interrupted
    from cdprid.cli._signals import install_termination_handlers, restore_handlers

    previous = install_termination_handlers()
    try:
        enable_x64()
        rc = int(args.func(args) or 0)
        check_pending()  # a signal swallowed where it could not be raised still ends the run
        return rc
    except KeyboardInterrupt as exc:
        return interrupted(getattr(exc, "signum", signal.SIGINT))
    except BaseException:
        if pending() is not None:  # an error while unwinding from a signal: the signal wins
            return interrupted(pending())
        return failed(sys.exc_info()[1])
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
    NumPy is imported, which the parser does not do.

    Returns
    -------
    int
        The exit code (0 success, 1 internal error, 2 user mistake); after an interruption
        (128 + the signal number) the process exits instead of returning.
    """
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    rc = main()
    if rc >= 128:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        os._exit(rc)
    return _end_process(rc)


def _end_process(rc: int) -> int:
    """End the finished command's process without the interpreter's teardown, or return
    ``rc`` when a thread of its own still runs (or CPython lacks ``atexit._run_exitfuncs``).

    The exit handlers run first (JAX's clean-up, temporary folders, logging), then the streams
    are flushed and ``os._exit(rc)`` skips the finalisation of ~1300 modules and of XLA's
    objects: 0.3 CPU s and 0.9-1.1 s of wall time after ``cdprid identify`` on a loaded
    2-core machine (load 11; ``benchmarks/speed.py --only identify``). Every output is written
    whole before a command returns (the atomic output helpers), so nothing is left to flush
    but the streams.

    Parameters
    ----------
    rc : int
        The command's exit code.

    Returns
    -------
    int
        ``rc`` when the process is left to end normally.
    """
    import atexit
    import threading

    run_exit_handlers = getattr(atexit, "_run_exitfuncs", None)
    others = [t for t in threading.enumerate()
              if t is not threading.main_thread() and t.is_alive() and not t.daemon]
    if run_exit_handlers is None or others:
        return rc
    run_exit_handlers()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(rc)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
