"""Typed diagnosis results (issue 36, item 4): frozen parts with named attributes that still
read as the dicts of earlier releases, a JSON contract unchanged to the byte, and the typed
context that replaced the ``extra`` dict.

Oracles: two ``diagnose --json`` documents written by the code before the types
(commit 891ad5f: the shared ``craft-sim-orbits-delay`` dataset, and the 4-cable recording of
``test_competing`` with its competing models), the old ``as_json`` over plain dicts (copied
below), and, in the slow test, a new diagnosis of the shared dataset against the recorded
document.
"""

import dataclasses
import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from cdprid.diagnosis import (
    CompetingModel,
    DiagnosisContext,
    DiagnosisResult,
    Finding,
    NotNamed,
    ParameterEstimate,
    ParameterEstimates,
    RankedCandidate,
    Unexplained,
)

DATA = Path(__file__).parent / "data"
RECORDED = ["orbits_delay_diagnosis.json", "four_gain_diagnosis.json"]


def _dumps(d) -> str:
    return json.dumps(d, indent=2, allow_nan=True) + "\n"  # as cdprid.base.write_json


def _result_from_json(d: dict, **kw) -> DiagnosisResult:
    """A DiagnosisResult holding plain dicts and lists, as the pipeline held them before."""
    info = dict(d["info"])
    ic, nn = d["extended"]["information_criterion"], d["not_named"]
    info = {"information_criterion": ic, "not_named": nn, **info}
    return DiagnosisResult(
        base_parameters=d["base"]["parameters"], base_residual_rms=d["base"]["residual_rms"],
        base_heldout_rms=d["base"]["heldout_residual_rms"],
        findings=[Finding(**f) for f in d["findings"]],
        extended_parameters=d["extended"]["parameters"],
        extended_heldout_rms=d["extended"]["heldout_residual_rms"], ranking=d["ranking"],
        info=info, unexplained=kw.get("unexplained", d["unexplained"]), notes=d["notes"],
        competing=d["competing_models"], episodes=d["episodes"],
        extended_heldout_rms_with_episodes=d["extended"]["heldout_residual_rms_with_episodes"])


def _legacy_as_json(base_parameters, extended_parameters, ranking, unexplained, competing,
                    info) -> dict:
    """The parts of the JSON document the old ``DiagnosisResult.as_json`` wrote from its
    dicts (verbatim, for the keys the types changed)."""
    return {
        "base": base_parameters, "extended": extended_parameters,
        "unexplained": [{k: v for k, v in u.items() if k != "significant"}
                        for u in unexplained],
        "ranking": ranking, "not_named": list(info.get("not_named", [])),
        "competing_models": list(competing),
    }


@pytest.mark.parametrize("name", RECORDED)
def test_as_json_is_the_recorded_document_to_the_byte(name):
    """Rebuilt from a document the untyped code wrote, the typed result writes it again,
    byte for byte (the info keys in the document's order)."""
    raw = (DATA / name).read_text()
    d = json.loads(raw)
    res = _result_from_json(d)
    out = res.as_json()
    out["info"] = {k: out["info"][k] for k in d["info"]}  # the rebuild's info order
    assert _dumps(out) == raw
    assert isinstance(res.base_parameters, ParameterEstimates)
    assert all(isinstance(r, RankedCandidate) for r in res.ranking)
    assert all(isinstance(c, CompetingModel) for c in res.competing)
    if name.startswith("four"):
        assert res.competing  # the recording's competing models are covered
    # the same document as the old as_json over plain dicts
    old = _legacy_as_json(d["base"]["parameters"], d["extended"]["parameters"], d["ranking"],
                          d["unexplained"], d["competing_models"], {"not_named": d["not_named"]})
    new = {"base": out["base"]["parameters"], "extended": out["extended"]["parameters"],
           **{k: out[k] for k in ("unexplained", "ranking", "not_named", "competing_models")}}
    assert _dumps(new) == _dumps(old)


@pytest.mark.parametrize("name", RECORDED)
def test_attributes_and_keys_agree(name):
    """Every part reads the same through attributes and through the old dict keys."""
    d = json.loads((DATA / name).read_text())
    res = _result_from_json(d)
    for which, js in (("base_parameters", d["base"]["parameters"]),
                      ("extended_parameters", d["extended"]["parameters"])):
        est = getattr(res, which)
        assert list(est) == list(js) and est == js
        for k, v in js.items():
            assert est[k].value == est[k]["value"] == v["value"]
            assert est[k].std == est[k].get("std") == v["std"]
            assert est[k].rel_std_percent == v["rel_std_percent"]
            assert dict(est[k]) == v and list(est[k].keys()) == list(v)
    for r, js in zip(res.ranking, d["ranking"], strict=True):
        assert r == js and dict(r) == js
        assert (r.candidate, r.statistic, r.dof, r.p_value, r.p_bonferroni) == tuple(js.values())
    for c, js in zip(res.competing, d["competing_models"], strict=True):
        assert c == js and list(c.keys()) == list(js) and c.as_json() == js
        assert (c.replaces, c.by, c.parameters, c.effects) == (
            js["replaces"], js["by"], js["parameters"], js["effects"])
        assert c.heldout_force_rms_N == js["heldout_force_rms_N"]
        assert (c.relative_difference, c.p_worse) == (js["relative_difference"], js["p_worse"])
    for f, js in zip(res.findings, d["findings"], strict=True):
        assert f["effect"] == f.effect == js["effect"] and f == js
        assert f.get("separated_by") == js["separated_by"] and "p_value" in f
    for u, js in zip(res.not_named, d["not_named"], strict=True):
        assert (u.effect, u.parameters, u.interval, u.p_value, u.why) == (
            js["effect"], js["parameters"], js["interval"], js["p_value"], js["why"])
        assert isinstance(u, NotNamed) and u.named is False and u == js


def test_unexplained_items_keep_their_keys_and_order():
    """The unexplained stage's items differ by test (keys and order): each is written back as
    it was, ``significant`` left out of the document as before, the test-specific keys under
    ``details`` and through ``[]``."""
    structure = {"where": "force along z", "size": 0.31, "correlates_with": "tension level",
                 "coefficients": [0.1, -0.2], "significant": True, "p_raw": 1e-9,
                 "test": "structure regression (HAC Wald)", "p_value": 4e-9, "floor_N": 0.05,
                 "separated_by": "a load-cell calibration"}
    withdrawn = {"where": "pulley[cable 2]", "size": 0.2, "correlates_with": "x",
                 "p_value": 1.0, "test": "stability (halves of the recording, groups of "
                 "cables)", "withdrawn_finding": "pulley:cable=2"}
    hint = {"where": "tension_drift[cable 1]", "size": 0.12, "correlates_with": "y",
            "p_value": 0.2, "floor_N": 0.05, "test": "backward elimination (hint)"}
    items = [structure, withdrawn, hint]
    d = json.loads((DATA / RECORDED[0]).read_text())
    res = _result_from_json(d, unexplained=items)
    assert [type(u) for u in res.unexplained] == [Unexplained] * 3
    old = [{k: v for k, v in u.items() if k != "significant"} for u in items]
    assert _dumps(res.as_json()["unexplained"]) == _dumps(old)
    u = res.unexplained[0]
    assert (u.where, u.size, u.correlates_with, u.p_value, u.test) == (
        "force along z", 0.31, "tension level", 4e-9, "structure regression (HAC Wald)")
    assert u["p_raw"] == u.details["p_raw"] == 1e-9 and u["significant"] is True
    assert "withdrawn_finding" in res.unexplained[1] and "withdrawn_finding" not in u
    assert u.get("frequency_hz") is None and u.get("frequency_hz", 3) == 3
    with pytest.raises(KeyError):
        u["frequency_hz"]
    assert res.unexplained == items  # a part equals the dict it was made from


def test_parts_given_without_optional_keys():
    """A competing model without ``effects`` (as the report tests give it) and an unexplained
    item with its four keys are written with exactly their keys."""
    c = CompetingModel.of({"replaces": "a", "by": "b", "parameters": {"k": 1.0},
                           "heldout_force_rms_N": 0.27, "relative_difference": 0.004,
                           "p_worse": 0.3})
    assert c.effects is None and "effects" not in c and list(c) == [
        "replaces", "by", "parameters", "heldout_force_rms_N", "relative_difference",
        "p_worse"]
    u = Unexplained(where="force along x", size=0.2, correlates_with="its own past",
                    p_value=1e-3)
    assert u.as_json() == {"where": "force along x", "size": 0.2,
                           "correlates_with": "its own past", "p_value": 1e-3, "test": None}


def test_parts_are_frozen_and_survive_replace_and_pickle():
    d = json.loads((DATA / RECORDED[1]).read_text())
    res = _result_from_json(d)
    parts = [res.base_parameters["m"], res.ranking[0], res.competing[0], res.findings[0],
             res.not_named[0], Unexplained(where="w", size=1.0, correlates_with="c")]
    for p in parts:
        name = dataclasses.fields(p)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(p, name, None)
    with pytest.raises(TypeError):
        res.base_parameters["m"] = ParameterEstimate(1.0, 0.1, 10.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.base_parameters._items = {}
    with pytest.raises(TypeError):
        hash(res.base_parameters["m"])  # like the dict it stands for
    again = dataclasses.replace(res, notes=[])  # converted once, kept as they are
    assert again.base_parameters is res.base_parameters and again.ranking == res.ranking
    back = pickle.loads(pickle.dumps(res))
    assert _dumps(back.as_json()) == _dumps(res.as_json())
    assert back.base_parameters == res.base_parameters


def test_context_reads_as_the_dict_it_replaces():
    """Attributes and keys agree; a field left None is absent (KeyError, ``get`` default) as
    a missing key was; the vocabulary forms read it like the dict; a misspelt key of a dict
    is refused, not dropped."""
    from cdprid.effects import DIAGNOSIS

    axis = np.array([0.0, 0.0, 1.0])
    old = {"rotation_amplitude": 0.02, "rotation_amplitude_std": 0.001, "pulley_axis": axis,
           "finding_floor_N": 0.03, "base_mass_kg": 6.2}
    ctx = DiagnosisContext(**old)
    assert DiagnosisContext.of(old) == ctx and DiagnosisContext.of(ctx) is ctx
    for k, v in old.items():
        assert ctx[k] is getattr(ctx, k) and ctx.get(k) is v and k in ctx
    assert ctx.keys() == list(old)
    v = np.array([0.05])
    for effect in ("rotational_dynamics", "pulley"):
        form = DIAGNOSIS[effect]
        assert form.params(v, ctx) == form.params(v, old)
        if form.interval is not None:
            assert form.interval(v - 0.01, v + 0.01, ctx) == form.interval(v - 0.01, v + 0.01,
                                                                           old)
    part = DiagnosisContext.of({"base_mass_kg": 6.2})
    assert part.get("finding_floor_N", 0.0) == 0.0 == part.finding_floor_N
    assert part.get("pulley_axis", [0, 0, -1]) == [0, 0, -1] and "pulley_axis" not in part
    with pytest.raises(KeyError):
        part["rotation_amplitude"]
    with pytest.raises(TypeError, match="base_mass"):
        DiagnosisContext.of({"base_mass": 6.2})
    with pytest.raises(dataclasses.FrozenInstanceError):
        ctx.base_mass_kg = 1.0


@pytest.mark.slow  # a full diagnosis, ~100 s on 2 cores
def test_a_new_diagnosis_writes_the_recorded_document():
    """The shared delayed-clock dataset diagnosed now gives the recorded document, key for
    key and in order; numbers to 1e-9 relative (another BLAS may differ in the last bits), the
    wall time left out. Recorded by the untyped code (commit 891ad5f); recorded again in
    session 11, when the hysteresis form's new regressor moved its candidates in the first
    step's ranking and the ``unexplained`` stage gained its seventh test (each cell's
    tension-rate sign): the findings and everything else identical to 1e-9."""
    from conftest import shared_dataset

    from cdprid.diagnosis import diagnose
    from cdprid.io import read_dataset

    want = json.loads((DATA / RECORDED[0]).read_text())
    got = json.loads(_dumps(diagnose(read_dataset(shared_dataset("craft-sim-orbits-delay")))
                            .as_json()))
    for d in (want, got):
        d["info"].pop("wall_time_s")

    def same(a, b, where="$"):
        assert type(a) is type(b) or {type(a), type(b)} <= {int, float}, where
        if isinstance(a, dict):
            assert list(a) == list(b), where
            for k in a:
                same(a[k], b[k], f"{where}.{k}")
        elif isinstance(a, list):
            assert len(a) == len(b), where
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                same(x, y, f"{where}[{i}]")
        elif isinstance(a, float):
            assert a == pytest.approx(b, rel=1e-9, abs=1e-12, nan_ok=True), where
        else:
            assert a == b, where
    same(got, want)
