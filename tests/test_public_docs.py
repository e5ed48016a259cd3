"""Every name a package face exports carries a numpydoc docstring (project standard).

For each package in ``DOCUMENTED`` the test walks the names its face
(``src/cdprid/<pkg>/__init__.py``) re-exports: functions, classes and the classes' public
methods (static and class methods too; properties are attributes, not checked). It reads
the source with ``ast`` (nothing is imported: the test takes well under a second). A
function or method fails when its docstring

- is missing,
- takes arguments (other than ``self``/``cls``) but has no ``Parameters`` section, or a
  parameter that the section does not name,
- returns something (a return annotation other than ``None``, or, unannotated, a
  ``return <value>`` in its own body) but has no ``Returns`` section (``Yields`` for a
  generator).

A class fails when it has no docstring. A name a face re-exports from another package (the
identify face exports core's guards) is checked with the package that defines it.

Every package is listed; the list only grows.
``python tests/test_public_docs.py [pkg ...]`` prints the offenders of any package, listed
or not.
"""

from __future__ import annotations

import ast
import functools
import re
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

DOCUMENTED = ("base", "model", "io", "identify", "excitation", "tuning", "report", "cli",
              "simulation", "signal", "core", "episodes", "diagnosis", "effects")

_SECTION = re.compile(r"^(\w[\w ]*)\n-{3,}\s*$", re.MULTILINE)
_NAMES = re.compile(r"^(\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)*)\s*(?::|$)", re.MULTILINE)
_FUNC = ast.FunctionDef | ast.AsyncFunctionDef


def _sections(doc: str) -> dict[str, str]:
    """The numpydoc sections of a docstring, by title, each its body text."""
    heads = list(_SECTION.finditer(doc))
    out = {}
    for i, h in enumerate(heads):
        end = heads[i + 1].start() if i + 1 < len(heads) else len(doc)
        out[h.group(1).strip()] = doc[h.end():end]
    return out


def _own_body_returns(fn) -> tuple[bool, bool]:
    """(returns a value, yields) from the function's own body, nested defs excluded."""
    returns = yields = False
    stack = list(fn.body)
    while stack:
        node = stack.pop()
        if isinstance(node, _FUNC | ast.Lambda | ast.ClassDef):
            continue
        if isinstance(node, ast.Return) and node.value is not None and not (
                isinstance(node.value, ast.Constant) and node.value.value is None):
            returns = True
        if isinstance(node, ast.Yield | ast.YieldFrom):
            yields = True
        stack.extend(ast.iter_child_nodes(node))
    return returns, yields


def _returns_none(ann) -> bool:
    return (isinstance(ann, ast.Constant) and ann.value in (None, "None")) or (
        isinstance(ann, ast.Name) and ann.id == "None")


def _function_problems(fn) -> list[str]:
    """What the docstring of the function node ``fn`` lacks ([] when nothing)."""
    doc = ast.get_docstring(fn) or ""
    if not doc.strip():
        return ["no docstring"]
    sec = _sections(doc)
    problems = []
    a = fn.args
    params = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    params += [p.arg for p in (a.vararg, a.kwarg) if p is not None]
    params = [p for p in params if p not in ("self", "cls")]
    if params:
        body = sec.get("Parameters")
        if body is None:
            problems.append("no Parameters section")
        else:
            named = {n.strip().lstrip("*") for line in _NAMES.findall(body)
                     for n in line.split(",")}
            missing = [p for p in params if p not in named]
            if missing:
                problems.append(f"Parameters does not name {', '.join(missing)}")
    returns, yields = _own_body_returns(fn)
    if fn.returns is not None and not _returns_none(fn.returns):
        returns = True
    if yields and "Yields" not in sec and "Returns" not in sec:
        problems.append("no Yields section")
    elif returns and not yields and "Returns" not in sec:
        problems.append("no Returns section")
    return problems


def _is_property(fn) -> bool:
    for d in fn.decorator_list:
        name = d.attr if isinstance(d, ast.Attribute) else getattr(d, "id", "")
        if name in ("property", "cached_property", "setter", "getter", "deleter"):
            return True
    return False


@functools.cache
def _module(name: str):
    """The parsed module ``cdprid.x._y`` (a package's ``__init__.py`` for ``cdprid.x``)."""
    path = SRC / Path(*name.split("."))
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    return ast.parse(path.read_text(encoding="utf-8"))


def _definition(pkg: str, module: str, name: str, depth: int = 0):
    """The def/class node of ``name`` in ``module``, following imports inside ``pkg``; None
    for a constant, an assignment or a name from another package."""
    tree = _module(module)
    for node in tree.body:
        if isinstance(node, _FUNC | ast.ClassDef) and node.name == name:
            return node
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.level == 0 and depth < 5:
            for alias in node.names:
                if (alias.asname or alias.name) == name:
                    if node.module.startswith(f"cdprid.{pkg}."):
                        return _definition(pkg, node.module, alias.name, depth + 1)
                    return None
    return None


def _face_members(pkg: str):
    """(name, node) for each function, class and public method the face re-exports."""
    for node in _module(f"cdprid.{pkg}").body:
        if not (isinstance(node, ast.ImportFrom) and node.module
                and node.module.startswith(f"cdprid.{pkg}.")):
            continue  # a re-export from another package is checked there
        for alias in node.names:
            public = alias.asname or alias.name
            if public.startswith("_"):
                continue
            obj = _definition(pkg, node.module, alias.name)
            if obj is None:
                continue
            yield public, obj
            if isinstance(obj, ast.ClassDef):
                for m in obj.body:
                    if isinstance(m, _FUNC) and not m.name.startswith("_") \
                            and not _is_property(m):
                        yield f"{public}.{m.name}", m


def offenders(pkg: str) -> list[str]:
    """Face members of ``cdprid.<pkg>`` whose docstring breaks the standard.

    Parameters
    ----------
    pkg : str
        Subpackage name, e.g. ``"model"``.

    Returns
    -------
    list of str
        ``"name: problem; problem"`` per offending function, method or class.
    """
    out = []
    for name, node in _face_members(pkg):
        if isinstance(node, ast.ClassDef):
            problems = [] if (ast.get_docstring(node) or "").strip() else ["no docstring"]
        else:
            problems = _function_problems(node)
        if problems:
            out.append(f"{name}: {'; '.join(problems)}")
    return sorted(out)


def test_face_exports_carry_numpydoc():
    bad = {pkg: offenders(pkg) for pkg in DOCUMENTED}
    lines = [f"cdprid.{pkg}.{o}" for pkg, v in bad.items() for o in v]
    assert not lines, "face exports without numpydoc Parameters/Returns:\n" + "\n".join(lines)


def test_every_documented_face_has_members():
    """The walk finds what each face exports (an empty walk would pass vacuously)."""
    counts = {pkg: sum(1 for _ in _face_members(pkg)) for pkg in DOCUMENTED}
    assert all(n > 0 for n in counts.values()), counts
    assert counts["model"] > 40 and counts["excitation"] > 40 and counts["core"] > 80, counts


_SAMPLE = '''
def f(x, y):
    """One line only."""
    return x + y


def g(x: float) -> float:
    """Half.

    Parameters
    ----------
    x : float
        Value.

    Returns
    -------
    float
        ``x / 2``.
    """
    return x / 2


def h(x, y, *args, **kw):
    """Sum.

    Parameters
    ----------
    x, args : float
        Value.
    **kw
        Options.
    """
    print(x + y)


def k():
    """Yield.

    Returns
    -------
    nothing
    """
    def inner():
        return 1
    yield 1
'''


def test_checker_catches_missing_sections():
    """The checker itself fails a stripped docstring (the test can fail)."""
    fns = {n.name: n for n in ast.parse(_SAMPLE).body}
    assert _function_problems(fns["f"]) == ["no Parameters section", "no Returns section"]
    assert _function_problems(fns["g"]) == []
    assert _function_problems(fns["h"]) == ["Parameters does not name y"]
    assert _function_problems(fns["k"]) == []  # a Returns section also covers a generator


if __name__ == "__main__":
    for p in sys.argv[1:] or DOCUMENTED:
        off = offenders(p)
        print(f"== {p}: {len(off)} offenders")
        for o in off:
            print("  ", o)
