"""``time_delay``: the tension stream lags the pose stream (one module, one effect)."""

from __future__ import annotations

from cdprid.effects._form import DiagnosisForm
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC"]


def _undo(tau, q, c):
    """First-order expansion about the linearisation point: exact in value and slope."""
    return tau + (q["delay"] - c["at"]["delay"]) * c["taud"]


SPEC = EffectSpec(
    name="time_delay",
    parameters=(Parameter("delay_s", "float", "s", minimum=0.0),),
    doc="""``time_delay {delay_s}``
    The tension stream lags the pose stream: the tension sample stamped t holds the
    (noise-free) tensions of the plant at ``t - delay_s``, the trajectory being evaluated
    exactly at that time (a true fractional delay).""",
    place=Place.CLOCK, once=True, plant=(("delay_s", "delay_s"),),
    diagnosis=DiagnosisForm(
        blocks=(("delay", 1),), group=0, keys=("delay_s",), bounds={"delay_s": 0.5},
        clock=True, report_size=True, tension=_undo,
        separated_by={"viscous_drag": "faster motion with the same velocities (a delay "
                      "follows the tension rate, drag the velocity)"}),
)
