"""``cdprid identify --source currents | free-motion`` on the command line (issue 41)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tests.identify import winch_sim  # noqa: E402

from cdprid.cli import main  # noqa: E402
from cdprid.model import SIX_SUSPENDED  # noqa: E402

SIX = dict(SIX_SUSPENDED, home=[0.0, 0.0, 1.4])


@pytest.fixture(scope="module")
def no_tolerance(tmp_path_factory):
    """A recording whose drives state no tolerance and whose robot has no mass: no reference."""
    sim = winch_sim.simulate(SIX, (5.0, np.zeros(3), np.diag([0.05, 0.05, 0.08])), seed=2,
                             duration=8.0, rate_drive=100.0)
    sim["drive_fields"] = [{k: v for k, v in f.items() if k != "torque_constant_tolerance"}
                           for f in sim["drive_fields"]]
    return winch_sim.write(tmp_path_factory.mktemp("cli") / "d", SIX, sim)


def test_no_reference_is_one_sentence_and_exit_2(no_tolerance, capsys):
    assert main(["identify", str(no_tolerance), "--source", "currents"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("cdprid: error: no scale reference") and err.count("\n") == 0


@pytest.mark.parametrize("extra, word", [(["--online"], "--online"),
                                         (["--std", "iid"], "--std iid"),
                                         (["--reference", "kg:3"], "not understood"),
                                         (["--differentiator", "sihd2-cascade"],
                                          "euler-filtfilt")])
def test_options_of_the_tension_path_are_refused(no_tolerance, capsys, extra, word):
    assert main(["identify", str(no_tolerance), "--source", "currents", *extra]) == 2
    assert word in capsys.readouterr().err


def test_a_dataset_without_tensions_still_needs_them_for_the_tension_path(no_tolerance,
                                                                        capsys):
    assert main(["identify", str(no_tolerance)]) == 2
    assert "tensions.csv" in capsys.readouterr().err


def test_free_motion_refuses_six_cables(no_tolerance, capsys):
    assert main(["identify", str(no_tolerance), "--source", "free-motion",
                 "--reference", "mass:5"]) == 2
    assert "fewer than 6 cables" in capsys.readouterr().err


@pytest.mark.slow  # ~25 s: the Cramer-Rao bound's compilation
def test_currents_json_on_the_command_line(no_tolerance, tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["identify", str(no_tolerance), "--source", "currents", "--reference",
                 "drive:1", "--json", str(out), "--params", '{"cutoff_hz": 4}']) == 0
    js = json.loads(out.read_text())
    assert js["source"] == "currents" and js["scale_reference"]["kind"] == "drive"
    assert {"parameters", "drives", "sigma_rho", "notes", "warnings"} <= set(js)
    assert "scale reference: drive 1" in capsys.readouterr().out
