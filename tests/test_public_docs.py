"""Every name a package face exports carries a numpydoc docstring (project standard).

For each package in ``DOCUMENTED`` the test walks the names its face (``cdprid.<pkg>``)
exports: functions, classes and the classes' public methods (static and class methods too).
A function or method fails when its docstring

- is missing,
- takes arguments (other than ``self``/``cls``) but has no ``Parameters`` section, or a
  parameter that the section does not name,
- returns something (a return annotation other than ``None``, or, unannotated, a
  ``return <value>`` in its own body) but has no ``Returns`` section (``Yields`` for a
  generator).

A class fails when it has no docstring. A name a face re-exports from another package (the
identify face exports core's guards) is checked with the package that defines it. The packages not yet listed (``core``, ``signal``,
``diagnosis``, ``episodes``, ``effects``) are to be added to ``DOCUMENTED`` once their
faces are documented; the list only grows. ``python tests/test_public_docs.py [pkg ...]``
prints the offenders of any package, listed or not.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import sys
import textwrap

DOCUMENTED = ("base", "model", "io", "identify",
              )

_SECTION = re.compile(r"^(\w[\w ]*)\n-{3,}\s*$", re.MULTILINE)


def _sections(doc: str) -> dict[str, str]:
    """The numpydoc sections of a docstring, by title, each its body text."""
    heads = list(_SECTION.finditer(doc))
    out = {}
    for i, h in enumerate(heads):
        end = heads[i + 1].start() if i + 1 < len(heads) else len(doc)
        out[h.group(1).strip()] = doc[h.end():end]
    return out


def _own_body_returns(func) -> tuple[bool, bool]:
    """(returns a value, yields) from the function's own body, nested defs excluded."""
    try:
        src = textwrap.dedent(inspect.getsource(func))
    except (OSError, TypeError):
        return False, False
    tree = ast.parse(src)
    fn = tree.body[0]
    returns = yields = False
    stack = list(fn.body) if isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef) else []
    while stack:
        node = stack.pop()
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda | ast.ClassDef):
            continue
        if isinstance(node, ast.Return) and node.value is not None and not (
                isinstance(node.value, ast.Constant) and node.value.value is None):
            returns = True
        if isinstance(node, ast.Yield | ast.YieldFrom):
            yields = True
        stack.extend(ast.iter_child_nodes(node))
    return returns, yields


def _function_problems(func) -> list[str]:
    doc = inspect.getdoc(func) or ""
    if not doc.strip():
        return ["no docstring"]
    sec = _sections(doc)
    problems = []
    sig = inspect.signature(func)
    params = [p for p in sig.parameters.values() if p.name not in ("self", "cls")]
    if params:
        body = sec.get("Parameters")
        if body is None:
            problems.append("no Parameters section")
        else:
            named = {n.strip().lstrip("*") for line in re.findall(
                r"^(\*{0,2}\w+(?:\s*,\s*\*{0,2}\w+)*)\s*(?::|$)", body, re.MULTILINE)
                for n in line.split(",")}
            missing = [p.name for p in params if p.name not in named]
            if missing:
                problems.append(f"Parameters does not name {', '.join(missing)}")
    ann = sig.return_annotation
    returns, yields = _own_body_returns(func)
    if ann is not inspect.Signature.empty:
        returns = ann not in (None, "None") or returns
    if yields and "Yields" not in sec and "Returns" not in sec:
        problems.append("no Yields section")
    elif returns and not yields and "Returns" not in sec:
        problems.append("no Returns section")
    return problems


def _face_members(pkg: str):
    """(name, object) for each function, class and public method the face exports."""
    face = importlib.import_module(f"cdprid.{pkg}")
    for name in sorted(dir(face)):
        if name.startswith("_"):
            continue
        obj = getattr(face, name)
        home = getattr(obj, "__module__", "") or ""
        if home != f"cdprid.{pkg}" and not home.startswith(f"cdprid.{pkg}."):
            continue  # a re-export is checked with the package that defines it
        if inspect.isfunction(obj):
            yield name, obj
        elif inspect.isclass(obj):
            yield name, obj
            for k, v in vars(obj).items():
                if k.startswith("_"):
                    continue
                if isinstance(v, staticmethod | classmethod):
                    v = v.__func__
                if inspect.isfunction(v):
                    yield f"{name}.{k}", v


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
    for name, obj in _face_members(pkg):
        if inspect.isclass(obj):
            problems = [] if (inspect.getdoc(obj) or "").strip() else ["no docstring"]
        else:
            problems = _function_problems(obj)
        if problems:
            out.append(f"{name}: {'; '.join(problems)}")
    return out


def test_face_exports_carry_numpydoc():
    bad = {pkg: offenders(pkg) for pkg in DOCUMENTED}
    bad = {k: v for k, v in bad.items() if v}
    lines = [f"cdprid.{pkg}.{o}" for pkg, v in bad.items() for o in v]
    assert not bad, "face exports without numpydoc Parameters/Returns:\n" + "\n".join(lines)


def test_checker_catches_missing_sections():
    """The checker itself fails a stripped docstring (the test can fail)."""
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

    def h(x, y):
        """Sum.

        Parameters
        ----------
        x : float
            Value.
        """
        print(x + y)

    assert _function_problems(f) == ["no Parameters section", "no Returns section"]
    assert _function_problems(g) == []
    assert _function_problems(h) == ["Parameters does not name y"]


if __name__ == "__main__":
    for p in sys.argv[1:] or DOCUMENTED:
        off = offenders(p)
        print(f"== {p}: {len(off)} offenders")
        for o in off:
            print("  ", o)
