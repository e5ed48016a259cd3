"""The effect vocabulary: one table, validation, and the load-cell friction model."""

from __future__ import annotations

import numpy as np
import pytest

from cdprid.effects import EPISODE_EFFECTS, VOCABULARY, Effect, load_cell_friction, parse_effect


def test_pulley_friction_is_in_the_vocabulary_and_validated():
    assert VOCABULARY["pulley_friction"] == {"cable": "cable", "coulomb_N": "float",
                                             "viscous_Ns_per_m": "float"}
    e = parse_effect("pulley_friction", ["cable=2", "coulomb_N=1.5", "viscous_Ns_per_m=0.3"])
    assert e.params == {"cable": 2, "coulomb_N": 1.5, "viscous_Ns_per_m": 0.3}
    with pytest.raises(ValueError, match="coulomb_N"):
        Effect("pulley_friction", {"cable": 1, "coulomb_N": -1, "viscous_Ns_per_m": 0})


def test_load_cell_friction_opposes_the_cable_motion(rng):
    n, m = 40, 6
    W = rng.normal(size=(n, 6, m))
    v, om = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    e = Effect("pulley_friction", {"cable": 3, "coulomb_N": 2.0, "viscous_Ns_per_m": 5.0})
    f = load_cell_friction([e], W, v, om)
    ldot = np.array([-W[k].T @ np.concatenate([v[k], om[k]]) for k in range(n)])
    assert np.allclose(f[:, [0, 1, 3, 4, 5]], 0.0)
    assert np.allclose(f[:, 2], -2.0 * np.sign(ldot[:, 2]) - 5.0 * ldot[:, 2], atol=1e-12)
    # hauling in (dl/dt < 0): the winch-side cell reads more than the platform side gets
    assert np.all(f[ldot[:, 2] < 0, 2] > 0)


def test_cable_elasticity_is_in_the_vocabulary_and_stretches_the_encoder_reading():
    from cdprid.effects import encoder_lengths

    assert VOCABULARY["cable_elasticity"] == {"cable": "cable", "EA_N": "float"}
    e = parse_effect("cable_elasticity", ["cable=2", "EA_N=2e5"])
    assert e.params == {"cable": 2, "EA_N": 2e5}
    for bad in (0, -1):
        with pytest.raises(ValueError, match="EA_N"):
            Effect("cable_elasticity", {"cable": 1, "EA_N": bad})
    L = np.array([[2.0, 3.0], [2.5, 1.5]])
    tau = np.array([[20.0, 40.0], [10.0, 30.0]])
    out = encoder_lengths([e], L, tau)
    assert np.allclose(out[:, 0], L[:, 0], rtol=0, atol=0)
    # Hooke: the stretched length L is the unstrained one times (1 + tau / EA)
    assert np.allclose(out[:, 1] * (1 + tau[:, 1] / 2e5), L[:, 1], rtol=1e-15)


def test_diagnosis_candidates_and_layout_name_no_effect():
    """Issue 13: the candidates and theta layout read cdprid.effects.DIAGNOSIS only."""
    import ast
    from pathlib import Path

    from cdprid.effects import DIAGNOSIS

    blocks = {b for f in DIAGNOSIS.values() for b, _ in f.blocks}  # theta blocks ("pulley")
    names = (set(VOCABULARY) | set(DIAGNOSIS)) - blocks
    root = Path(__file__).resolve().parents[2] / "src" / "cdprid" / "diagnosis"
    for mod in ("_candidates.py", "_model.py"):
        tree = ast.parse((root / mod).read_text())
        found = {n.value for n in ast.walk(tree)
                 if isinstance(n, ast.Constant) and isinstance(n.value, str)} & names
        assert not found, f"diagnosis/{mod} names effects {sorted(found)}"


def test_diagnosis_forms_are_complete_and_laid_out_once():
    from cdprid.diagnosis import CANDIDATE_EFFECTS, ThetaLayout, candidate_list
    from cdprid.effects import DIAGNOSIS

    # every vocabulary effect but none and cable_elasticity (lengths stream) is a candidate
    # (external_wrench is located in time by the episodes stage, not a candidate)
    assert set(CANDIDATE_EFFECTS) == (set(VOCABULARY) - {"none", "cable_elasticity"}
                                      - EPISODE_EFFECTS)
    for m in (4, 6, 8):
        lay = ThetaLayout(m)
        flip = lay.candidate_indices("pulley_flipped")
        every = set(flip)
        for source in ("tensions", "currents"):
            cands = candidate_list(m, True, None, source=source)
            used = sorted(i for c in cands for i in lay.candidate_indices(c.effect, c.cable))
            # on one stream each theta index belongs to at most one candidate (the no-pulley
            # variant excluded); the drive's forms share the load cell's blocks
            assert len(set(used)) == len(used) and not set(used) & set(flip), source
            every |= set(used)
        assert sorted(every) == list(range(lay.size))  # every index some stream's
        for name, f in DIAGNOSIS.items():
            for key in f.keys:
                assert key in VOCABULARY[f.vocabulary or name], (name, key)


def _effect_name_literals(root) -> list:
    """String literals equal to an effect name in src/ outside the effects package
    ('none' excluded: it also names filters and weightings)."""
    import ast
    from pathlib import Path

    from cdprid.effects import DIAGNOSIS, VOCABULARY

    names = (set(VOCABULARY) | set(DIAGNOSIS)) - {"none"}
    found = []
    for p in sorted(Path(root).rglob("*.py")):
        if "effects" in p.parts:
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Constant) and node.value in names:
                found.append(f"{p.name}:{node.lineno} {node.value!r}")
    return found


def test_no_effect_name_as_a_string_outside_the_effects_package(tmp_path):
    """Issue 22: effects are objects; the simulator and the diagnosis ask the effects
    package (plant_terms, DiagnosisForm flags) instead of testing names."""
    from pathlib import Path

    src = Path(__file__).resolve().parents[2] / "src" / "cdprid"
    assert _effect_name_literals(src) == []
    # the detector can fail
    (tmp_path / "m.py").write_text('if name == "time_delay":\n    pass\n')
    assert _effect_name_literals(tmp_path) == ["m.py:1 'time_delay'"]


def test_plant_terms_read_the_effects():
    from cdprid.effects import Effect, plant_terms

    t = plant_terms([Effect("time_delay", {"delay_s": 0.02}),
                     Effect("cable_mass", {"linear_density_kg_per_m": 0.1}),
                     Effect("cable_elasticity", {"cable": 1, "EA_N": 1e5})])
    assert (t.delay_s, t.rho_kg_per_m, t.drag_Ns_per_m) == (0.02, 0.1, 0.0)
    assert t.encoders and not t.tilted and t.rotation_amplitude_rad == 0.0
    assert plant_terms([]) == type(t)()
