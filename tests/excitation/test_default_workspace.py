"""Issue 40 (still there from before): a robot without [limits] had its default workspace on
the plane of its exits (no gentle run was possible); the box now hangs below a suspended
robot's exits, and the gentle first run exists."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.excitation import safety_limits
from cdprid.model import robot_from_dict


def _without_limits(d):
    return robot_from_dict({k: v for k, v in d.items() if k != "limits"}, source="test")


def test_suspended_robot_box_lies_below_its_exits(robot):
    r = _without_limits({"name": "r", "gravity": [0, 0, -9.81],
                         "cable": [{"exit": list(map(float, a)), "anchor": list(map(float, b))}
                                   for a, b in zip(np.asarray(robot.B_A), np.asarray(robot.P_b),
                                                   strict=True)]})
    lim = safety_limits(r, 10.0)
    A = np.asarray(r.B_A)
    lo, hi = np.asarray(lim.workspace_min), np.asarray(lim.workspace_max)
    assert "workspace" in lim.defaults_used
    assert hi[2] <= A[:, 2].min() - 0.3 + 1e-12  # below every exit, with a margin
    assert np.all(hi - lo > 0.1)  # a box, not a sliver
    assert np.all(lo[:2] > A[:, :2].min(0)) and np.all(hi[:2] < A[:, :2].max(0))


def test_exits_at_many_heights_keep_the_shrunk_box():
    cables = [{"exit": [x, y, z], "anchor": [0.1 * np.sign(x), 0.1 * np.sign(y), 0.0]}
              for x, y, z in [(-2, -2, 0.2), (-2, 2, 3.0), (2, 2, 0.2), (2, -2, 3.0),
                              (-2, -2, 3.0), (-2, 2, 0.2), (2, 2, 3.0), (2, -2, 0.2)]]
    lim = safety_limits(_without_limits({"name": "r", "gravity": [0, 0, -9.81],
                                         "cable": cables}), 10.0)
    assert lim.workspace_min[2] == pytest.approx(1.6 - 0.75 * 1.4)
    assert lim.workspace_max[2] == pytest.approx(1.6 + 0.75 * 1.4 - 0.3)


@pytest.mark.slow
def test_gentle_run_of_a_robot_without_limits(sample_dataset, tmp_path, capsys):
    import tomli_w
    import tomllib

    from cdprid.cli import main

    d = tomllib.loads((sample_dataset / "robot.toml").read_text())
    d.pop("limits")
    f = tmp_path / "robot.toml"
    f.write_text(tomli_w.dumps(d))
    assert main(["excite", str(f), "--gentle", "--out", str(tmp_path / "g")]) == 0, \
        capsys.readouterr().err
    assert (tmp_path / "g" / "trajectory.csv").exists()
