"""``diagnose --mat`` variables and the episodes hook, on a DiagnosisResult built here (a
diagnosis run takes ~20 s; its JSON is stored whole, the arrays are the result's own)."""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.io

from cdprid.cli import main
from cdprid.diagnosis import DiagnosisResult, Finding
from cdprid.io import write_mat
from cdprid.report import diagnosis_variables, episodes_of


@dataclasses.dataclass(frozen=True)
class _Episode:  # what another module's episode object may look like
    start_s: float
    end_s: float
    kind: str


def _result(episodes=None):
    t = np.arange(0.0, 4.0, 0.01)
    rng = np.random.default_rng(1)
    rb, re_ = rng.standard_normal((len(t), 6)), rng.standard_normal((len(t), 6))
    par = {"m": {"value": 6.3, "std": 0.003, "rel_std_percent": 0.05},
           "mxG": {"value": 0.07, "std": 0.001, "rel_std_percent": 1.4}}
    ext = dict(par, delay_s={"value": -0.005, "std": 1e-4, "rel_std_percent": 2.0})
    f = Finding("time_delay", {"delay_s": -0.005}, {"delay_s": [-0.0052, -0.0048]}, [],
                0.97, 0.72, 1e-12, 2050.0, 1e-5)
    res = DiagnosisResult(par, [0.5] * 6, 0.36, [f], ext, 0.27, [], {"heldout": "cv"},
                          {"t": t, "residual_base": rb, "residual_extended": re_,
                           "use": t > 0.5, "train": np.ones(len(t), bool)})
    if episodes is not None:
        object.__setattr__(res, "episodes", episodes)
    return res


def test_diagnosis_mat_round_trip(tmp_path):
    res = _result([_Episode(1.0, 2.0, "push"), _Episode(2.5, 3.0, "slack")])
    data = res.as_json()
    out = write_mat(tmp_path / "d.mat", diagnosis_variables(res, data, {"command": "c",
                                                                         "version": "v"}))
    m = scipy.io.loadmat(out)
    np.testing.assert_array_equal(m["t"].ravel(), res.arrays["t"])
    np.testing.assert_array_equal(m["residual_base"], res.arrays["residual_base"])
    np.testing.assert_array_equal(m["residual_extended"], res.arrays["residual_extended"])
    np.testing.assert_array_equal(m["used"].ravel().astype(bool), res.arrays["use"])
    assert [str(c[0][0]) for c in m["extended_parameter_names"]] == ["m", "mxG", "delay_s"]
    np.testing.assert_array_equal(m["extended_estimates"].ravel(), [6.3, 0.07, -0.005])
    f = m["findings"][0, 0][0, 0]
    assert str(f["effect"][0]) == "time_delay"
    assert f["heldout_rms_after"][0, 0] == 0.72
    assert f["interval"][0, 0]["delay_s"].ravel().tolist() == [-0.0052, -0.0048]
    ep = m["episodes"][0, 0]
    assert ep["start_s"].ravel().tolist() == [1.0, 2.5]
    assert ep["end_s"].ravel().tolist() == [2.0, 3.0]
    assert [str(k[0][0]) for k in ep["kind"]] == ["push", "slack"]
    j = m["json"][0, 0]
    assert j["base"][0, 0]["heldout_residual_rms"][0, 0] == 0.36


def test_episodes_hook_reads_objects_dicts_and_keys():
    assert episodes_of(_result()) == []
    assert episodes_of({"episodes": [{"start_s": 1, "end_s": 2, "kind": "k", "x": 3}]}) == [
        {"start_s": 1, "end_s": 2, "kind": "k", "x": 3}]
    assert episodes_of(_result([_Episode(1.0, 2.0, "push"), {"kind": "no times"}])) == [
        {"start_s": 1.0, "end_s": 2.0, "kind": "push"}]


def test_diagnose_and_identify_refuse_bad_mat_before_work(tmp_path, capsys):
    from cdprid.data import write_sample

    ds = write_sample(tmp_path / "sample")
    (tmp_path / "d.mat").write_text("keep")
    capsys.readouterr()
    assert main(["diagnose", str(ds), "--mat", str(tmp_path / "d.mat")]) == 2
    err = capsys.readouterr().err
    assert "--mat" in err and "exists" in err and len(err.splitlines()) == 1, err
    assert (tmp_path / "d.mat").read_text() == "keep"
    rc = main(["identify", str(tmp_path / "none"), "--online", "--report", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert rc == 2 and "--report applies to batch identify only" in err
    rc = main(["identify", str(tmp_path / "none"), "--mat", str(tmp_path / "x.mat"),
               "--report", str(tmp_path / "x.mat")])
    assert rc == 2
