"""robot.toml's ``survey_tolerance`` (issue 37): parsed, checked, written back."""

from __future__ import annotations

import pytest

from cdprid.model import SIX_SUSPENDED, RobotFileError, robot_from_dict, robot_to_dict


def test_survey_tolerance_is_read_checked_and_written_back():
    assert robot_from_dict(SIX_SUSPENDED).survey_tolerance_m is None  # not stated
    rob = robot_from_dict(dict(SIX_SUSPENDED, survey_tolerance=0.005))
    assert rob.survey_tolerance_m == 0.005
    assert robot_from_dict(robot_to_dict(rob)).survey_tolerance_m == 0.005
    assert "survey_tolerance" not in robot_to_dict(robot_from_dict(SIX_SUSPENDED))
    with pytest.raises(RobotFileError, match="survey_tolerance' must be > 0"):
        robot_from_dict(dict(SIX_SUSPENDED, survey_tolerance=-0.01))
    with pytest.raises(RobotFileError, match="did you mean 'survey_tolerance'"):
        robot_from_dict(dict(SIX_SUSPENDED, survey_tolerence=0.01))

