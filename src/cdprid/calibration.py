"""Deprecated path (goes in the next release): import from ``cdprid.identify``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.identify._calibration", "cdprid.identify")
