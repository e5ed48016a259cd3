"""One object per effect (issue 36, item 3): each effect module exports one spec, one registry
lists them, and the vocabulary, sensor chain, diagnosis table, validation and docs derive
from it; the refit's ``>= 0`` clamp holds for every diagnosis form."""

from __future__ import annotations

import ast
import dataclasses
import importlib
import re
from pathlib import Path

import numpy as np
import pytest

from cdprid.base import InputError
from cdprid.effects import (
    DIAGNOSIS,
    REGISTRY,
    SENSOR_CHAIN,
    VOCABULARY,
    DiagnosisForm,
    Effect,
    EffectSpec,
    Parameter,
    Place,
    SpecError,
    plant_terms,
    vocabulary_markdown,
)

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "cdprid" / "effects"


def _spec_calls(text: str) -> list:
    """Names assigned an ``EffectSpec(...)`` call at module level (None: not assigned)."""
    out = []
    for node in ast.parse(text).body:
        value = node.value if isinstance(node, ast.Assign | ast.AnnAssign) else None
        for call in ast.walk(node):
            if isinstance(call, ast.Call) and getattr(call.func, "id", None) == "EffectSpec":
                target = node.targets[0] if isinstance(node, ast.Assign) else None
                out.append(target.id if call is value and isinstance(target, ast.Name)
                           else None)
    return out


def _effect_modules(folder) -> dict:
    """Module stem -> names assigned an EffectSpec, for every module that builds one."""
    out = {}
    for path in sorted(Path(folder).glob("_*.py")):
        calls = _spec_calls(path.read_text())
        if calls:
            out[path.stem] = calls
    return out


def test_every_effect_module_has_one_spec_and_the_registry_lists_them_all():
    modules = _effect_modules(PACKAGE)
    assert modules and all(calls == ["SPEC"] for calls in modules.values()), modules
    specs = [importlib.import_module(f"cdprid.effects.{stem}").SPEC for stem in modules]
    assert {id(s) for s in specs} == {id(s) for s in REGISTRY}
    assert len(REGISTRY) == len(modules)
    for stem in modules:  # the module is named after its effect
        assert importlib.import_module(f"cdprid.effects.{stem}").SPEC.name == stem[1:]


def test_the_module_detector_can_fail(tmp_path):
    (tmp_path / "_two.py").write_text("A = EffectSpec(name='a')\nB = EffectSpec(name='b')\n")
    (tmp_path / "_inline.py").write_text("X = (EffectSpec(name='a'),)\n")
    (tmp_path / "_plain.py").write_text("x = 1\n")
    assert _effect_modules(tmp_path) == {"_inline": [None], "_two": ["A", "B"]}


def test_names_are_unique_and_the_tables_follow_the_registry():
    names = [s.name for s in REGISTRY] + [k for s in REGISTRY for k, _ in s.variants]
    assert len(names) == len(set(names))
    assert list(VOCABULARY) == [s.name for s in REGISTRY]
    assert VOCABULARY == {s.name: {p.name: p.kind for p in s.parameters} for s in REGISTRY}
    assert list(DIAGNOSIS) == [k for s in REGISTRY for k in s.forms()]
    for s in REGISTRY:
        for key, _ in s.variants:  # a variant reports its effect
            assert DIAGNOSIS[key].vocabulary == s.name


def test_sensor_chain_is_ordered_by_place_and_the_diagnosis_undoes_it_in_reverse():
    places = {s.name: s.place for s in REGISTRY}
    chain = [name for name, _ in SENSOR_CHAIN]
    assert chain == ["pulley_friction", "load_cell_hysteresis", "tension_gain",
                     "tension_offset", "tension_drift"]
    assert [places[n].value for n in chain] == sorted(places[n].value for n in chain)
    assert {n for n, p in places.items() if p.load_cell} == set(chain)
    undo = [places[f.vocabulary or k].value for k, f in DIAGNOSIS.items()
            if f.tension is not None]
    assert undo == sorted(undo, reverse=True)


def test_a_registry_out_of_physical_order_is_refused():
    from cdprid.effects._registry import _check

    _check(REGISTRY)
    by_name = {s.name: s for s in REGISTRY}
    swapped = [by_name["tension_gain"], by_name["tension_offset"]]
    with pytest.raises(SpecError, match="reverse of the sensor chain"):
        _check(swapped)
    with pytest.raises(SpecError, match="registered twice"):
        _check([by_name["tension_gain"], by_name["tension_gain"]])


def test_docs_effects_md_equals_its_regeneration():
    text = vocabulary_markdown()
    for s in REGISTRY:
        assert f"| `{s.name}` |" in text and f"### ``{s.name}" in text
        for p in s.parameters:
            assert f"| `{s.name}` | `{p.name}` | {p.kind} | {p.unit} | {p.range_text} |" in text
    assert text.count("## Adding an effect") == 1
    doc = ROOT / "docs" / "effects.md"
    assert doc.read_text() == text, "regenerate docs/effects.md with vocabulary_markdown()"


def test_a_new_effect_appears_in_the_docs_by_regeneration_alone(monkeypatch):
    from cdprid.effects import _docs

    probe = EffectSpec(name="probe_effect", parameters=(Parameter("size_N", "float", "N",
                                                                  minimum=0.0),),
                       doc="``probe_effect {size_N}``\n    A probe.", place=Place.PLATFORM)
    monkeypatch.setattr(_docs, "REGISTRY", (*REGISTRY, probe))
    text = _docs.vocabulary_markdown()
    assert "| `probe_effect` | `size_N` (float) | platform |" in text
    assert "| `probe_effect` | `size_N` | float | N | >= 0 |" in text
    assert "### ``probe_effect {size_N}``\n\nA probe." in text


def _valid(spec: EffectSpec) -> dict:
    """A valid value of every parameter (floats increasing, so start_s < end_s)."""
    value = {"cable": 1, "vec3": [0.01, 0.0, -0.02], "vec2": [0.001, -0.002]}
    return {p.name: value.get(p.kind, 1.0 + i) for i, p in enumerate(spec.parameters)}


def _one_sentence(err, *names):
    msg = str(err.value)
    # one line, one full stop at the end, no second sentence
    assert "\n" not in msg and msg.endswith(".") and not re.search(r"\.\s+[A-Z]", msg), msg
    for n in names:
        assert n in msg, (n, msg)


@pytest.mark.parametrize("spec", REGISTRY, ids=lambda s: s.name)
def test_validation_per_effect(spec):
    good = _valid(spec)
    assert Effect(spec.name, good).params == good
    assert Effect(spec.name, {k: str(v).strip("[]") for k, v in good.items()}).params == good
    for p in spec.parameters:
        with pytest.raises(InputError) as err:
            Effect(spec.name, {**good, p.name: "x"})
        _one_sentence(err, f"'{spec.name}'", f"'{p.name}'")
        bad = (0.0 if p.positive else -1.0 if p.minimum == 0 else
               0 if p.kind == "cable" else None)
        if bad is not None:
            with pytest.raises(InputError) as err:
                Effect(spec.name, {**good, p.name: bad})
            _one_sentence(err, f"'{spec.name}'", f"'{p.name}'")
        with pytest.raises(InputError) as err:
            Effect(spec.name, {k: v for k, v in good.items() if k != p.name})
        _one_sentence(err, f"'{spec.name}'", p.name)
    with pytest.raises(InputError) as err:
        Effect(spec.name, {**good, "bogus_N": 1.0})
    _one_sentence(err, f"'{spec.name}'", "'bogus_N'")


def test_validation_is_per_effect_not_per_parameter_name():
    """tension_gain's ``gain`` must be > 0; another effect's parameter of the same name
    follows its own declaration (the old table keyed the rule by the name)."""
    with pytest.raises(InputError, match="'tension_gain' parameter 'gain' must be > 0"):
        Effect("tension_gain", {"cable": 1, "gain": -0.5})
    probe = EffectSpec(name="probe", parameters=(Parameter("gain", "float"),),
                       doc="``probe {gain}``\n    A signed gain.")
    assert probe.validate({"gain": -0.5}) == {"gain": -0.5}
    with pytest.raises(InputError, match="end_s > start_s"):
        Effect("external_wrench", {"start_s": 2.0, "end_s": 1.0, "force_N": [0, 0, 1],
                                   "moment_Nm": [0, 0, 0]})
    with pytest.raises(InputError, match="or all"):
        Effect("pulley_friction", {"cable": 0, "coulomb_N": 1, "viscous_Ns_per_m": 0})
    assert Effect("pulley_friction", {"cable": "all", "coulomb_N": 1,
                                      "viscous_Ns_per_m": 0}).params["cable"] == "all"
    with pytest.raises(InputError, match="cable number 1, 2, ...,"):
        Effect("tension_gain", {"cable": "all", "gain": 1.0})


def test_a_spec_that_reports_an_unknown_parameter_is_refused():
    with pytest.raises(SpecError, match="not one of its parameters"):
        EffectSpec(name="probe", parameters=(Parameter("a_N", "float"),), doc="``probe``",
                   diagnosis=DiagnosisForm(blocks=(("a", 1),), keys=("b_N",)))


# ------------------------------------------------------------------------ the >= 0 clamp


def _clamped(layout, effect, form) -> set:
    idx = set()
    for name in form.nonneg_blocks:
        s = layout.slices[name]
        idx |= set(range(s.start, s.stop))
    return idx


@pytest.mark.parametrize("m", [4, 6, 8])
def test_every_nonneg_parameter_of_every_form_is_clamped(m):
    from cdprid.diagnosis import ThetaLayout

    lay = ThetaLayout(m)
    expect = set()
    for name, form in DIAGNOSIS.items():
        assert len(form.nonneg_blocks) == len(form.nonneg), name
        expect |= _clamped(lay, name, form)
    assert lay.nonneg == expect
    # friction per cable and on all (2 m + 2), drag, two pulley radii, cable density (4), the
    # hysteresis width per cable (m) and the drive's inertia per cable (m; the drive's
    # friction shares the pulley friction's blocks)
    assert len(expect) == 4 * m + 6


def test_the_clamp_holds_for_a_form_that_reports_through_params(monkeypatch):
    """A form whose JSON comes from ``params=`` used to lose its ``>= 0`` clamp silently when
    it gave no ``keys``: the clamp is found through the blocks' JSON names. Now such a form is
    refused at construction, and with its names the layout clamps it."""
    from cdprid.diagnosis import ThetaLayout

    def params(v, extra):
        return {"size_N": float(v[0])}

    with pytest.raises(SpecError, match="one JSON name in keys per theta block"):
        DiagnosisForm(blocks=(("probe", 1),), params=params, nonneg=("size_N",))
    with pytest.raises(SpecError, match="clamp would be lost"):
        DiagnosisForm(blocks=(("probe", 3),), keys=("size_N",), nonneg=("size_N",))
    form = DiagnosisForm(blocks=(("probe", 1),), keys=("size_N",), params=params,
                         nonneg=("size_N",))
    monkeypatch.setitem(DIAGNOSIS, "probe", form)
    lay = ThetaLayout(4)
    assert set(lay.candidate_indices("probe")) <= lay.nonneg
    assert form.nonneg_blocks == ("probe",)


# ------------------------------------------------------------------------ simulation terms


def test_plant_terms_follow_the_specs():
    fields = {f.name for f in dataclasses.fields(type(plant_terms([])))}
    for s in REGISTRY:
        assert {f for f, _ in s.plant} <= fields, s.name
    effects = [Effect(s.name, _valid(s)) for s in REGISTRY if s.plant]
    t = plant_terms(effects)
    for s, e in zip([s for s in REGISTRY if s.plant], effects, strict=True):
        for field, key in s.plant:
            assert getattr(t, field) == e.params[key]
    assert plant_terms([Effect("frame_tilt", {"tilt_rad": [0.01, 0.0]})]).tilted
    assert not plant_terms(effects).encoders


def test_true_robot_and_gravity_apply_the_geometry_and_gravity_terms():
    from cdprid.effects import true_gravity, true_robot
    from cdprid.model import robot_from_dict
    from conftest import ROBOT_CRAFT

    rob = robot_from_dict(ROBOT_CRAFT)
    d = [0.01, -0.02, 0.03]
    out = true_robot(rob, [Effect("exit_point_error", {"cable": 2, "displacement_m": d}),
                           Effect("anchor_point_error", {"cable": 3, "displacement_m": d}),
                           Effect("pulley", {"radius_m": 0.04})])
    assert np.allclose(np.asarray(out.B_A) - np.asarray(rob.B_A),
                       np.eye(rob.n_cables)[:, [1]] * np.array(d), atol=1e-15)
    assert np.allclose(np.asarray(out.P_b) - np.asarray(rob.P_b),
                       np.eye(rob.n_cables)[:, [2]] * np.array(d), atol=1e-15)
    assert np.allclose(out.pulley_radius, 0.04)
    rx, ry = 0.01, -0.02
    g = true_gravity(rob, [Effect("frame_tilt", {"tilt_rad": [rx, ry]})])
    g0 = -np.asarray(rob.gravity)[2]  # g = [0, 0, -g0]: the formula of the docs
    assert np.allclose(g, g0 * np.array([np.sin(ry), -np.sin(rx) * np.cos(ry),
                                         -np.cos(rx) * np.cos(ry)]), atol=1e-14)


# ------------------------------------------------------------------------ the hook context


def test_every_hook_reads_the_typed_context_as_it_reads_the_dict(rng):
    """The per-cable hooks give the same with :class:`CableContext` as with the dict the
    diagnosis builds today (so the diagnosis can pass the typed one)."""
    import jax.numpy as jnp

    from cdprid.effects import CableContext

    blocks = {b: (rng.normal(size=n) * 0.01 if n > 1 else jnp.asarray(0.01 * (i + 1)))
              for i, (b, n) in enumerate(b for f in DIAGNOSIS.values() for b in f.blocks)}
    R = jnp.eye(3)
    fields = dict(at=dict(blocks), taud=jnp.asarray(3.0), ldot=jnp.asarray(-0.2), R=R,
                  p=jnp.array([0.1, 0.2, 1.0]), k=jnp.array([0.0, 0.0, -1.0]),
                  ref=jnp.array([1.0, 0.0, 0.0]), t=jnp.asarray(4.0),
                  slide=jnp.asarray(-0.7), bb=jnp.array([0.05, -0.05, 0.02]),
                  lddot=jnp.asarray(1.3))
    typed = CableContext(**fields)
    geo = {"A": jnp.array([2.0, 1.0, 3.0]), "b": jnp.array([0.05, -0.05, 0.02]),
           "r": jnp.asarray(0.0)}
    q = {k: v * 2 for k, v in blocks.items()}
    hooks = 0
    for form in DIAGNOSIS.values():
        if form.tension is not None:
            assert np.allclose(form.tension(20.0, q, fields), form.tension(20.0, q, typed))
            hooks += 1
        if form.leave is not None:
            T = geo["A"]
            assert np.allclose(form.leave(T, geo, q, fields), form.leave(T, geo, q, typed))
            hooks += 1
    # delay, offset, drift, gain, friction, friction on all, flipped pulley, drive inertia
    assert hooks == 8
    # the typed context is read-only and reports a missing entry as a dict does
    with pytest.raises(dataclasses.FrozenInstanceError):
        typed.ldot = 0.0
    with pytest.raises(KeyError):
        dataclasses.replace(typed, bb=None)["bb"]
    assert dataclasses.replace(typed, slide=None).get("slide", 1.0) == 1.0
