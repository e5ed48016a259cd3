"""How the diagnosis represents one effect: :class:`DiagnosisForm` (one per effect).

A leaf module: each effect's module declares its form here without importing the vocabulary.
A form names the JSON parameter of each of its theta blocks (``keys``, one per block) even when
it reports through ``params=``: the ``>= 0`` clamp of a refit (``nonneg``) is found through that
name, so a form that could lose it is refused at construction.
"""

from __future__ import annotations

import dataclasses

__all__ = ["DiagnosisForm", "SpecError", "STREAMS", "Z95"]

#: the normal distribution's 95 % two-sided quantile (the drive forms' ``drive_report``)
Z95 = 1.959963984540054

#: the force streams a diagnosis form may be restricted to (:attr:`DiagnosisForm.stream`)
STREAMS = ("any", "tensions", "currents")


class SpecError(Exception):
    """A malformed effect declaration (a spec, a diagnosis form or the registry): a mistake of
    whoever adds an effect, found at import, never the user's (so not an ``InputError``)."""


@dataclasses.dataclass(frozen=True)
class DiagnosisForm:
    """How the diagnosis represents one effect (its candidates, theta blocks, JSON form).

    The diagnosis reads only this table (:mod:`cdprid.diagnosis._candidates` and the theta
    layout of :mod:`cdprid.diagnosis._model` contain no effect name): adding an effect that
    acts through existing theta blocks touches this module only.

    Attributes
    ----------
    blocks : tuple of (block, size)
        Theta blocks of :func:`cdprid.diagnosis._model.cable_contribution` /
        :func:`~cdprid.diagnosis._model.model_side` the effect uses, ``size`` numbers per
        cable when ``per_cable`` else in all. The theta vector is laid out in the order of
        :data:`DIAGNOSIS` and of each effect's blocks.
    per_cable : bool
        One candidate per cable (parameters carry ``cable``).
    group : int
        Candidates are listed by group, then in the table's order.
    when : str
        ``"always"``, ``"no_pulley"`` (robot.toml gives no pulley) or ``"rotation"``
        (the pose stream rotates).
    stream : str
        The force stream whose recordings make it a candidate: ``"any"``, ``"tensions"``
        (load cells: ``tensions.csv``) or ``"currents"`` (winch drives: ``currents.csv``,
        ``diagnose --source currents``). A form may share theta blocks (and so their hooks)
        with a form of the other stream: the drive's current offset, torque constant and
        friction act on the reading as the load cell's offset, gain and pulley friction do.
    keys : tuple of str
        JSON parameter names of the block values, one per block, in order (a key of
        ``size`` 3 or 2 takes that many values as one list). Required with ``params=`` too.
    params : callable, optional
        ``(values, extra) -> dict`` instead of ``keys`` (e.g. a gain is ``1 + theta``).
    interval : callable, optional
        ``(lo, hi, extra) -> dict`` instead of ``keys``.
    vocabulary : str, optional
        The vocabulary name the finding reports (default: the table key).
    alias : str, optional
        Its label in ``aliases`` (default ``effect`` or ``effect:cable=i``).
    displacement : bool
        Shrink poorly determined directions of its 3-vector (weakly observable components).
    bounds : dict
        Plausibility bound of a refitted parameter's magnitude (degenerate linearisation).
    nonneg : tuple of str
        Parameters (keys of scalar blocks) whose theta value must be >= 0 after a refit.
    ranges : dict
        Parameters that must lie in an open interval after a refit.
    separated_by : dict
        Other effect -> what trajectory or measurement would tell the two apart.
    report_size : bool
        When the search does not name it, its linearised size with a 95 % interval and its
        p-value are reported anyway (``not_named``): "friction named or reported with its
        size".
    base_model : bool
        The effect extends the base model itself (rotational dynamics: 4 -> 10 inertial
        parameters) rather than adding theta blocks.
    clock : bool
        The effect is the tension stream's clock offset (profiled first, see
        :mod:`cdprid.diagnosis._clock`).
    cell_play : bool
        The effect is a play on one load cell's reading whose ``model`` hook reads the
        regressor the data carry (``DiagData.hyst_h``); once named, the diagnosis builds that
        regressor from the model's force on the cell (:mod:`cdprid.diagnosis._hysteresis`).
    tension, geometry, leave, gravity, load, model : callable, optional
        The effect's physics in the diagnosis's forward model, JAX, applied in the order of
        :data:`DIAGNOSIS` at each stage of :func:`cdprid.diagnosis._model.cable_contribution`
        (one cable, its blocks ``q`` by name, ``c`` the context,
        :class:`~cdprid.effects.CableContext`, read by key: the blocks at the linearisation
        point ``c["at"]``, ``taud``, ``ldot``, ``R``, ``p``, ``k``, ``ref``, ``t``, ``slide``,
        ``bb``): ``tension(tau, q, c)`` the tension behind the load-cell reading;
        ``geometry(geo, q)`` the exit point ``A``, attachment ``b`` (platform frame) and
        pulley radius ``r``; ``leave(T, geo, q, c)`` the leave point; ``gravity(g, q)``;
        ``load(f, Ln, g, q)`` a force on the platform at the attachment. ``model(y, d, q)``
        adds to the model side (:func:`~cdprid.diagnosis._model.model_side`).
    """

    blocks: tuple = ()
    per_cable: bool = False
    group: int = 2
    when: str = "always"
    stream: str = "any"
    #: never a candidate on the scale reference drive (a torque constant taken as exact)
    not_on_reference: bool = False
    #: a drive-side effect: the drive model's parameters it is (``identify --source currents``:
    #: ``k``, ``J``, ``fv``, ``fc``, ``c``), tested against the datasheet model (``k`` the
    #: datasheet's, the others 0) by :mod:`cdprid.diagnosis._drives`
    drive: tuple = ()
    #: ``(values, stds, k_nominal) -> (parameters, intervals)``: the effect's JSON from one
    #: drive's fitted parameters (dicts by the names of ``drive``' model) and the datasheet's k
    drive_report: object = None
    keys: tuple = ()
    params: object = None
    interval: object = None
    vocabulary: str | None = None
    alias: str | None = None
    displacement: bool = False
    bounds: dict = dataclasses.field(default_factory=dict)
    nonneg: tuple = ()
    ranges: dict = dataclasses.field(default_factory=dict)
    separated_by: dict = dataclasses.field(default_factory=dict)
    #: the effect shifts the tension stream's clock (its one block is the delay in s): the
    #: diagnosis profiles it before the greedy search and keeps it in every refit
    clock: bool = False
    #: the effect is the base model's own extension (the 4-parameter model to the full
    #: 10-parameter one), not theta blocks: its columns are the extra inertial parameters
    base_model: bool = False
    #: when not named, its size is still reported (``not_named`` in the JSON): effects a real
    #: recording always holds to some degree (friction on every pulley, a clock offset)
    report_size: bool = False
    #: a play on one load cell's reading, its regressor refined from the model's force on the
    #: cell once named (:mod:`cdprid.diagnosis._hysteresis`)
    cell_play: bool = False
    tension: object = None
    geometry: object = None
    leave: object = None
    gravity: object = None
    load: object = None
    model: object = None

    def __post_init__(self):
        if self.not_on_reference and not self.per_cable:
            raise SpecError("not_on_reference needs a per-cable form.")
        if bool(self.drive) != (self.drive_report is not None) or (
                self.drive and not self.per_cable):
            raise SpecError("a drive-side form gives drive and drive_report together, per cable.")
        if self.stream not in STREAMS:
            raise SpecError(f"a diagnosis form's stream is one of {STREAMS}, not "
                            f"{self.stream!r}.")
        if self.blocks and len(self.keys) != len(self.blocks):
            raise SpecError(
                f"a diagnosis form needs one JSON name in keys per theta block (also with "
                f"params=, for its clamp and bounds): blocks {[b for b, _ in self.blocks]}, "
                f"keys {list(self.keys)}.")
        sizes = dict(zip(self.keys, (n for _, n in self.blocks), strict=False))
        bad = [k for k in self.nonneg if sizes.get(k) != 1]
        if bad:
            raise SpecError(f"nonneg names {bad}, which are not keys of scalar blocks "
                             f"{sizes}: the >= 0 clamp would be lost.")

    @property
    def nonneg_blocks(self) -> tuple:
        """The theta blocks whose value must be >= 0 after a refit (from ``nonneg``)."""
        return tuple(b for k, (b, _) in zip(self.keys, self.blocks, strict=True)
                     if k in self.nonneg)
