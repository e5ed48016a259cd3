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

REST_SPEED_M_S: float = 0.02
"""The platform is at rest when its speed stays below this (m/s); the one "at rest" rule
(:func:`cdprid.core.rest_mask`, for at least 0.5 s). Measured on the real recording
UACDPR FreeMotion02: in its stillest 0.7 s the speed (Euler + 4 Hz) has median 9.5 mm/s and
maximum 19 mm/s (marker noise and vibration), so 5 mm/s finds no rest window at all; 20 mm/s
finds t = 4.90-5.60 s."""
