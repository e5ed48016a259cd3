"""Differentiator parameters chosen from the data when the user gives none (issue 24).

``euler-filtfilt`` without a ``cutoff_hz`` gets the widest cutoff whose predicted
errors-in-variables attenuation stays below :data:`cdprid.core.BUDGET`
(:func:`cdprid.core.choose_cutoff`, noise levels estimated from the data); every other method,
or an explicit cutoff, is left as given.
"""

from __future__ import annotations

from cdprid.core import choose_cutoff, noise_levels

__all__ = ["AUTO_BANDWIDTH_METHODS", "cutoff_from_data", "resolve_params"]

AUTO_BANDWIDTH_METHODS = ("euler-filtfilt",)
"""Differentiators whose cutoff is chosen from the data when not given."""


def cutoff_from_data(differentiator: str, params: dict | None) -> bool:
    """Whether :func:`resolve_params` chooses the cutoff from the data: an
    :data:`AUTO_BANDWIDTH_METHODS` differentiator given no ``cutoff_hz``."""
    return differentiator in AUTO_BANDWIDTH_METHODS and "cutoff_hz" not in (params or {})


def resolve_params(ds, sig, differentiator: str, params: dict | None,
                   notes: list) -> tuple[dict, list]:
    """The differentiator's parameters, with the cutoff chosen from the data when missing.

    Parameters
    ----------
    ds : Dataset
    sig : AlignedSignals
        The aligned recording (positions, quaternions, segments).
    differentiator : str
    params : dict or None
        As given by the user.
    notes : list
        The choice's sentence is appended here.

    Returns
    -------
    params : dict
    warnings : list of str
        One sentence when even the narrowest cutoff leaves a predicted attenuation above the
        budget (the motion is too small for the noise).
    """
    if not cutoff_from_data(differentiator, params):
        return dict(params or {}), []
    params = dict(params or {})
    _, _, s_pos, s_rot = noise_levels(ds, sig)
    rot = sig.quaternion if sig.has_rotation else None
    choice = choose_cutoff(sig.position, rot, sig.dt, getattr(sig, "segments", ()) or
                           ((0, len(sig.t)),), s_pos, s_rot)
    params["cutoff_hz"] = choice.cutoff_hz
    notes.append(choice.note())
    warns = []
    if not choice.within_budget:
        worst = max(choice.ratio, key=choice.ratio.get)
        what = ("motion is too small for the position noise" if worst == "translation" else
                "rotation is too small for the orientation noise")
        warns.append(f"the {what}: even with a {choice.cutoff_hz:g} Hz cutoff the noise passes "
                     f"{choice.ratio[worst]:.1%} of the {worst} acceleration power, which biases "
                     "the parameters it carries towards zero by about as much (excite more: "
                     "cdprid excite).")
    return params, warns
