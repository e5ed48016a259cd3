"""Deprecated path (goes in the next release): import from ``cdprid.simulation``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.simulation._simulate", "cdprid.simulation")
