"""Geometry selected again once the sensor side is complete (issue 37): a geometry finding
accepted before a sensor-side one is chosen again given the final sensor side."""

from __future__ import annotations

import pytest

from cdprid.diagnosis._candidates import Candidate
from cdprid.diagnosis._regeometry import is_geometry, needs_reselection

DELAY = Candidate("time_delay")
FRICTION = Candidate("pulley_friction_all")
ANCHOR3 = Candidate("anchor_point_error", 3)
EXIT2 = Candidate("exit_point_error", 2)
HYST1 = Candidate("load_cell_hysteresis", 1)
OFFSET7 = Candidate("tension_offset", 7)
ROT = Candidate("rotational_dynamics")
TILT = Candidate("frame_tilt")


def test_geometry_is_the_displacement_forms_and_the_frame_tilt():
    assert is_geometry(ANCHOR3) and is_geometry(EXIT2) and is_geometry(TILT)
    assert not any(is_geometry(c) for c in (DELAY, FRICTION, HYST1, OFFSET7, ROT))


@pytest.mark.parametrize("accepted, expected", [
    # floor8 seed 2's greedy path: anchor 3 at step 3, the hysteretic cell and the offset after
    ((DELAY, FRICTION, ANCHOR3, HYST1, OFFSET7), True),
    ((DELAY, FRICTION, HYST1, OFFSET7, EXIT2), False),  # geometry last: the same path again
    ((DELAY, FRICTION, EXIT2, ANCHOR3), False),  # nothing on the sensor side after it
    ((EXIT2, ROT), False),  # the rotational dynamics extend the base model: not sensor side
    ((DELAY, FRICTION, HYST1), False),  # no geometry
    # floor8 seed 3 at 200 Hz: a tilt at step 2 carried a gain and an offset, drag after it
    ((FRICTION, DELAY, TILT, Candidate("viscous_drag")), True),
    ((), False),
])
def test_reselection_only_when_a_sensor_finding_came_after_geometry(accepted, expected):
    assert needs_reselection(accepted) is expected


@pytest.mark.slow  # a full diagnosis of the floor-winch robot, 60-90 s on 2 quiet cores
def test_floor8_seed_2_names_no_anchor_error(tmp_path):
    """floor8 seed 2 (a 3 cm exit-point error on cable 2, a hysteretic cell on cable 1, a
    13 ms clock offset, friction on every pulley, an offset on cable 7) held two anchor
    errors (cables 3 and 1) that stood in for the exit-point error; none is in the truth."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from tests._testbench import floor8_case, write

    from cdprid.diagnosis import diagnose
    from cdprid.io import read_dataset

    rec = floor8_case(2)
    res = diagnose(read_dataset(write(rec, tmp_path / "d", overwrite=True)))
    named = {(f.effect, f.parameters.get("cable")) for f in res.findings}
    truth = {(name, p.get("cable")) for name, p in rec.effects}
    # on its cable: the reselection's sensor pass (geometry held back) once took a 0.44 N
    # offset on cable 5 in the exit-point error's place; weighed against the geometry it
    # was chosen without, it is withdrawn (sensor_pass_check)
    assert named <= truth, named - truth
    # before session 11 the greedy path took the anchor errors and the reselection replaced
    # them; since the hysteresis form finds the cell on cable 1 first, no geometry is taken
    rs = res.info["geometry_reselection"]
    assert not rs["tried"] or rs["kept"] == "geometry selected again"


@pytest.mark.slow  # a full diagnosis of the floor-winch robot, 2-3 min on 2 cores
def test_floor8_seed_3_at_200_hz_names_the_gain_and_offset_not_a_tilt(tmp_path):
    """floor8 seed 3 with the load cells at 200 Hz (the AR(1) noise slower in time): the greedy
    path took a 1-2 deg frame tilt at step 2 (it carries the 4.6 % gain on cable 2 and the
    -3 N offset on cable 3 together), then a 17 cm exit-point error, and stopped before any
    gain or offset was tested (results/many-effects-floor8-200hz.md). The reselection
    withdraws the tilt with the displacements, completes the sensor side first, then tries
    the geometry: the truth's five effects, with their sizes."""
    import jax

    jax.config.update("jax_enable_x64", True)
    from tests._testbench import floor8_case, write

    from cdprid.diagnosis import diagnose
    from cdprid.io import read_dataset

    rec = floor8_case(3, tension_rate_hz=200.0)
    res = diagnose(read_dataset(write(rec, tmp_path / "d", overwrite=True)))
    named = {(f.effect, f.parameters.get("cable")) for f in res.findings}
    assert ("tension_gain", 2) in named and ("tension_offset", 3) in named, named
    assert not any(e in ("frame_tilt", "exit_point_error", "anchor_point_error")
                   for e, _ in named), named
    gain = next(f for f in res.findings if f.effect == "tension_gain")
    assert abs(gain.parameters["gain"] - rec.sensors.gain[1]) < 0.01
