"""``external_wrench``: a push on the platform for a while (one module, one effect).

Everything the tool knows about this effect is here, in :data:`SPEC`: its parameters, its
model text (for ``docs/effects.md``) and the wrench the simulator's plant adds. It is not a
candidate of the diagnosis (a wrench that changes from push to push has no parameters to fit):
the episodes stage (:mod:`cdprid.episodes`) locates it in time and the fits leave it out.
"""

from __future__ import annotations

import numpy as np

from cdprid.base import InputError
from cdprid.effects._spec import EffectSpec, Parameter, Place

__all__ = ["SPEC", "EXTERNAL_WRENCH", "RAMP_S", "profile"]

NAME = "external_wrench"
#: the name as the face exports it
EXTERNAL_WRENCH = NAME

#: duration of each smooth ramp of a push, s (at most a third of the push)
RAMP_S = 0.1

_DOC = """``external_wrench {start_s, end_s, force_N, moment_Nm}``
    Something outside the robot (a hand, a contact, a brake) pushes the platform between
    ``start_s`` and ``end_s`` (s, the trajectory's clock): the force ``force_N`` (N, base
    frame, applied at P) and the moment ``moment_Nm`` (N m about P, base frame), each times
    a profile that rises from 0 to 1 over the first ``min(0.1 s, (end_s - start_s) / 3)``
    (septic smoothstep) and falls back to 0 over the same time before ``end_s``. The
    simulator's plant follows its prescribed trajectory, so the cables take the push
    (``W_true tau = platform_wrench - w_ext - w_push``, as for ``viscous_drag``): the
    residual of the paper's model is ``-w_push``. Several may be given (each its own
    interval); they add."""


def _check(params: dict) -> None:
    """The push ends after it starts: ``end_s > start_s``."""
    if not params["end_s"] > params["start_s"]:
        raise InputError(f"effect '{NAME}' needs end_s > start_s, got start_s = "
                         f"{params['start_s']:g} and end_s = {params['end_s']:g}.")


def profile(t, start_s: float, end_s: float) -> np.ndarray:
    """The push's profile in [0, 1] at times ``t`` (s): smooth ramps up and down.

    Parameters
    ----------
    t : array (k,)
        Times, s.
    start_s, end_s : float
        The push begins rising at ``start_s`` and is back to zero at ``end_s``, s.

    Returns
    -------
    ndarray (k,)
    """
    ramp = min(RAMP_S, (end_s - start_s) / 3.0)
    t = np.asarray(t, float)

    def s7(x):
        x = np.clip(x, 0.0, 1.0)
        return x**4 * (35.0 + x * (-84.0 + x * (70.0 - 20.0 * x)))

    return s7((t - start_s) / ramp) * s7((end_s - t) / ramp)


def _wrench(t, p) -> np.ndarray:
    """The push's wrench ``(k, 6)`` at times ``t`` (force N and moment N m, base frame)."""
    w = np.concatenate([np.asarray(p["force_N"], float), np.asarray(p["moment_Nm"], float)])
    return profile(t, p["start_s"], p["end_s"])[:, None] * w[None, :]


SPEC = EffectSpec(
    name=NAME,
    parameters=(Parameter("start_s", "float", "s"), Parameter("end_s", "float", "s"),
                Parameter("force_N", "vec3", "N"), Parameter("moment_Nm", "vec3", "N m")),
    doc=_DOC, place=Place.PLATFORM, check=_check, wrench=_wrench, episodic=True,
)
