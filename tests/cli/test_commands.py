"""The command registry (issue 36 item 5): one module per command, the parser and the help
listing built from one table, ``--help`` without JAX, exit codes decided by exception type."""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cdprid.base import InputError
from cdprid.cli import build_parser, main
from cdprid.cli._commands import COMMANDS
from cdprid.cli._exits import is_user_error

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src"
HEAVY = ("jax", "scipy", "matplotlib")

# Commands whose --help lists a registry of the library, which only its face (importing JAX)
# provides today: the differentiators (cdprid.signal.METHODS), the effects and presets
# (cdprid.effects.VOCABULARY, cdprid.model.PRESETS). Every other --help imports no JAX.
HELP_LISTS_THE_LIBRARY = {("differentiate",), ("simulate",)}


def _subparsers(parser: argparse.ArgumentParser) -> argparse._SubParsersAction:
    return next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))


def _help_paths(parser, prefix=()) -> list[tuple[str, ...]]:
    """Every command path (``()``, ``("import",)``, ``("import", "c3d")``, ...)."""
    paths = [prefix]
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                paths += _help_paths(sp, prefix + (name,))
    return paths


def test_the_parser_is_built_from_the_registry():
    """Names, order and one-line helps of the full parser are the registry's; every command's
    module defines ``configure`` and sets the function that runs it (for `import`, each
    format's)."""
    sp = _subparsers(build_parser())
    assert list(sp.choices) == [c.name for c in COMMANDS]
    assert [(ca.dest, ca.help) for ca in sp._choices_actions] == \
        [(c.name, c.help) for c in COMMANDS]
    for c in COMMANDS:
        assert c.module == f"cdprid.cli._{c.name}", "one module per command, named after it"
        assert callable(importlib.import_module(c.module).configure)
        leaves = [sp.choices[c.name]]  # the command, or each FORMAT of `cdprid import`
        while any(isinstance(a, argparse._SubParsersAction) for a in leaves[0]._actions):
            leaves = [f for p in leaves for f in _subparsers(p).choices.values()]
        assert all(callable(p.get_default("func")) for p in leaves), c.name


def test_top_level_help_lists_every_command_once(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for c in COMMANDS:
        lines = [ln for ln in out.splitlines() if ln.split()[:1] == [c.name]]
        assert len(lines) == 1 and c.help in " ".join(out.split()), c.name


def test_only_the_asked_command_is_built():
    """``build_parser(argv)`` configures the named command; the others are bare entries."""
    sp = _subparsers(build_parser(["tune", "--help"]))
    assert [a.dest for a in sp.choices["tune"]._actions if a.option_strings][:1] == ["help"]
    assert all(sp.choices[c.name]._actions == [] for c in COMMANDS if c.name != "tune")


_PROBE = """
import contextlib, io, json, sys
from cdprid.cli import main
heavy = {heavy!r}
seen = {{}}
for path in json.loads(sys.argv[1]):
    with contextlib.redirect_stdout(io.StringIO()):
        rc = main([*path, "--help"])
    seen[" ".join(path) or "(top)"] = [rc, sorted(m for m in heavy if m in sys.modules)]
print(json.dumps(seen))
"""


def _probe(paths) -> dict:
    """Run ``cdprid PATH --help`` for each path in one fresh interpreter, in order; for each,
    its exit code and the heavy modules loaded so far."""
    code = _PROBE.format(heavy=HEAVY)
    env = {**os.environ, "PYTHONPATH": f"{SRC}{os.pathsep}{ROOT}"}
    proc = subprocess.run([sys.executable, "-c", code, json.dumps(paths)], capture_output=True,
                          text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def test_help_imports_no_jax_scipy_or_matplotlib():
    """``cdprid --help`` and ``cdprid COMMAND [FORMAT] --help`` import none of them (checked
    in one fresh interpreter: every help must leave the list empty)."""
    paths = [list(p) for p in _help_paths(build_parser()) if p[:1] not in HELP_LISTS_THE_LIBRARY]
    assert len(paths) >= len(COMMANDS)  # the top level, the commands, the import formats
    seen = _probe(paths)
    assert seen == {(" ".join(p) or "(top)"): [0, []] for p in paths}


def test_the_helps_that_list_the_library_are_exactly_those_named():
    """The exceptions above are real (and go from the list once the faces load lazily)."""
    for path in sorted(HELP_LISTS_THE_LIBRARY):
        seen = _probe([list(path)])
        assert seen[" ".join(path)][0] == 0 and "jax" in seen[" ".join(path)][1], path


# ----------------------------------------------------------------------------- exit codes


def _raise_from(exc: BaseException, filename: str) -> BaseException:
    """``exc`` raised by code whose frame claims to be in ``filename``."""
    try:
        exec(compile("raise exc", filename, "exec"), {"exc": exc})
    except BaseException as caught:  # noqa: BLE001
        return caught
    raise AssertionError("not raised")


def test_exit_code_is_decided_by_type_not_by_where_it_was_raised():
    inside = str(SRC / "cdprid" / "io" / "_dataset.py")
    outside = str(Path(np_file()).resolve())
    assert not is_user_error(_raise_from(ValueError("could not convert"), inside))
    assert not is_user_error(_raise_from(ValueError("x"), outside))
    assert is_user_error(_raise_from(InputError("x"), outside))
    assert is_user_error(_raise_from(InputError("x"), inside))


def np_file() -> str:
    import numpy

    return numpy.__file__


def _infeasible():
    from cdprid.model import InfeasibleTensionsError

    return InfeasibleTensionsError("tension distribution infeasible at 3 of 10 samples.", [1])


@pytest.mark.parametrize("make,rc,line", [
    (lambda: InputError("--out x: a bad value."), 2, "cdprid: error: --out x: a bad value."),
    (_infeasible, 2, "cdprid: error: tension distribution infeasible at 3 of 10 samples."),
    (lambda: ValueError("invalid literal for int()"), 1, "cdprid: internal error: ValueError"),
    (lambda: RuntimeError("boom"), 1, "cdprid: internal error: RuntimeError: boom"),
], ids=["InputError", "InfeasibleTensionsError", "ValueError", "RuntimeError"])
def test_main_exit_code_by_exception_type(monkeypatch, tmp_path, capsys, make, rc, line):
    """What a command raises decides the exit code: a user error is one sentence and 2, any
    other exception an internal error and 1."""
    import cdprid.cli._example as example

    def failing(args):
        raise make()

    monkeypatch.delenv("CDPRID_DEBUG", raising=False)
    monkeypatch.setattr(example, "_cmd_example", failing)
    assert main(["example", "--out", str(tmp_path / "ex")]) == rc
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(line), err
    assert not (tmp_path / "ex").exists()


@pytest.mark.parametrize("var,value", [("CDPRID_SCAN_UNROLL", "0"),
                                       ("CDPRID_CACHE_DIR", "{file}")])
def test_bad_environment_is_one_sentence_and_exit_2(monkeypatch, tmp_path, capsys, var, value):
    """Checked before the command line is parsed: nothing is built or written."""
    (tmp_path / "a_file").write_text("")
    monkeypatch.setenv(var, value.format(file=tmp_path / "a_file"))
    assert main(["example", "--out", str(tmp_path / "ex")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cdprid: error: environment variable {var}=")
    assert not (tmp_path / "ex").exists()
