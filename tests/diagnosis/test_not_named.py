"""Effects a real recording always holds are reported with their size when not named
(issue 23: "friction named or reported with its size")."""

from __future__ import annotations

import numpy as np

from cdprid.diagnosis import diagnose
from cdprid.io import read_dataset
from cdprid.model import SIX_SUSPENDED, preset, robot_from_dict
from cdprid.simulation import SensorNoise, simulate, write_simulation


def test_clean_data_report_friction_and_delay_sizes_that_cover_zero(tmp_path):
    robot = robot_from_dict(SIX_SUSPENDED)
    sim = simulate(robot, preset("rich", robot, duration=30.0),
                   noise=SensorNoise(position_m=2e-4, tension_N=0.5), seed=4)
    res = diagnose(read_dataset(write_simulation(sim, tmp_path / "d")))
    assert res.findings == []
    js = res.as_json()
    items = {u["effect"]: u for u in js["not_named"]}
    assert set(items) == {"pulley_friction", "time_delay"}
    fr = items["pulley_friction"]
    assert fr["parameters"]["cable"] == "all" and not fr["named"]
    # no friction: the size is tiny and the data bound it within 0.05 N (a 95 % interval
    # may miss 0 by its own width one time in twenty; here it is [0.001, 0.026] N)
    lo, hi = fr["interval"]["coulomb_N"]
    assert -0.05 < lo <= fr["parameters"]["coulomb_N"] <= hi < 0.05
    lo, hi = items["time_delay"]["interval"]["delay_s"]
    assert lo < 0 < hi and hi - lo < 0.002
    assert all(np.isfinite(u["p_value"]) for u in items.values())
    # the report's section: every number with 3 significant digits
    from cdprid.report import format_values, not_named_lines

    text = "\n".join(not_named_lines(res))
    assert "## Checked and not named" in text and "pulley_friction" in text
    assert format_values({"a": 0.0010070784, "b": [-0.000398256, 7.7255e-4], "c": "all"}) == \
        "a 0.00101, b [-0.000398, 0.000773], c all"
