"""Deprecated path (goes in the next release): import from ``cdprid.base``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.base._progress", "cdprid.base")
