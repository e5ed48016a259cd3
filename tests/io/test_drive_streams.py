"""Format 1.2: robot.toml drive fields, currents.csv, optional tensions.csv (issue 41)."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.io import DatasetError, read_dataset, read_drives, read_stream, write_dataset
from cdprid.io._drives import drive_table
from cdprid.model import SIX_SUSPENDED, robot_from_dict

FIELDS = {"drum_radius": 0.05, "gear_ratio": 10.0, "torque_constant": 0.1,
          "torque_constant_tolerance": 0.1}


def _write(tmp_path, drives=None, tension=True, currents=True):
    robot = robot_from_dict(SIX_SUSPENDED)
    t = np.arange(0, 2.0, 0.01)
    pos = np.column_stack([0.1 * np.sin(t), 0.1 * np.cos(t), 1.0 + 0 * t])
    extra = {}
    if currents:
        extra["currents"] = (["t"] + [f"i_{j}" for j in range(1, 7)],
                             np.column_stack([t, np.ones((len(t), 6))]))
    return write_dataset(tmp_path / "d", robot, t, pos, t,
                         np.full((len(t), 6), 20.0) if tension else None, extra=extra,
                         drives=drives)


def test_drive_fields_round_trip_and_nominal_constant(tmp_path):
    drives = [dict(FIELDS, drive_reference=(j == 2)) for j in range(6)]
    path = _write(tmp_path, drives)
    d = read_drives(path)
    np.testing.assert_allclose(d.k_nominal, 0.1 * 10.0 / 0.05)  # K_t N / r = 20 N/A
    assert d.reference.tolist() == [False, False, True, False, False, False]
    t, cur = read_stream(path, "currents", "i", 6)
    assert cur.shape == (200, 6)


def test_old_datasets_still_read_and_tensions_stay_required_by_default(tmp_path):
    path = _write(tmp_path / "a", currents=False)
    assert read_drives(path) is None
    assert read_dataset(path).tension.shape == (200, 6)
    path = _write(tmp_path / "b", [FIELDS] * 6, tension=False)
    with pytest.raises(DatasetError, match="tensions.csv"):
        read_dataset(path)
    ds = read_dataset(path, require_tensions=False)
    assert ds.tension is None and ds.tension_t is None


@pytest.mark.parametrize("bad, message", [
    ({"drum_radius": 0.05, "gear_ratio": 10.0}, "lacks the drive field 'torque_constant'"),
    (dict(FIELDS, drum_radius=-1.0), "'drum_radius' must be > 0"),
    (dict(FIELDS, torque_constant_tolerance=-0.1), "must be >= 0"),
    (dict(FIELDS, drive_reference="yes"), "true or false"),
])
def test_bad_drive_fields_are_one_sentence(bad, message):
    with pytest.raises(DatasetError, match=message):
        drive_table([bad] + [FIELDS] * 5)


def test_malformed_currents_are_refused_with_the_column(tmp_path):
    path = _write(tmp_path, [FIELDS] * 6, currents=False)
    (path / "currents.csv").write_text("t,i_1,i_2\n" + "\n".join(
        f"{k * 0.01},1,1" for k in range(60)))
    with pytest.raises(DatasetError, match="lacks the column 'i_3'"):
        read_stream(path, "currents", "i", 6)


def test_a_near_miss_drive_field_is_refused():
    from cdprid.model import RobotFileError

    bad = dict(SIX_SUSPENDED, cable=[dict(c, drum_radus=0.05) for c in SIX_SUSPENDED["cable"]])
    with pytest.raises(RobotFileError, match="did you mean 'drum_radius'"):
        robot_from_dict(bad)
