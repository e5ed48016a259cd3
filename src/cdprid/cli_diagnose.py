"""Deprecated path (goes in the next release): import from ``cdprid.cli``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.cli._diagnose", "cdprid.cli")
