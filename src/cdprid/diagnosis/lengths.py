"""Deprecated path (goes in the next release): import from ``cdprid.diagnosis``."""

from cdprid._moved import moved

__getattr__, __dir__ = moved(__name__, "cdprid.diagnosis._lengths", "cdprid.diagnosis")
