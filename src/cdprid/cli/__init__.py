"""The ``cdprid`` command line: one module per command."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.cli._main import build_parser as build_parser
from cdprid.cli._main import console_main as console_main
from cdprid.cli._main import main as main
from cdprid.cli._main import parse_params as parse_params
from cdprid.cli._signals import install_termination_handlers as install_termination_handlers
from cdprid.cli._signals import restore_handlers as restore_handlers

# The command modules load JAX: their names load on first use (PEP 562), so that ``import
# cdprid.cli`` and ``cdprid --help`` stay fast.
_LAZY = {"run_online_cli": "cdprid.cli._online"}


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module 'cdprid.cli' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(_LAZY[name]), name)
