"""The ``cdprid`` command line: one module per command."""

# ruff: noqa: F401  (explicit re-exports)

from cdprid.cli._main import main as main
