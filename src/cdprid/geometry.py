"""Deprecated path (goes in the next release): import from ``cdprid.model``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.model", "cdprid.model")
