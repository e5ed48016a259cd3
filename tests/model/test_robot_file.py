"""robot.toml spec 1.1: the new limits and [platform] fields are read, round-trip, and every
invalid value is refused with one sentence naming the file and the field."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from cdprid.model import RobotFileError, load_robot, robot_from_dict, robot_to_dict

BASE = {
    "name": "spec11",
    "limits": {"tension_min": 5.0, "tension_max": 60.0, "cable_speed_max": 1.0,
               "workspace_min": [-0.4, -0.35, 0.5], "workspace_max": [0.4, 0.35, 0.95],
               "acceleration_max": 1.5, "jerk_max": 10.0, "tilt_max": 0.2,
               "angular_velocity_max": 0.8, "angular_acceleration_max": 4.0,
               "cable_clearance": 0.015},
    "cable": [{"exit": [1.0, 0.0, 2.0], "anchor": [0.1, 0.0, 0.0]},
              {"exit": [-1.0, 0.0, 2.0], "anchor": [-0.1, 0.0, 0.0]},
              {"exit": [0.0, 1.0, 2.0], "anchor": [0.0, 0.1, 0.0]}],
    "platform": {"mass": 4.3, "com": [0.0, 0.01, -0.05],
                 "inertia": [[0.05, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 0.04]],
                 "mass_uncertainty": 0.2, "com_uncertainty": 0.02, "inertia_uncertainty": 0.3,
                 "body_min": [-0.15, -0.15, -0.1], "body_max": [0.15, 0.15, 0.05]},
}


def test_spec11_fields_read():
    r = robot_from_dict(BASE, "robot.toml")
    lim, pl = r.limits, r.platform
    assert (lim.acceleration_max, lim.jerk_max, lim.tilt_max) == (1.5, 10.0, 0.2)
    assert (lim.angular_velocity_max, lim.angular_acceleration_max) == (0.8, 4.0)
    assert lim.cable_clearance == 0.015
    assert (pl.mass_uncertainty, pl.com_uncertainty, pl.inertia_uncertainty) == (0.2, 0.02, 0.3)
    assert pl.body_min == (-0.15, -0.15, -0.1) and pl.body_max == (0.15, 0.15, 0.05)
    again = robot_from_dict(robot_to_dict(r), "again")
    assert again.limits == lim and again.platform == pl
    absent = robot_from_dict({k: v for k, v in BASE.items() if k not in ("limits", "platform")})
    assert absent.limits.acceleration_max is None and absent.platform.body_min is None


@pytest.mark.parametrize("table, field, value, words", [
    ("limits", "acceleration_max", -1.0, "must be > 0"),
    ("limits", "jerk_max", "fast", "finite number"),
    ("limits", "tilt_max", 0.0, "must be > 0"),
    ("limits", "cable_clearance", float("nan"), "finite number"),
    ("limits", "tension_max", 2.0, "must exceed"),
    ("limits", "workspace_max", [0.4, -0.5, 0.95], "must exceed"),
    ("platform", "mass", 0.0, "must be > 0"),
    ("platform", "mass_uncertainty", 1.5, "below 1"),
    ("platform", "com_uncertainty", -0.01, ">= 0"),
    ("platform", "body_max", [0.1, 0.1], "list of 3"),
    ("platform", "body_max", [-0.2, 0.15, 0.05], "must exceed"),
    ("platform", "inertia", [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]],
     "positive definite"),
])
def test_spec11_invalid_fields_one_sentence(tmp_path, table, field, value, words):
    d = copy.deepcopy(BASE)
    d[table][field] = value
    with pytest.raises(RobotFileError) as exc:
        robot_from_dict(d, "dir/robot.toml")
    msg = str(exc.value)
    assert msg.startswith("dir/robot.toml:") and field in msg and words in msg
    assert msg.count(". ") == 0 and msg.endswith(".")


def test_body_box_needs_both_corners():
    d = copy.deepcopy(BASE)
    del d["platform"]["body_min"]
    with pytest.raises(RobotFileError, match="body_min.*body_max.*together"):
        robot_from_dict(d, "robot.toml")


def test_load_robot_reads_spec11_file(tmp_path):
    text = """name = "x"
[limits]
jerk_max = 12.5
cable_clearance = 0.02
[[cable]]
exit = [1.0, 0.0, 2.0]
anchor = [0.0, 0.0, 0.0]
[platform]
mass = 2.0
body_min = [-0.1, -0.1, -0.1]
body_max = [0.1, 0.1, 0.1]
"""
    p = tmp_path / "robot.toml"
    p.write_text(text)
    r = load_robot(p)
    assert r.limits.jerk_max == 12.5 and r.limits.cable_clearance == 0.02
    np.testing.assert_allclose(r.platform.body_max, [0.1, 0.1, 0.1])
