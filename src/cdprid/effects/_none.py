"""``none``: no effect (the simulator's clean plant; one module, one effect)."""

from __future__ import annotations

from cdprid.effects._spec import EffectSpec

__all__ = ["SPEC"]

SPEC = EffectSpec(name="none", doc="""``none``
    Nothing.""")
