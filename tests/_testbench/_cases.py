"""Recordings of the floor-winch 8-cable robot with several effects at once (issue 37).

Each seed draws: 45-55 s; tensions at 500, 800 or 1000 Hz on their own clock (phase 50-60 ms),
with a clock offset of 12-28 ms on three seeds of four; white (0.3-0.5 N) + AR(1) (0.3 N,
pole 0.95-0.98 per sample) tension noise; motion capture at 100 or 200 Hz (0.3 mm, 0.2 mrad);
Coulomb friction of 1-3 N on every pulley (cells on the winch side); on even seeds a
hysteretic cell (2-4 N); an offset (3-8 N) on one cell; on odd seeds a gain (4-8 %) on
another; on seeds 3, 7, ... viscous drag (5-15 N s/m); on seeds 2, 6, ... a 3 cm exit-point
error. robot.toml states a mass 3 % below the truth.

:func:`floor8_combined` (issue 38) adds what happens only sometimes: hand pushes and marker
glitches (:mod:`._episodes`), and gives the same recording without them (its clean twin).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from tests._testbench._episodes import draw_glitches, draw_pushes, push_wrench
from tests._testbench._motion import motion
from tests._testbench._record import Recording, _plant, feasible_path, record
from tests._testbench._robots import floor8
from tests._testbench._sensors import Sensors


def floor8_case(seed: int, duration_s: float | None = None, hysteresis: bool | None = None,
                noise: bool = True, tension_rate_hz: float | None = None) -> Recording:
    """The seed's recording of the floor-winch robot (module docstring); ``hysteresis``
    forces a hysteretic cell on (True) or off (False); ``tension_rate_hz`` replaces the drawn
    load-cell rate (every other draw unchanged; the AR(1) pole stays per sample)."""
    rob, s, dur, exit_error, drag = _floor8_draw(seed, duration_s, hysteresis)
    if tension_rate_hz is not None:
        s = dataclasses.replace(s, tension_rate_hz=float(tension_rate_hz))
    return record(rob, s, seed, dur, exit_error=exit_error, drag_Ns_per_m=drag, noise=noise)


def _floor8_draw(seed: int, duration_s: float | None, hysteresis: bool | None):
    """The robot, sensors, duration, exit-point errors and drag of :func:`floor8_case`."""
    rng = np.random.default_rng(37_000 + seed)
    rob = floor8()
    m = rob.m
    cab = rng.permutation(m)
    rate = float(rng.choice([500.0, 800.0, 1000.0]))
    offset_s = float(rng.uniform(0.012, 0.028)) if seed % 4 else 0.0
    coulomb = float(rng.uniform(1.0, 3.0))
    off = np.zeros(m)
    off[cab[0]] = rng.choice([-1, 1]) * rng.uniform(3.0, 8.0)
    gain = np.ones(m)
    if seed % 2:
        gain[cab[1]] = 1 + rng.choice([-1, 1]) * rng.uniform(0.04, 0.08)
    hyst = np.zeros(m)
    if (seed % 2 == 0) if hysteresis is None else hysteresis:
        hyst[cab[2]] = rng.uniform(2.0, 4.0)
    drag = float(rng.uniform(5.0, 15.0)) if seed % 4 == 3 else 0.0
    exit_error = np.zeros((m, 3))
    if seed % 4 == 2:
        u = rng.normal(size=3)
        exit_error[cab[3]] = 0.03 * u / np.linalg.norm(u)
    s = Sensors(rate, offset_s, float(rng.uniform(0.05, 0.06)), float(rng.choice([100.0, 200.0])),
                float(rng.uniform(0.3, 0.5)), 0.3, float(rng.uniform(0.95, 0.98)),
                tuple(off), tuple(gain), (coulomb,) * m, (0.0,) * m, True, tuple(hyst),
                3e-4, 2e-4)
    dur = float(rng.uniform(45.0, 55.0)) if duration_s is None else duration_s
    return rob, s, dur, exit_error, drag


#: the least platform-side tension during a drawn push (coarse check every 20 ms; or the
#: trajectory's own least tension when lower), N
PUSH_MIN_TENSION_N = 15.0


def floor8_combined(seed: int, clean: bool = False, n_pushes: int | None = None,
                    n_glitches: int = 4, duration_s: float | None = None) -> Recording:
    """:func:`floor8_case`'s robot, sensors and effects (its own trajectory draw) with 2-3
    hand pushes (10-40 N, 1-3 s, smooth ramps, a moment from a hand on the rim) and
    ``n_glitches`` marker glitches (1-3 samples, 3-8 cm, 2-6 deg); ``clean``: the same
    recording (same noise) without them. The pushes and glitches are in
    ``Recording.pushes`` / ``.glitches`` and meta.toml's ``[[truth.episodes]]``.
    ``duration_s`` replaces the seed's 45-55 s (at least 25 s)."""
    rob, s, dur, exit_error, drag = _floor8_draw(seed, duration_s, None)
    path = feasible_path(rob, np.random.default_rng(seed), dur)
    rng = np.random.default_rng(38_000 + seed)
    n = int(rng.integers(2, 4)) if n_pushes is None else n_pushes
    t = np.arange(0.0, dur, 0.02)
    mo = motion(path, t)
    least = min(PUSH_MIN_TENSION_N, float(np.min(_plant(rob, rob.A + exit_error, mo, drag)[0])))
    for _ in range(50):  # a push that would slacken a cable is drawn again
        pushes = draw_pushes(rng, dur, n)
        tau = _plant(rob, rob.A + exit_error, mo, drag, push_wrench(pushes, t))[0]
        if np.min(tau) >= least:
            break
    else:
        raise RuntimeError(f"floor8 seed {seed}: no push draw keeps the cables taut")
    glitches = draw_glitches(rng, dur, n_glitches, pushes)
    if clean:
        pushes, glitches = (), ()
    return record(rob, s, seed, dur, exit_error=exit_error, drag_Ns_per_m=drag, path=path,
                  pushes=pushes, glitches=glitches)


def floor8_with(effects: list, seed: int, noise_scale: float = 1.0,
                duration_s: float = 52.0) -> Recording:
    """The floor-winch robot with the vocabulary's ``effects`` ``[(name, params)]`` only
    (``time_delay``, ``tension_offset``, ``tension_gain``, ``load_cell_hysteresis``,
    ``pulley_friction``, ``viscous_drag``, ``exit_point_error``; cables from 1), its own
    tension clock (500, 800 or 1000 Hz, phase 50-60 ms) and white + AR(1) noise (0.4 N +
    0.3 N, pole 0.95-0.98) times ``noise_scale``; rotations up to 5 deg."""
    rng = np.random.default_rng(52_000 + seed)
    rob = floor8()
    m = rob.m
    off, gain, hyst = np.zeros(m), np.ones(m), np.zeros(m)
    coul, visc = np.zeros(m), np.zeros(m)
    exit_error = np.zeros((m, 3))
    delay = drag = 0.0
    for name, p in effects:
        i = p["cable"] - 1 if isinstance(p.get("cable"), int) else slice(None)
        if name == "time_delay":
            delay = p["delay_s"]
        elif name == "tension_offset":
            off[i] = p["offset_N"]
        elif name == "tension_gain":
            gain[i] = p["gain"]
        elif name == "load_cell_hysteresis":
            hyst[i] = p["width_N"]
        elif name == "pulley_friction":
            coul[i], visc[i] = p["coulomb_N"], p["viscous_Ns_per_m"]
        elif name == "viscous_drag":
            drag = p["coefficient_Ns_per_m"]
        elif name == "exit_point_error":
            exit_error[i] = p["displacement_m"]
        else:
            raise KeyError(f"the test simulator does not simulate {name!r}")
    s = Sensors(float(rng.choice([500.0, 800.0, 1000.0])), float(delay),
                float(rng.uniform(0.05, 0.06)), 100.0, 0.4 * noise_scale, 0.3 * noise_scale,
                float(rng.uniform(0.95, 0.98)), tuple(off), tuple(gain), tuple(coul),
                tuple(visc), True, tuple(hyst), 3e-4 * noise_scale, 2e-4 * noise_scale)
    return record(rob, s, seed, duration_s, exit_error=exit_error, drag_Ns_per_m=drag)
