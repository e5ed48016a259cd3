"""Argparse ``type=`` validators shared by every command: options are checked at parse time.

Each validator turns a bad value into one sentence (argparse prints ``cdprid CMD: error:
argument --opt: <sentence>`` and exits with code 2) before any work starts. They import
nothing heavy, so building the parser stays fast.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

__all__ = [
    "existing_dir",
    "existing_file",
    "existing_path",
    "finite_float",
    "nonneg_float",
    "nonneg_int",
    "positive_float",
    "positive_int",
    "probability",
    "unit_interval_open_closed",
    "json_or_file",
    "float_in",
    "int_at_least",
]


def _float(text: str) -> float:
    try:
        v = float(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"'{text}' is not a number.") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"'{text}' is not a finite number.")
    return v


def _int(text: str) -> int:
    try:
        return int(str(text).strip())
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"'{text}' is not an integer.") from None


def finite_float(text: str) -> float:
    """A finite float (rejects nan and inf)."""
    return _float(text)


def positive_float(text: str) -> float:
    """A finite float > 0."""
    v = _float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"{text} must be greater than 0.")
    return v


def duration_up_to(limit_s: float, why: str):
    """A ``type=`` for a duration in s: finite, > 0 and at most ``limit_s`` (memory is bounded:
    ``why`` says what the command holds per sample)."""

    def check(text: str) -> float:
        v = positive_float(text)
        if v > limit_s:
            raise argparse.ArgumentTypeError(f"{text} s is longer than {limit_s:g} s, the most "
                                             f"this command takes ({why}).")
        return v

    return check


#: Longest excitation the optimiser takes: it differentiates through every 100 Hz sample.
EXCITE_MAX_S = 600.0
#: Longest training signal of ``tune``: every noise realisation is held in memory.
TUNE_MAX_S = 3600.0
#: Longest simulated recording (4 h at 100 Hz is about 1.5 million samples per stream).
SIMULATE_MAX_S = 14400.0
#: Most samples of one simulated stream (4 h at 100 Hz), whatever the rate.
SIMULATE_MAX_SAMPLES = 1_440_000


def nonneg_float(text: str) -> float:
    """A finite float >= 0."""
    v = _float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text} must be 0 or more.")
    return v


def positive_int(text: str) -> int:
    """An integer >= 1."""
    v = _int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"{text} must be an integer of at least 1.")
    return v


def nonneg_int(text: str) -> int:
    """An integer >= 0."""
    v = _int(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text} must be an integer of at least 0.")
    return v


def probability(text: str) -> float:
    """A probability strictly between 0 and 1 (a significance level, a confidence)."""
    v = _float(text)
    if not 0 < v < 1:
        raise argparse.ArgumentTypeError(f"{text} must lie strictly between 0 and 1.")
    return v


def unit_interval_open_closed(text: str) -> float:
    """A number in (0, 1] (a forgetting factor, a fraction)."""
    v = _float(text)
    if not 0 < v <= 1:
        raise argparse.ArgumentTypeError(f"{text} must lie in (0, 1].")
    return v


def float_in(lo: float, hi: float, lo_open: bool = False, hi_open: bool = False):
    """A validator for a finite float in the interval between ``lo`` and ``hi``."""
    lb, rb = ("(" if lo_open else "["), (")" if hi_open else "]")

    def check(text: str) -> float:
        v = _float(text)
        if (v < lo or (lo_open and v == lo)) or (v > hi or (hi_open and v == hi)):
            raise argparse.ArgumentTypeError(f"{text} must lie in {lb}{lo:g}, {hi:g}{rb}.")
        return v

    check.__name__ = f"float in {lb}{lo:g}, {hi:g}{rb}"
    return check


def int_at_least(lo: int):
    """A validator for an integer >= ``lo``."""

    def check(text: str) -> int:
        v = _int(text)
        if v < lo:
            raise argparse.ArgumentTypeError(f"{text} must be an integer of at least {lo}.")
        return v

    check.__name__ = f"integer >= {lo}"
    return check


def existing_file(text: str) -> str:
    """A path naming an existing, readable file (returned unchanged)."""
    p = Path(text)
    if not p.exists():
        raise argparse.ArgumentTypeError(f"{text}: the file is missing (it does not exist).")
    if p.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a folder, expected a file.")
    if not os.access(p, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text}: the file is not readable.")
    return text


def existing_dir(text: str) -> str:
    """A path naming an existing folder (returned unchanged)."""
    p = Path(text)
    if not p.exists():
        raise argparse.ArgumentTypeError(f"{text}: the folder is missing (it does not exist).")
    if not p.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a file, expected a folder.")
    return text


def existing_path(text: str) -> str:
    """A path naming an existing file or folder (returned unchanged)."""
    if not Path(text).exists():
        raise argparse.ArgumentTypeError(f"{text}: does not exist.")
    return text


def json_or_file(text: str) -> str:
    """Inline JSON (starting with ``{``) or the path of an existing JSON file.

    The JSON itself is parsed later by :func:`cdprid.cli._json_args.load_json_object`; this only
    refuses a
    path that does not exist, so that ``--params nofile.json`` says so instead of "bad JSON".
    """
    s = text.lstrip()
    if s.startswith("{") or s.startswith("["):
        return text
    return existing_file(text)
