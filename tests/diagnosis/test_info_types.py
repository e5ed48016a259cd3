"""The typed ``info`` and ``episodes`` of a diagnosis result (issue 36, item 4).

Oracles: a ``diagnose --json`` document the untyped code wrote (tests/diagnosis/data), whose
``info`` the typed result must write again key by key and in order, and the JSON of
:class:`cdprid.episodes.Episode`.
"""

import dataclasses
import json
from pathlib import Path

import pytest

from cdprid.diagnosis import DiagnosisInfo, DiagnosisResult, EpisodeRecord
from cdprid.episodes import Episode

DATA = Path(__file__).parent / "data"


def _minimal(info, episodes=()):
    return DiagnosisResult({}, [], 1.0, [], {}, 0.8, [], info, episodes=list(episodes))


def test_info_reads_as_its_fields_and_as_the_dict_it_was():
    d = json.loads((DATA / "orbits_delay_diagnosis.json").read_text())
    info = {"information_criterion": d["extended"]["information_criterion"],
            "not_named": d["not_named"], **d["info"], "a_key_of_a_newer_stage": {"x": 1}}
    res = _minimal(info)
    assert isinstance(res.info, DiagnosisInfo)
    out = res.as_json()["info"]
    # every key kept, in the order the diagnosis set them; the two written elsewhere left out
    assert list(out) == [k for k in info if k not in ("information_criterion", "not_named")]
    assert json.dumps(out) == json.dumps({k: v for k, v in info.items()
                                          if k not in ("information_criterion", "not_named")})
    assert res.info.base_model == d["info"]["base_model"] == res.info["base_model"]
    assert res.info.hac_lags == d["info"]["hac_lags"]
    assert res.info.verdict == d["info"].get("verdict")
    assert res.info.details == {"a_key_of_a_newer_stage": {"x": 1}}
    assert res.info.get("no_such_key", 7) == 7 and "heldout" in res.info
    assert res.as_json()["extended"]["information_criterion"] == info["information_criterion"]
    assert [n.as_json() for n in res.not_named] == d["not_named"]
    with pytest.raises(KeyError):
        res.info["no_such_key"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.info.base_model = "full"
    assert res.info == {k: v for k, v in info.items()}  # equal to the dict it stands for


def test_info_by_name_and_empty():
    assert _minimal({}).as_json()["info"] == {}
    i = DiagnosisInfo(base_model="full", hac_lags=12, details={"extra": 1})
    assert i.as_json() == {"base_model": "full", "hac_lags": 12, "extra": 1}
    assert i.n_samples is None and "n_samples" not in i


def test_episodes_typed_from_episodes_and_dicts():
    e = Episode(1.0, 2.5, "external_wrench", (3.0, 0.0, -4.0), (0.0, 0.0, 0.5), 5.0, 0.5,
                1e-9)
    g = Episode(4.0, 4.01, "pose_glitches", None, None, None, None, 0.0,
                {"n_samples": 2, "largest_m": 0.03})
    res = _minimal({}, [e, g.as_json()])
    assert all(isinstance(x, EpisodeRecord) for x in res.episodes)
    a, b = res.episodes
    assert (a.start_s, a.end_s, a.kind, a.size_N) == (1.0, 2.5, "external_wrench", 5.0)
    assert a["force_N"] == [3.0, 0.0, -4.0] and b.details == {"n_samples": 2, "largest_m": 0.03}
    assert b["n_samples"] == 2 and b.get("energy_J") is None
    out = res.as_json()["episodes"]
    assert json.dumps(out) == json.dumps([e.as_json(), g.as_json()])
    # the result pickles and its JSON is plain (what write_json writes)
    assert json.loads(json.dumps(res.as_json()))["episodes"][1]["largest_m"] == 0.03
