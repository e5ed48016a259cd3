"""An injected effect (:class:`Effect`, validated by its spec) and what the simulator's plant
takes from a list of them.

Every function here asks the effects' specs (:data:`cdprid.effects._registry.REGISTRY`) and
names no effect: the model of each effect is in its own module (``_time_delay.py``...) and in
``docs/effects.md``, generated from the specs (:func:`cdprid.effects.vocabulary_markdown`).
Several effects may be combined (also the same effect on several cables).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cdprid.base import InputError
from cdprid.effects._registry import SPECS, spec_of
from cdprid.effects._spec import Place as _Place

__all__ = [
    "Effect",
    "parse_effect",
    "validate_effects",
    "true_robot",
    "true_gravity",
    "load_cell_friction",
    "encoder_lengths",
    "external_wrench",
    "effect_parameters_table",
]


@dataclasses.dataclass(frozen=True)
class Effect:
    """One injected effect of the vocabulary (validated at construction by its spec).

    Parameters
    ----------
    name : str
        A key of :data:`cdprid.effects.VOCABULARY`.
    params : dict
        Exactly its parameters; strings (as from the command line) are converted:
        ``"3"``, ``"1.05"``, ``"0.01,0,-0.02"`` or ``"[0.01, 0, -0.02]"``.

    Raises
    ------
    InputError
        Unknown effect or parameter names, missing parameters or bad values (one sentence
        naming the effect and the parameter and listing the valid names).
    """

    name: str
    params: dict = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "params", spec_of(self.name).validate(dict(self.params)))


def parse_effect(name: str, pairs) -> Effect:
    """Build an :class:`Effect` from ``key=value`` strings (command-line form).

    Parameters
    ----------
    name : str
    pairs : sequence of str
        E.g. ``["cable=3", "gain=1.05"]``.

    Returns
    -------
    Effect
    """
    params = {}
    for text in pairs:
        if "=" not in text:
            raise InputError(f"--param {text!r} must have the form key=value (effect '{name}').")
        k, v = text.split("=", 1)
        params[k.strip()] = v
    return Effect(name, params)


def validate_effects(effects, n_cables: int) -> list[Effect]:
    """Check cable numbers against the robot and the combination of effects.

    Parameters
    ----------
    effects : sequence of Effect or (name, params)
    n_cables : int

    Returns
    -------
    list of Effect

    Raises
    ------
    InputError
        A cable beyond the robot's, an effect given twice that may be given once, or a
        drive-side effect (``Place.DRIVE``: the simulator's load-cell recording has no motor
        current).
    """
    out = []
    for e in effects:
        e = e if isinstance(e, Effect) else Effect(*e)
        if SPECS[e.name].place is _Place.DRIVE:
            raise InputError(
                f"effect '{e.name}' acts in a winch drive, on its motor current, which this "
                "simulation does not write: simulate the drives with "
                "cdprid.simulation.simulate_drives (their true k, J, fv, fc, c) and diagnose "
                "with --source currents.")
        c = e.params.get("cable")
        if c is not None and c != "all" and c > n_cables:
            raise InputError(
                f"effect '{e.name}' refers to cable {c} but the robot has {n_cables} cables "
                f"(numbered 1 to {n_cables})."
            )
        out.append(e)
    for spec in SPECS.values():
        if spec.once and sum(e.name == spec.name for e in out) > 1:
            raise InputError(f"effect '{spec.name}' is given more than once; give it once.")
    return out


def true_robot(robot, effects):
    """The plant's robot: nominal geometry with the effects' ``robot`` terms applied.

    Parameters
    ----------
    robot : CableRobot
    effects : sequence of Effect

    Returns
    -------
    CableRobot
        Exit points, attachments and pulley radii of the plant.
    """
    arrays = {"B_A": np.array(robot.B_A), "P_b": np.array(robot.P_b),
              "pulley_radius": np.array(robot.pulley_radius)}
    for e in effects:
        if (term := SPECS[e.name].robot) is not None:
            term(arrays, e.params)
    return robot.replace(**arrays)


def true_gravity(robot, effects) -> np.ndarray:
    """Gravity of the plant expressed in the pose frame (the effects' ``gravity`` terms).

    Parameters
    ----------
    robot : CableRobot
    effects : sequence of Effect

    Returns
    -------
    ndarray (3,), m/s^2
    """
    g = np.asarray(robot.gravity, float)
    for e in effects:
        if (term := SPECS[e.name].gravity) is not None:
            g = term(g, e.params)
    return g


def load_cell_friction(effects, W, v, omega) -> np.ndarray:
    """What the load cells read in excess of the tension, ``(n, m)``, from the effects
    between the platform and the cell (place ``PULLEY``: ``pulley_friction``).

    Parameters
    ----------
    effects : sequence of Effect
    W : (n, 6, m) true wrench matrices
    v, omega : (n, 3) platform velocity and angular rate at the tension times

    Returns
    -------
    ndarray (n, m)
        ``-coulomb_N sign(dl/dt) - viscous_Ns_per_m dl/dt`` on the cables with friction, N.
    """
    from cdprid.effects._sensor import load_cell_reading
    from cdprid.effects._spec import Place

    W = np.asarray(W)
    zero = np.zeros((W.shape[0], W.shape[2]))
    friction = [e for e in effects if SPECS[e.name].place is Place.PULLEY]
    return load_cell_reading(friction, zero, W, v, omega, np.zeros(W.shape[0]))


def encoder_lengths(effects, L, tension) -> np.ndarray:
    """What the winch encoders read, ``(n, m)`` (the effects' ``encoder`` terms:
    ``L / (1 + tau / EA_N)`` on elastic cables).

    Parameters
    ----------
    effects : sequence of Effect
    L : (n, m) geometric cable lengths (leave point to attachment), m
    tension : (n, m) cable tensions, N

    Returns
    -------
    ndarray (n, m)
        The unstrained lengths (``L`` where no effect acts on a cable's encoder), m.
    """
    out = np.array(L, float)
    for e in effects:
        if (term := SPECS[e.name].encoder) is not None:
            out = term(out, tension, e.params)
    return out


def external_wrench(effects, t) -> np.ndarray:
    """The summed wrench of the effects' ``wrench`` terms (``external_wrench``), ``(k, 6)``.

    Parameters
    ----------
    effects : sequence of Effect
    t : array (k,)
        Plant times, s.

    Returns
    -------
    ndarray (k, 6)
        Force (N, base frame) and moment about P (N m, base frame) on the platform.
    """
    t = np.asarray(t, float)
    out = np.zeros((t.size, 6))
    for e in effects:
        if (term := SPECS[e.name].wrench) is not None:
            out += term(t, e.params)
    return out


def effect_parameters_table(effects) -> dict:
    """The ``[truth.effect_parameters]`` table of meta.toml.

    One effect: its parameters as flat keys (e.g. ``delay_s = 0.025``). Several effects:
    the flat keys that are not ambiguous (given by one effect only), plus one sub-table per
    effect name (``[truth.effect_parameters.tension_gain]``); a name used again gets
    ``_2``, ``_3``... appended.

    Parameters
    ----------
    effects : sequence of Effect

    Returns
    -------
    dict
    """
    effects = [e for e in effects if e.name != "none"]
    if len(effects) == 1:
        return dict(effects[0].params)
    flat: dict = {}
    counts: dict = {}
    for e in effects:
        for k, v in e.params.items():
            counts[k] = counts.get(k, 0) + 1
            flat[k] = v
    out = {k: v for k, v in flat.items() if counts[k] == 1}
    seen: dict = {}
    for e in effects:
        seen[e.name] = seen.get(e.name, 0) + 1
        key = e.name if seen[e.name] == 1 else f"{e.name}_{seen[e.name]}"
        out[key] = dict(e.params)
    return out
