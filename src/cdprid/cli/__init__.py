"""The ``cdprid`` command line: one module per command, listed once in
:mod:`cdprid.cli._commands`."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.cli._main import build_parser as build_parser
from cdprid.cli._main import console_main as console_main
from cdprid.cli._main import main as main

# Names whose modules load cdprid.base, NumPy or JAX load on first use (PEP 562), so that
# ``import cdprid.cli`` and ``cdprid --help`` stay fast.
_LAZY = {
    "parse_params": "cdprid.cli._json_args",
    "install_termination_handlers": "cdprid.cli._signals",
    "restore_handlers": "cdprid.cli._signals",
    "run_online_cli": "cdprid.cli._online",
}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'cdprid.cli' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(_LAZY[name]), name)


def __dir__():
    return sorted({*globals(), *_LAZY})
