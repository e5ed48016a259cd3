"""Deprecated path (goes in the next release): import from ``cdprid.core``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.core._nuisance", "cdprid.core")
