"""``cdprid identify --json`` keeps its contract while the results became typed (issue 36).

The fixture (tests/cli/data/identify_json_contract.json) was written on main before the change by
``scripts/capture_identify_json.py``: per case the command line, the JSON's recursive key list
and the JSON. Each case is run again here on the package's sample dataset; the keys must be the
same in the same order and every value the same (numbers to 1e-9 relative, strings exactly: a
run on a loaded machine gave a HAC bandwidth 1.03e-12 from the captured value, rounding in
XLA's reductions, never a change of the computation).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

FIXTURE = Path(__file__).parent / "data" / "identify_json_contract.json"
CAPTURED = json.loads(FIXTURE.read_text())["cases"]


def key_paths(obj, prefix: str = "") -> list[str]:
    """Every key of a parsed JSON value as a ``/``-joined path, in order (lists by index)."""
    out = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += [f"{prefix}{k}", *key_paths(v, f"{prefix}{k}/")]
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += key_paths(v, f"{prefix}{i}/")
    return out


def differences(new, old, path: str = "", rtol: float = 1e-9) -> list[str]:
    """Where two parsed JSON values differ: types, keys, lengths, strings, or numbers beyond
    ``rtol`` (relative, absolute below 1e-300); an empty list when they agree."""
    if isinstance(old, dict) and isinstance(new, dict):
        if list(new) != list(old):
            return [f"{path}: keys {list(new)} != {list(old)}"]
        return [d for k in old for d in differences(new[k], old[k], f"{path}/{k}", rtol)]
    if isinstance(old, list) and isinstance(new, list):
        if len(new) != len(old):
            return [f"{path}: {len(new)} items != {len(old)}"]
        return [d for i, (a, b) in enumerate(zip(new, old, strict=True))
                for d in differences(a, b, f"{path}/{i}", rtol)]
    if isinstance(old, bool) or isinstance(new, bool) or old is None or new is None \
            or isinstance(old, str) or isinstance(new, str):
        return [] if type(new) is type(old) and new == old else [f"{path}: {new!r} != {old!r}"]
    if isinstance(old, (int, float)) and isinstance(new, (int, float)):
        if type(new) is not type(old):
            return [f"{path}: {type(new).__name__} != {type(old).__name__}"]
        if math.isnan(old) and math.isnan(new) or new == old:
            return []
        if abs(new - old) <= rtol * max(abs(old), 1e-300):
            return []
        return [f"{path}: {new!r} != {old!r}"]
    return [f"{path}: {type(new).__name__} != {type(old).__name__}"]


@pytest.fixture(scope="module")
def sample(tmp_path_factory):
    """The package's sample dataset (8 cables, rotating; the one the fixture was captured on)."""
    from cdprid.data import write_sample

    return write_sample(tmp_path_factory.mktemp("contract") / "sample-8cable")


@pytest.mark.parametrize("case", sorted(CAPTURED))
def test_identify_json_keeps_keys_and_values(case, sample, tmp_path):
    from cdprid.cli import main

    out = tmp_path / "out.json"
    argv = CAPTURED[case]["argv"]
    assert main(["identify", str(sample), *argv, "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert key_paths(data) == CAPTURED[case]["keys"]
    assert differences(data, CAPTURED[case]["json"]) == []


def test_the_comparison_can_fail():
    """The checks above see a renamed key, a moved key, a changed number and a changed type."""
    old = CAPTURED["default"]["json"]
    renamed = {("parameters_" if k == "parameters" else k): v for k, v in old.items()}
    assert key_paths(renamed) != CAPTURED["default"]["keys"]
    moved = dict(reversed(list(old.items())))
    assert key_paths(moved) != CAPTURED["default"]["keys"]
    changed = json.loads(json.dumps(old))
    changed["parameters"]["m"]["value"] *= 1 + 1e-8
    new_m, old_m = changed["parameters"]["m"]["value"], old["parameters"]["m"]["value"]
    assert differences(changed, old) == [f"/parameters/m/value: {new_m!r} != {old_m!r}"]
    changed["parameters"]["m"]["value"] = old["parameters"]["m"]["value"]
    changed["n_samples"] = float(changed["n_samples"])
    assert differences(changed, old) == ["/n_samples: float != int"]
    assert differences(old, old) == []
