"""Capture what ``cdprid identify --json`` writes on the package's sample dataset.

The fixture ``tests/cli/data/identify_json_contract.json`` holds, per case, the command line,
the recursive key list of the JSON (``a/b/c`` paths, in file order) and the whole JSON. It was
generated on main before the identification results became typed (issue 36, item 4);
``tests/cli/test_identify_json_contract.py`` checks that the JSON keeps the same keys and the
same values (1e-12). Regenerate it only when a change of the numbers is intended:

    python scripts/capture_identify_json.py            # writes the fixture
    python scripts/capture_identify_json.py --check    # compares instead (exit 1 on a change)
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

FIXTURE = Path(__file__).resolve().parents[1] / "tests" / "cli" / "data" / \
    "identify_json_contract.json"

#: name -> arguments after ``cdprid identify DATASET``: the default batch path (full model,
#: errors-in-variables, HAC), the translation model with group weights and i.i.d. std (no
#: ``inertia_about``, no HAC bandwidth), and the full model about G constrained by --physical
#: with ordinary least squares
CASES = {
    "default": [],
    "translation-groups-iid": ["--model", "translation", "--weighting", "groups",
                               "--std", "iid"],
    "full-G-physical-ols": ["--model", "full", "--inertia-about", "G", "--physical",
                            "--weighting", "none"],
}


def key_paths(obj, prefix: str = "") -> list[str]:
    """Every key of ``obj`` as a ``/``-joined path, recursively, in order (list items by index).

    Parameters
    ----------
    obj : dict, list or scalar
        A parsed JSON value.
    prefix : str
        Path of ``obj`` itself.

    Returns
    -------
    list of str
    """
    out = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out.append(f"{prefix}{k}")
            out += key_paths(v, f"{prefix}{k}/")
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += key_paths(v, f"{prefix}{i}/")
    return out


def run_cases(dataset: Path, out_dir: Path) -> dict:
    """``{name: {"argv", "keys", "json"}}`` of :data:`CASES` run on ``dataset``.

    Parameters
    ----------
    dataset : Path
        The sample dataset folder (``cdprid example``).
    out_dir : Path
        Folder for the JSON files the commands write.

    Returns
    -------
    dict
    """
    from cdprid.cli import main

    cases = {}
    for name, extra in CASES.items():
        path = out_dir / f"{name}.json"
        rc = main(["identify", str(dataset), *extra, "--json", str(path), "--force"])
        if rc != 0:
            raise SystemExit(f"cdprid identify {' '.join(extra)} exited {rc}")
        data = json.loads(path.read_text())
        cases[name] = {"argv": extra, "keys": key_paths(data), "json": data}
    return cases


def main(argv=None) -> int:
    """Write (or ``--check``) the fixture; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="compare with the fixture, write nothing")
    args = ap.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    from cdprid.data import write_sample

    with tempfile.TemporaryDirectory() as tmp:
        ds = write_sample(Path(tmp) / "sample-8cable")
        cases = run_cases(ds, Path(tmp))
    doc = {"about": "cdprid identify --json on the package sample dataset (sample-8cable), "
                    "captured by scripts/capture_identify_json.py", "cases": cases}
    if args.check:
        old = json.loads(FIXTURE.read_text())
        same = old["cases"] == cases
        print("same as the fixture" if same else "differs from the fixture")
        return 0 if same else 1
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    FIXTURE.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {FIXTURE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
