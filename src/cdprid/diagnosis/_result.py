"""Result types of the diagnosis (frozen; ``as_json`` is the CLI's JSON contract)."""

from __future__ import annotations

import dataclasses

from cdprid.diagnosis._info import DiagnosisInfo, EpisodeRecord
from cdprid.diagnosis._parts import (
    CompetingModel,
    JsonView,
    NotNamed,
    ParameterEstimates,
    RankedCandidate,
    Unexplained,
    parts,
)


@dataclasses.dataclass(frozen=True, eq=False)
class Finding(JsonView):
    """One accepted effect (read also as its JSON object: ``finding["effect"]``).

    Attributes
    ----------
    effect : str
        The vocabulary effect.
    parameters : dict
        Its values (SI units).
    interval : dict
        95 % intervals.
    aliases : list of str
        Candidates the data cannot tell from it.
    heldout_rms_before, heldout_rms_after : float
        Held-out rms without and with it (weighted units).
    p_value : float
        Bonferroni-adjusted p-value of its test.
    statistic : float
        Its Wald statistic.
    threshold : float
        The threshold its p-value passed.
    separated_by : dict
        Alias label -> what trajectory or measurement would tell the two apart.
    """

    effect: str
    parameters: dict
    interval: dict
    aliases: list
    heldout_rms_before: float
    heldout_rms_after: float
    p_value: float
    statistic: float
    threshold: float
    #: alias label -> what trajectory or measurement would tell the two apart
    separated_by: dict = dataclasses.field(default_factory=dict)

    def as_json(self) -> dict:
        """The finding as the JSON object of ``diagnose --json``'s ``findings`` list.

        Returns
        -------
        dict
            ``effect``, ``parameters`` (SI units), ``interval`` (95 %), ``aliases``, the
            held-out rms before and after it (N), ``p_value`` and the rest of its fields.
        """
        return {
            "effect": self.effect,
            "parameters": self.parameters,
            "interval": self.interval,
            "aliases": self.aliases,
            "heldout_rms_before": self.heldout_rms_before,
            "heldout_rms_after": self.heldout_rms_after,
            "p_value": self.p_value,
            "statistic": self.statistic,
            "threshold": self.threshold,
            "separated_by": self.separated_by,
        }

    @classmethod
    def of(cls, v) -> Finding:
        """``v`` itself, or the finding of its JSON object.

        Parameters
        ----------
        v : Finding or mapping

        Returns
        -------
        Finding
        """
        return v if isinstance(v, cls) else cls(**v)


@dataclasses.dataclass(frozen=True)
class DiagnosisResult:
    """Everything :func:`diagnose` found; ``as_json()`` is the CLI's JSON contract.

    The parts are typed (:class:`ParameterEstimates`, :class:`Finding`,
    :class:`RankedCandidate`, :class:`Unexplained`, :class:`CompetingModel`,
    :class:`DiagnosisInfo`, :class:`EpisodeRecord` and :attr:`not_named`) and read also as the
    dicts of earlier releases
    (``res.base_parameters["m"]["value"]`` is ``res.base_parameters["m"].value``); given as
    dicts (JSON objects) they are converted on construction.
    """

    base_parameters: ParameterEstimates
    base_residual_rms: list
    base_heldout_rms: float
    findings: list[Finding]
    extended_parameters: ParameterEstimates
    extended_heldout_rms: float
    ranking: list[RankedCandidate]
    info: DiagnosisInfo
    arrays: dict = dataclasses.field(default_factory=dict, repr=False)
    #: residual structure the extended model leaves, and hints (vocabulary effects removed
    #: by backward elimination): ``where``, ``size`` (N), ``correlates_with``, ``p_value``
    unexplained: list[Unexplained] = dataclasses.field(default_factory=list)
    #: sentences the user must read with the numbers (e.g. a budgeted subset of the recording)
    notes: list = dataclasses.field(default_factory=list)
    #: complete alternative models within the noise of the final one
    #: (:func:`cdprid.diagnosis._competing.competing_models`), best first
    competing: list[CompetingModel] = dataclasses.field(default_factory=list)
    #: the located episodes (:class:`EpisodeRecord`, as :meth:`cdprid.episodes.Episode.as_json`
    #: writes them), left out of the fits unless ``keep_episodes``
    episodes: list[EpisodeRecord] = dataclasses.field(default_factory=list)
    #: the extended model's held-out force rms (N) with the episodes' samples kept
    extended_heldout_rms_with_episodes: float | None = None

    def __post_init__(self):
        for name, convert in (("base_parameters", ParameterEstimates.of),
                              ("extended_parameters", ParameterEstimates.of),
                              ("findings", lambda v: parts(Finding, v)),
                              ("ranking", lambda v: parts(RankedCandidate, v)),
                              ("unexplained", lambda v: parts(Unexplained, v)),
                              ("competing", lambda v: parts(CompetingModel, v)),
                              ("info", DiagnosisInfo.of),
                              ("episodes", lambda v: [EpisodeRecord.of(_json(e)) for e in v])):
            object.__setattr__(self, name, convert(getattr(self, name)))

    @property
    def not_named(self) -> list[NotNamed]:
        """The effects a real recording always holds, sized and not named
        (``info["not_named"]``, typed).

        Returns
        -------
        list of NotNamed
        """
        return parts(NotNamed, self.info.get("not_named", []))

    def as_json(self) -> dict:
        """The whole diagnosis as the JSON document of ``diagnose --json`` (the contract).

        Returns
        -------
        dict
            ``base``, ``findings``, ``extended``, ``not_named``, ``unexplained``,
            ``competing_models``, ``episodes``, ``notes`` and ``info`` (SI units).
        """
        return {
            "base": {
                "parameters": self.base_parameters.as_json(),
                "residual_rms": self.base_residual_rms,
                "heldout_residual_rms": self.base_heldout_rms,
            },
            "findings": [f.as_json() for f in self.findings],
            "extended": {
                "parameters": self.extended_parameters.as_json(),
                "heldout_residual_rms": self.extended_heldout_rms,
                "heldout_residual_rms_with_episodes": self.extended_heldout_rms_with_episodes,
                "effects": [f.effect for f in self.findings],
                "information_criterion": self.info.get("information_criterion", {}),
            },
            "unexplained": [{k: v for k, v in u.items() if k != "significant"}
                            for u in self.unexplained],
            "ranking": [r.as_json() for r in self.ranking],
            "not_named": list(self.info.get("not_named", [])),
            "competing_models": [c.as_json() for c in self.competing],
            "notes": list(self.notes),
            "episodes": [e.as_json() if hasattr(e, "as_json") else e for e in self.episodes],
            "info": {k: v for k, v in self.info.items()
                     if k not in ("information_criterion", "not_named")},
        }


def _json(e):
    """An episode as its JSON object (an :class:`cdprid.episodes.Episode` or a mapping)."""
    return e if isinstance(e, EpisodeRecord) or not hasattr(e, "as_json") else e.as_json()
