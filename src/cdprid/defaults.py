"""Named defaults shared by every feature (one definition each; never repeat the literal).

Each value states its unit and where it comes from.
"""

from __future__ import annotations

__all__ = [
    "CUTOFF_HZ",
    "FILTER_ORDER",
    "REST_SPEED_M_S",
    "TAUT_THRESHOLD_N",
    "TRIM_S",
]

CUTOFF_HZ: float = 4.0
"""Cut-off of the paper's zero-phase Butterworth low-pass (Euler + 4 Hz recipe), Hz."""

FILTER_ORDER: int = 2
"""Order of that Butterworth filter (applied forward and backward: zero phase)."""

TRIM_S: float = 1.0
"""Seconds dropped at both ends after differentiation (filter and observer transients)."""

TAUT_THRESHOLD_N: float = 5.0
"""A cable below this tension (N) is treated as slack: its samples leave the fits."""

REST_SPEED_M_S: float = 0.005
"""The platform is at rest when its speed stays below this (m/s); the one "at rest" rule."""
