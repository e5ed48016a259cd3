"""The typed ``info`` and ``episodes`` of a diagnosis result (issue 36, item 4).

Both read also as the JSON objects they are written as (:class:`cdprid.diagnosis._parts.
JsonView`: ``res.info["verdict"]``, ``res.info.get("subset")``, ``e["start_s"]``), keep the
keys they do not name in ``details`` and the JSON key order in ``json_keys``, so
``diagnose --json`` is unchanged byte for byte.
"""

from __future__ import annotations

import dataclasses

from cdprid.diagnosis._parts import _Open

__all__ = ["DiagnosisInfo", "EpisodeRecord"]


@dataclasses.dataclass(frozen=True, eq=False)
class DiagnosisInfo(_Open):
    """How the diagnosis was run and what it measured besides the estimates
    (``diagnose --json``'s ``info``, with ``information_criterion`` and ``not_named``, which the
    JSON writes elsewhere). A field the diagnosis did not set is None (and not in the JSON).

    Attributes
    ----------
    base_model : str
        ``"translation"`` or ``"full"`` (the model ``identify --model auto`` uses: full when
        the platform rotates).
    rotation_deg : float
        The platform's largest rotation in the recording, deg.
    n_samples, n_train, n_heldout : int
        Pose samples used; those the fits use; those held out (None with cross-validation).
    heldout : str
        How the held-out residual is taken (a train/test split or blocked k-fold CV).
    heldout_units : str
        Units of the held-out residuals.
    train_until : float or None
        ``--train-until``, s.
    taut_threshold_N : float
        Tension below which a sample counts as slack, N.
    n_candidates : int
        Vocabulary candidates (effect x cable) tried.
    alpha : float
        Family-wise level of the naming tests.
    competing_models_tried : int
        Alternative models evaluated for ``competing_models``.
    noise_position_m : float
        Position noise estimated from the data, m.
    noise_tension_N : list of float
        Tension noise per cable, N.
    rotation_amplitude_rad : float or None
        The platform's 99.5 % rotation amplitude, rad.
    n_excluded_slack : int
        Samples left out because a cable was slack.
    row_weights : list of float
        Weights of the six wrench rows in the fits.
    hac_lags : int
        Lags of the HAC covariance.
    weight_at_rest : dict or None
        The weight the final model reads at rest, N (against the nominal mass).
    information_criterion : dict
        BIC of the base and extended models (effective sample size).
    not_named : list of dict
        The effects a real recording always holds, sized and not named.
    unexplained_rule : dict or None
        The tests of the ``unexplained`` stage and their family-wise rule.
    lengths : dict or None
        The winch-lengths stream's use (None without one).
    clock_profile : dict or None
        The tension clock's profile (grid, held-out rms, the refined minimum).
    second_start : dict or None
        The second search start's outcome.
    geometry_reselection : dict or None
        Whether the geometry was selected again, and what was kept.
    wall_time_s : float
        The diagnosis's wall time, s.
    subset : dict or None
        The budgeted subset of the recording, when one was used.
    verdict : dict or None
        Whether the extended model explains the data within its noise, and how far above
        it the held-out residual is.
    details : dict
        The JSON keys not named above.
    json_keys : tuple of str
        The JSON keys in their order.
    """

    base_model: str | None = None
    rotation_deg: float | None = None
    n_samples: int | None = None
    n_train: int | None = None
    n_heldout: int | None = None
    heldout: str | None = None
    heldout_units: str | None = None
    train_until: float | None = None
    taut_threshold_N: float | None = None
    n_candidates: int | None = None
    alpha: float | None = None
    competing_models_tried: int | None = None
    noise_position_m: float | None = None
    noise_tension_N: list | None = None
    rotation_amplitude_rad: float | None = None
    n_excluded_slack: int | None = None
    row_weights: list | None = None
    hac_lags: int | None = None
    weight_at_rest: dict | None = None
    information_criterion: dict | None = None
    not_named: list | None = None
    unexplained_rule: dict | None = None
    lengths: dict | None = None
    clock_profile: dict | None = None
    second_start: dict | None = None
    geometry_reselection: dict | None = None
    wall_time_s: float | None = None
    subset: dict | None = None
    verdict: dict | None = None
    details: dict = dataclasses.field(default_factory=dict)
    json_keys: tuple = ()

    def as_json(self) -> dict:
        """The JSON object: the keys of ``json_keys`` in their order (as the diagnosis set
        them, None values included); without ``json_keys`` (constructed by name) the fields
        that are not None, then ``details``.

        Returns
        -------
        dict
        """
        if self.json_keys:
            return super().as_json()
        out = {k: getattr(self, k) for k in self._names() if getattr(self, k) is not None}
        out.update(self.details)
        return out


@dataclasses.dataclass(frozen=True, eq=False)
class EpisodeRecord(_Open):
    """One located episode as the diagnosis reports it (:meth:`cdprid.episodes.Episode.
    as_json`): what happened only at times, left out of the fits unless kept.

    Attributes
    ----------
    start_s, end_s : float
        Its time interval, s.
    kind : str
        ``external_wrench``, ``load_cell_step``, ``pose_glitches`` or ``energy``.
    force_N : list of float or None
        Mean force on the platform over the episode (base frame), N.
    moment_Nm : list of float or None
        Mean moment, N m.
    size_N, size_Nm : float or None
        Their norms.
    p_value : float or None
        Its p-value (the scan's false-alarm rate over the recording).
    details : dict
        The kind's other keys (``energy_J``, ``n_samples``, ``largest_m``, ``cable``, ...).
    json_keys : tuple of str
        The JSON keys in their order.
    """

    start_s: float
    end_s: float
    kind: str
    force_N: list | None = None
    moment_Nm: list | None = None
    size_N: float | None = None
    size_Nm: float | None = None
    p_value: float | None = None
    details: dict = dataclasses.field(default_factory=dict)
    json_keys: tuple = ()
