"""Warnings on the terminal, once.

Commands print their warnings on stdout with the result table; a copy goes to stderr so that a
redirected stdout (``> out.txt``) still shows them, except when both streams are one terminal,
where each warning would be shown twice.
"""

from __future__ import annotations

import sys

__all__ = ["echo_warnings"]


def echo_warnings(warnings) -> None:
    """Copy ``warnings`` (already printed on stdout) to stderr unless both are a terminal."""
    if not (sys.stdout.isatty() and sys.stderr.isatty()):
        for w in warnings:
            print(f"warning: {w}", file=sys.stderr)
