"""Deprecated path (goes in the next release): import from ``cdprid.excitation``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.excitation._safety", "cdprid.excitation")
