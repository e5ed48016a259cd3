"""Deprecated path (goes in the next release): import from ``cdprid.report``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.report._diagnosis", "cdprid.report")
