"""Measured checks of the package's architecture (issue 13), on the source tree with ``ast``.

Each check lists today's offenders in an explicit allow-list (module:function and the
reason); the lists only shrink: a NEW offender fails the test. An entry that is no longer an
offender does not fail (five helpers convert their modules in parallel and land in any
order); ``python tests/test_architecture.py`` prints the stale entries so that the list is
emptied at the end.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "cdprid"
MAX_FUNCTION_LINES = 80
MAX_MODULE_LINES = 600

# --------------------------------------------------------------------------- allow-lists
# "module:function" -> reason. Empty them as the modules are converted.
ALLOWED_LONG_FUNCTIONS: dict[str, str] = {
}
# "module" -> reason, for modules over MAX_MODULE_LINES lines
ALLOWED_LONG_MODULES: dict[str, str] = {
}
# "importer -> imported:name"
ALLOWED_PRIVATE_IMPORTS: dict[str, str] = {
    "cdprid.identify -> cdprid.identify._online_step:_online_scan":
        "benchmarks/online.py times the scan alone: the face exports the private step for it",
    **{f"cdprid.signal -> cdprid.signal._scan:{n}":
       "benchmarks/differentiators.py times the scan's kernels: the face exports them for it"
       for n in ("_CHANNEL_FNS", "_block_size", "_jax_kernel", "_sharded_kernel")},
    "cdprid.tuning -> cdprid.tuning._tuning:_golden":
        "benchmarks/tuning.py reruns the golden-section step: the face exports it for it",
}
# "importer -> imported" for modules below the CLI layer that import a cli* module
ALLOWED_CLI_IMPORTS: dict[str, str] = {
}
# "importer -> imported" for modules below the report layer that import it
ALLOWED_REPORT_IMPORTS: dict[str, str] = {
}
# test files that import benchmarks/
ALLOWED_BENCHMARK_USERS: dict[str, str] = {
    "test_diagnose.py": "runs benchmarks.diagnosis's run_one/run_case end to end (diag)",
}
# files (a notebook: any of its cells) that change sys.path; the repository root reaches
# benchmarks, studies, replication and tests' helpers as packages (pytest's pythonpath,
# ``python -m benchmarks.x`` from the root)
ALLOWED_SYS_PATH: dict[str, str] = {
    "notebooks/02_paper_replication.ipynb":
        "a notebook's kernel starts in notebooks/: the root is put on the path for replication/",
}
# import cycles as frozensets of module names
ALLOWED_CYCLES: dict[frozenset, str] = {
}
# "importer -> imported" against the layer order (LAYERS below)
ALLOWED_LAYER_VIOLATIONS: dict[str, str] = {
}


# --------------------------------------------------------------------------- the tree


def _module_name(path: Path) -> str:
    rel = path.relative_to(SRC.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_moved_stub(path: Path) -> bool:
    """An old import path kept for one release (``cdprid._moved``): warns and forwards."""
    return "from cdprid._moved import moved" in path.read_text()


def _modules() -> dict[str, tuple[Path, ast.Module]]:
    out = {}
    for p in sorted(SRC.rglob("*.py")):
        if not _is_moved_stub(p):
            out[_module_name(p)] = (p, ast.parse(p.read_text(), filename=str(p)))
    return out


MODULES = _modules()


def _resolve(mod: str, path: Path, node: ast.ImportFrom) -> str:
    if node.level == 0:
        return node.module or ""
    pkg = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
    base = pkg[: len(pkg) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(mod: str) -> list[tuple[str, str | None]]:
    """(imported module, imported name or None) for every import in ``mod`` (any depth)."""
    path, tree = MODULES[mod]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, None) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(mod, path, node)
            for a in node.names:
                sub = f"{target}.{a.name}"
                out.append((sub, None) if sub in MODULES else (target, a.name))
    return [(m, n) for m, n in out if m == "cdprid" or m.startswith("cdprid.")]


def _graph() -> dict[str, set[str]]:
    g = {m: set() for m in MODULES}
    for m in MODULES:
        for dep, _ in _imports(m):
            while dep not in MODULES and "." in dep:
                dep = dep.rsplit(".", 1)[0]
            if dep in MODULES and dep != m and dep != "cdprid":
                g[m].add(dep)
    return g


def _cycles(g: dict[str, set[str]]) -> list[frozenset]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(frozenset(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def _is_cli(mod: str) -> bool:
    last = mod.rsplit(".", 1)[-1]
    return last == "cli" or last.startswith("cli_") or ".cli." in f"{mod}."


def _check(found: dict[str, str], allowed: dict, what: str) -> None:
    new = sorted(set(found) - set(allowed))
    assert not new, f"new {what}: " + "; ".join(f"{k} ({found[k]})" for k in new)


# --------------------------------------------------------------------------- the checks


def test_import_graph_is_built_from_the_tree():
    g = _graph()
    # a known edge of the core path: the check would pass vacuously without it
    assert "cdprid.model" in g["cdprid.core._regression"]
    assert len(g) > 20


def test_no_import_cycle():
    found = {c: ", ".join(sorted(c)) for c in _cycles(_graph())}
    new = [found[c] for c in found if c not in ALLOWED_CYCLES]
    assert not new, f"new import cycle among: {new}"


def test_nothing_below_cli_imports_cli():
    found = {}
    for m, deps in _graph().items():
        if _is_cli(m) or m == "cdprid.__main__":
            continue
        for d in deps:
            if _is_cli(d):
                found[f"{m} -> {d}"] = "library module imports the CLI layer"
    _check(found, ALLOWED_CLI_IMPORTS, "imports of the CLI from below it")


def _is_report(mod: str) -> bool:
    return mod == "cdprid.report" or mod.startswith("cdprid.report.")


def test_io_layer_imports_only_base_model_and_io():
    """io converts formats: it reads the robot model but never calls a feature."""
    bad = {f"{m} -> {d}" for m, deps in _graph().items() if m.startswith("cdprid.io")
           for d in deps if not d.startswith(("cdprid.io", "cdprid.base", "cdprid.model"))}
    assert not bad, f"io modules importing above their layer: {sorted(bad)}"


def test_nothing_below_report_imports_report():
    found = {}
    for m, deps in _graph().items():
        if _is_report(m) or _is_cli(m):
            continue
        for d in deps:
            if _is_report(d):
                found[f"{m} -> {d}"] = "computation layer imports the figure layer"
    _check(found, ALLOWED_REPORT_IMPORTS, "imports of the report layer from below it")


# The layers, in import order: a module imports only from its own layer or an earlier one, and
# the features (identify, diagnosis, excitation, tuning) never import each other. The tree is
# the architecture: ``ls src/cdprid`` shows these subpackages (docs/architecture.md).
LAYERS = [("base",), ("model",), ("io",), ("signal",), ("core",), ("effects",), ("simulation",),
          ("episodes",), ("identify", "diagnosis", "excitation", "tuning"), ("report",), ("cli",)]
OUTSIDE_LAYERS = {"cdprid", "cdprid.__main__", "cdprid.data", "cdprid._moved"}


def _layer(mod: str) -> tuple[int, str]:
    sub = mod.split(".")[1]
    for i, group in enumerate(LAYERS):
        if sub in group:
            return i, sub
    raise AssertionError(f"{mod} is in no layer: add its subpackage to LAYERS")


def test_every_module_is_in_a_layer():
    for m in MODULES:
        if m not in OUTSIDE_LAYERS:
            _layer(m)


def _layer_violations() -> dict[str, str]:
    found = {}
    for m, deps in _graph().items():
        if m in OUTSIDE_LAYERS:
            continue
        (i, sub) = _layer(m)
        for d in deps:
            if d in OUTSIDE_LAYERS:
                continue
            (j, dsub) = _layer(d)
            if j > i:
                found[f"{m} -> {d}"] = f"{sub} imports the later layer {dsub}"
            elif j == i and dsub != sub:
                found[f"{m} -> {d}"] = f"feature {sub} imports feature {dsub}"
    return found


def test_imports_follow_the_layer_order():
    _check(_layer_violations(), ALLOWED_LAYER_VIOLATIONS, "imports against the layer order")


def test_layer_check_can_fail():
    g = {"cdprid.core._motion": {"cdprid.identify._batch"}, "cdprid.identify._batch": set()}
    bad = [f"{m} -> {d}" for m, deps in g.items() for d in deps if _layer(d)[0] > _layer(m)[0]]
    assert bad == ["cdprid.core._motion -> cdprid.identify._batch"]


def test_subpackages_re_export_explicitly():
    """Each layer's ``__init__`` re-exports its public names as ``from ._x import Y as Y``."""
    for group in LAYERS:
        for sub in group:
            init = SRC / sub / "__init__.py"
            assert init.exists(), f"src/cdprid/{sub} is not a package"
            tree = ast.parse(init.read_text())
            froms = [n for n in tree.body if isinstance(n, ast.ImportFrom)]
            assert froms, f"{init}: re-exports nothing"
            for node in froms:
                if node.module != "__future__":
                    for a in node.names:
                        assert a.asname == a.name, \
                            f"{init}:{node.lineno}: '{a.name}' re-exported without 'as {a.name}'"


def test_old_flat_paths_still_import_with_a_warning():
    """``cdprid.geometry`` (flat layout) forwards to ``cdprid.model`` and says so."""
    import importlib
    import sys

    sys.modules.pop("cdprid.geometry", None)
    with pytest.warns(DeprecationWarning, match="cdprid.model"):
        old = importlib.import_module("cdprid.geometry")
    from cdprid.model import CableRobot

    assert old.CableRobot is CableRobot


def test_no_private_name_imported_across_modules():
    found = {}
    for m in MODULES:
        for dep, name in _imports(m):
            # private to a subpackage: its sibling modules may share ``_names`` (equinox style)
            same_pkg = dep.rsplit(".", 1)[0] == m.rsplit(".", 1)[0]
            if name is not None and name.startswith("_") and not name.startswith("__") \
                    and dep != m and not same_pkg:
                found[f"{m} -> {dep}:{name}"] = "private name"
    _check(found, ALLOWED_PRIVATE_IMPORTS, "private names imported across modules")


def _long_functions() -> dict[str, str]:
    found = {}
    for m, (_path, tree) in MODULES.items():
        if _is_cli(m):
            continue
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    found[f"{m}:{node.name}"] = f"{n} lines"
    return found


def test_no_function_over_80_lines_outside_cli():
    _check(_long_functions(), ALLOWED_LONG_FUNCTIONS, f"functions over {MAX_FUNCTION_LINES} lines")


def _long_modules() -> dict[str, str]:
    found = {}
    for m, (path, _tree) in MODULES.items():
        n = len(path.read_text().splitlines())
        if n > MAX_MODULE_LINES:
            found[m] = f"{n} lines"
    return found


def test_no_module_over_600_lines():
    """Issue 22: every module of src/ (the CLI's too) stays under 600 lines."""
    _check(_long_modules(), ALLOWED_LONG_MODULES, f"modules over {MAX_MODULE_LINES} lines")


def _benchmark_users() -> dict[str, str]:
    """Test files that import ``benchmarks`` or name the folder in a string (sys.path)."""
    found = {}
    for p in sorted((ROOT / "tests").rglob("test_*.py")):
        if p.name == Path(__file__).name:
            continue
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                names = [node.value.strip("/")]
            else:
                continue
            if any(n.split(".")[0] == "benchmarks" for n in names):
                found[p.name] = "imports benchmarks/"
    return found


def test_tests_do_not_import_benchmarks():
    _check(_benchmark_users(), ALLOWED_BENCHMARK_USERS, "tests that import benchmarks/")


@pytest.mark.parametrize("source, expected", [
    ("def f():\n" + "    x = 1\n" * 130, 1),
    ("def f():\n" + "    x = 1\n" * 80, 1),
    ("def f():\n" + "    x = 1\n" * 79, 0),
    ("def f():\n" + "    x = 1\n" * 10, 0),
])
def test_long_function_detector_can_fail(source, expected):
    tree = ast.parse(source)
    n = sum(1 for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)
            and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES)
    assert n == expected


def test_cycle_detector_can_fail():
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [frozenset({"a", "b"})]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def _stale() -> list[str]:
    """Allow-list entries that are no longer offenders (to delete)."""
    g = _graph()
    cycles = set(_cycles(g))
    long = _long_functions()
    priv = {f"{m} -> {d}:{n}" for m in MODULES for d, n in _imports(m)
            if n is not None and n.startswith("_") and not n.startswith("__")}
    cli = {f"{m} -> {d}" for m, ds in g.items() for d in ds if not _is_cli(m) and _is_cli(d)}
    return ([k for k in ALLOWED_LONG_FUNCTIONS if k not in long]
            + [k for k in ALLOWED_LONG_MODULES if k not in _long_modules()]
            + [k for k in ALLOWED_PRIVATE_IMPORTS if k not in priv]
            + [k for k in ALLOWED_CLI_IMPORTS if k not in cli]
            + [k for k in ALLOWED_REPORT_IMPORTS
               if k.split(" -> ")[1] not in g.get(k.split(" -> ")[0], set())]
            + [k for k in ALLOWED_BENCHMARK_USERS if k not in _benchmark_users()]
            + [k for k in ALLOWED_SYS_PATH if k not in _sys_path_users()]
            + [", ".join(sorted(c)) for c in ALLOWED_CYCLES if c not in cycles])


def test_architecture_doc_tree_is_current():
    """docs/architecture.md's tree section is generated from src/ (scripts/architecture_doc.py)."""
    import subprocess
    import sys

    script = ROOT / "scripts" / "architecture_doc.py"
    proc = subprocess.run([sys.executable, str(script), "--check"])
    assert proc.returncode == 0, "docs/architecture.md is stale: run scripts/architecture_doc.py"


def test_validation_raises_typed_user_errors():
    """User mistakes are raised as ``InputError`` (a ``UserError``), so the CLI decides exit 2
    vs 1 by type: no ``raise ValueError`` in src (issue 22)."""
    found = {}
    for m, (_path, tree) in MODULES.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.Raise) and isinstance(node.exc, ast.Call) \
                    and getattr(node.exc.func, "id", None) == "ValueError":
                found[f"{m}:{node.lineno}"] = "raise ValueError"
    assert not found, f"raise InputError (cdprid.base) instead: {sorted(found)}"


# --------------------------------------------------------------------------- faces (issue 36)
# The rule: an import that crosses a subpackage goes through its face (``from cdprid.model
# import CableRobot``), in src/, benchmarks/, replication/, scripts/ and notebooks/. A test in
# ``tests/<sub>/`` may import ``cdprid.<sub>._x`` (the subpackage it tests: private helpers,
# monkeypatching); every other test goes through the faces too.
OUTSIDE_SRC = ("tests", "benchmarks", "studies", "replication", "scripts")


def _code_files() -> list[tuple[str, str]]:
    """(path relative to the repo, Python source) of every file the rule covers."""
    import json

    out = [(str(p.relative_to(ROOT)), p.read_text()) for p in sorted(SRC.rglob("*.py"))]
    for top in OUTSIDE_SRC:
        out += [(str(p.relative_to(ROOT)), p.read_text())
                for p in sorted((ROOT / top).rglob("*.py"))]
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        for i, cell in enumerate(json.loads(nb.read_text())["cells"]):
            if cell["cell_type"] == "code":
                src = "".join(cell["source"])
                src = "\n".join("" if line.lstrip().startswith(("%", "!")) else line
                                 for line in src.split("\n"))
                out.append((f"{nb.relative_to(ROOT)}[cell {i}]", src))
    return out


def _owner(rel: str) -> str | None:
    """The subpackage a file belongs to: ``src/cdprid/<sub>/...`` or ``tests/<sub>/...``."""
    parts = Path(rel.split("[")[0]).parts
    if parts[:2] == ("src", "cdprid") and len(parts) > 3:
        return parts[2]
    if parts[0] == "tests" and len(parts) > 2:
        return parts[1]
    return None


def _private_targets(node: ast.AST) -> list[str]:
    """The ``cdprid.<sub>._x`` modules an import statement reaches (absolute imports)."""
    names = []
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
        names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
    out = []
    for n in names:
        parts = n.split(".")
        if len(parts) >= 3 and parts[0] == "cdprid" and parts[2].startswith("_") \
                and not parts[2].startswith("__") \
                and (SRC / parts[1] / f"{parts[2]}.py").is_file():
            out.append(".".join(parts[:3]))
    return out


def _face_offenders(files) -> list[str]:
    found = []
    for rel, src in files:
        own = _owner(rel)
        for node in ast.walk(ast.parse(src)):
            for target in _private_targets(node):
                if target.split(".")[1] != own:
                    found.append(f"{rel}:{node.lineno}: {target}")
    return sorted(set(found))


def test_imports_across_subpackages_go_through_the_faces():
    bad = _face_offenders(_code_files())
    assert not bad, "import through the package face (from cdprid.<sub> import X), not its " \
        "private module:\n" + "\n".join(bad)


def test_face_check_can_fail():
    files = [("src/cdprid/core/_x.py", "from cdprid.model._geometry import CableRobot\n"),
             ("src/cdprid/core/_y.py", "from cdprid.core._motion import Motion\n"),
             ("tests/core/test_x.py", "import cdprid.core._motion as M\n"),
             ("tests/io/test_y.py", "from cdprid.core import _motion\n"),
             ("benchmarks/b.py", "def f():\n    from cdprid.model import CableRobot\n")]
    assert _face_offenders(files) == ["src/cdprid/core/_x.py:1: cdprid.model._geometry",
                                      "tests/io/test_y.py:1: cdprid.core._motion"]


def test_every_module_of_a_subpackage_is_private():
    """``io/_dataset.py``, never ``io/dataset.py``; an old path kept for one release is a stub
    (``cdprid._moved``) that only warns and forwards."""
    bad = []
    for group in LAYERS:
        for sub in group:
            for p in sorted((SRC / sub).glob("*.py")):
                if p.name.startswith("_"):
                    continue
                tree = ast.parse(p.read_text())
                stub = _is_moved_stub(p) and len(tree.body) == 3
                if not stub:
                    bad.append(f"{p.relative_to(ROOT)}:1: public module name")
    assert not bad, "rename to _name.py:\n" + "\n".join(bad)


def test_package_init_swaps_no_class_and_hooks_no_import():
    """``import cdprid`` installs no ``sys.meta_path`` finder and swaps no module class."""
    init = SRC / "__init__.py"
    bad = []
    for node in ast.walk(ast.parse(init.read_text())):
        if isinstance(node, ast.Attribute) and node.attr in ("meta_path", "path_hooks",
                                                             "__class__"):
            bad.append(f"{init.relative_to(ROOT)}:{node.lineno}: {node.attr}")
        if isinstance(node, ast.ClassDef):
            bad.append(f"{init.relative_to(ROOT)}:{node.lineno}: class {node.name}")
    assert not bad, "\n".join(bad)


def test_old_module_paths_warn_and_forward():
    """``cdprid.io.dataset`` (public module name before issue 36) forwards to ``cdprid.io``."""
    import importlib
    import sys

    sys.modules.pop("cdprid.io.dataset", None)
    with pytest.warns(DeprecationWarning, match="import from cdprid.io"):
        old = importlib.import_module("cdprid.io.dataset")
    from cdprid.io import read_dataset

    assert old.read_dataset is read_dataset


# ------------------------------------------------------------------- the diagnosis on the core
# Issue 36 item 2: the diagnosis derives nothing the core owns. Its motion, tension
# interpolation, noise levels, rest rule and friction sign are the core's, called by name; it
# may import the matched filter from cdprid.signal, never a differentiator.
DIAGNOSIS_SIGNAL_NAMES = {"zero_phase_filter", "make_zero_phase_filter", "ZeroPhaseFilter"}
DIAGNOSIS_CORE_NAMES = {"estimate_motion", "differentiate_pose", "tension_at", "tension_rate_at",
                        "TensionStream", "estimate_noise", "rest_mask", "sliding_sign"}
_OWN_ESTIMATOR_DEF = ("differentiat", "derivative", "interp", "catmull", "tension_at",
                      "tension_rate", "estimate_noise", "rest_mask", "sliding")
_OWN_ESTIMATOR_CALLS = {"gradient", "convolve", "interp", "minimum_filter1d", "binary_erosion",
                        "CubicSpline", "savgol_filter", "differentiate"}
# "file: what" -> reason (no line number: the other stages' edits move lines)
ALLOWED_DIAGNOSIS_ESTIMATORS: dict[str, str] = {
    "src/cdprid/diagnosis/_lengths.py: calls interp":
        "the winch-encoder lengths onto the pose times (lengths.csv is no tension stream); "
        "to move to the core with the lengths stream",
}


def _attr_name(func: ast.AST) -> str:
    return func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")


def _diff_order(call: ast.Call) -> int:
    n = [k.value for k in call.keywords if k.arg == "n"] + call.args[1:2]
    return n[0].value if n and isinstance(n[0], ast.Constant) else 1


def _own_estimators(files) -> list[str]:
    """What a diagnosis source derives by itself: differentiators or filters imported from
    cdprid.signal, functions named like an estimator, finite differences of order >= 2, an
    interpolation or convolution, a speed threshold on a norm, a MAD noise constant."""
    found = []
    for rel, src in files:
        for node in ast.walk(ast.parse(src)):
            where = f"{rel}:{getattr(node, 'lineno', 0)}:"
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("cdprid.signal"):
                found += [f"{where} imports {a.name} from cdprid.signal" for a in node.names
                          if a.name not in DIAGNOSIS_SIGNAL_NAMES]
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) \
                    and any(k in node.name.lower() for k in _OWN_ESTIMATOR_DEF):
                found.append(f"{where} defines {node.name}")
            elif isinstance(node, ast.Call):
                name = _attr_name(node.func)
                if name in _OWN_ESTIMATOR_CALLS:
                    found.append(f"{where} calls {name}")
                elif name == "diff" and _diff_order(node) >= 2:
                    found.append(f"{where} calls diff of order {_diff_order(node)}")
            elif isinstance(node, ast.Compare) and isinstance(node.left, ast.Call) \
                    and _attr_name(node.left.func) == "norm" \
                    and any(isinstance(op, ast.Lt | ast.LtE) for op in node.ops):
                found.append(f"{where} thresholds a norm (a rest rule)")
            elif isinstance(node, ast.Constant) and node.value == 1.4826:
                found.append(f"{where} MAD constant (a noise estimate)")
    return sorted(set(found))


def _diagnosis_files() -> list[tuple[str, str]]:
    return [(str(p.relative_to(ROOT)), p.read_text())
            for p in sorted((SRC / "diagnosis").glob("*.py")) if not _is_moved_stub(p)]


def test_diagnosis_derives_nothing_the_core_owns():
    found = {}
    for k in _own_estimators(_diagnosis_files()):
        path, line, what = k.split(":", 2)
        found[f"{path}:{what}"] = f"line {line}"
    _check(found, ALLOWED_DIAGNOSIS_ESTIMATORS,
           "estimators of the diagnosis' own (use cdprid.core's by name)")


def test_diagnosis_uses_the_core_estimators_by_name():
    """Motion, tension interpolation, noise, rest rule and friction sign come from cdprid.core."""
    used = set()
    for _rel, src in _diagnosis_files():
        for node in ast.walk(ast.parse(src)):
            if isinstance(node, ast.ImportFrom) and node.module == "cdprid.core":
                used |= {a.name for a in node.names}
    assert not DIAGNOSIS_CORE_NAMES - used, \
        f"the diagnosis does not import {sorted(DIAGNOSIS_CORE_NAMES - used)} from cdprid.core"


def test_own_estimator_check_can_fail():
    files = [("d/_a.py", "from cdprid.signal import differentiate, zero_phase_filter\n"),
             ("d/_b.py", "def tension_at(d, s):\n    return s\n"),
             ("d/_c.py", "import numpy as np\nx = np.diff(y, 3, axis=0)\nz = np.diff(y)\n"),
             ("d/_d.py", "import numpy as np\nr = np.linalg.norm(v, axis=1) < 0.03\n"),
             ("d/_e.py", "s = 1.4826 * mad\nq = np.interp(t, tt, y)\n"),
             ("d/_f.py", "from cdprid.core import tension_at\nv = tension_at(st, t)\n")]
    assert _own_estimators(files) == [
        "d/_a.py:1: imports differentiate from cdprid.signal", "d/_b.py:1: defines tension_at",
        "d/_c.py:2: calls diff of order 3", "d/_d.py:2: thresholds a norm (a rest rule)",
        "d/_e.py:1: MAD constant (a noise estimate)", "d/_e.py:2: calls interp"]


# --------------------------------------------------------------------------- sys.path


def _changes_sys_path(source: str) -> bool:
    """Whether ``source`` calls ``sys.path.insert/append/extend`` or assigns to ``sys.path``."""
    def is_sys_path(node) -> bool:
        return (isinstance(node, ast.Attribute) and node.attr == "path"
                and isinstance(node.value, ast.Name) and node.value.id == "sys")

    for node in ast.walk(ast.parse(source)):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
                and node.func.attr in ("insert", "append", "extend")
                and is_sys_path(node.func.value)):
            return True
        targets = (node.targets if isinstance(node, ast.Assign)
                   else [node.target] if isinstance(node, ast.AugAssign) else [])
        for tg in targets:
            if is_sys_path(tg) or (isinstance(tg, ast.Subscript) and is_sys_path(tg.value)):
                return True
    return False


def _sys_path_users() -> dict[str, str]:
    """Files of src/, tests/, benchmarks/, studies/, replication/, scripts/ and notebooks/
    (a notebook by file) that change ``sys.path``."""
    return {rel.split("[")[0]: "changes sys.path" for rel, src in _code_files()
            if rel != str(Path(__file__).relative_to(ROOT)) and _changes_sys_path(src)}


@pytest.mark.parametrize("source, expected", [
    ("import sys\nsys.path.insert(0, 'x')\n", True),
    ("import sys\ndef f():\n    sys.path.append('x')\n", True),
    ("import sys\nsys.path[:0] = ['x']\n", True),
    ("import sys\nsys.path += ['x']\n", True),
    ("import sys\nprint(sys.path)\nx = 'sys.path.insert(0, y)'\n", False),
])
def test_sys_path_detector(source, expected):
    assert _changes_sys_path(source) is expected


def test_no_sys_path_changes():
    """Issue 36: benchmarks, studies, replication and shared test helpers are packages reached
    from the repository root (pytest's ``pythonpath = ["."]``, ``python -m benchmarks.x``)."""
    found = _sys_path_users()
    _check(found, ALLOWED_SYS_PATH, "files that change sys.path")


if __name__ == "__main__":
    print("\n".join(_stale()) or "no stale allow-list entry")
