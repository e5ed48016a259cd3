"""The ``cdprid`` command line: one module per command."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.cli._main import console_main as console_main
from cdprid.cli._main import main as main
