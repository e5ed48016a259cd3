"""Deprecated path (goes in the next release): import from ``cdprid.signal``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.signal._sihd_high", "cdprid.signal")
