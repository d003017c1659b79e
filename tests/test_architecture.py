"""The house rules of the import graph, read from the source with ``ast`` (nothing is imported):

* no import circles among the modules of ``sim/``, ``estimators/`` and ``src/rlgsim/``;
* ``estimators/`` and the ground package ``src/rlgsim/ground/`` never import ``rlgsim.sim``
  (they work on real recordings too);
* the study runner ``sim/study.py`` never imports the recipes or building blocks in
  ``sim/studies/`` (it finds a recipe by name), and every recipe module there is registered.

Every ``import`` and ``from ... import`` counts, wherever it stands (module level, inside a
function, under ``if TYPE_CHECKING``), relative imports included: a function-level import that
closes a circle is still a circle for the reader of the code.
"""

from __future__ import annotations

import ast
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: source folder -> the package it installs as (pyproject.toml [tool.setuptools.package-dir])
PACKAGES = {"sim": "rlgsim.sim", "estimators": "rlgsim.estimators", "src/rlgsim": "rlgsim"}


def _modules() -> dict[str, tuple[pathlib.Path, bool]]:
    """Dotted module name -> (file, is a package __init__)."""
    out = {}
    for folder, package in PACKAGES.items():
        base = ROOT / folder
        for path in sorted(base.rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            rel = path.relative_to(base).with_suffix("").parts
            is_pkg = rel[-1] == "__init__"
            parts = rel[:-1] if is_pkg else rel
            out[".".join((package, *parts))] = (path, is_pkg)
    return out


MODULES = _modules()


def _resolve(name: str, known) -> str | None:
    """The internal module ``name`` refers to: itself or its longest known prefix."""
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def edges(text: str, module: str, is_pkg: bool, known) -> set[str]:
    """The modules of ``known`` that the source ``text`` of ``module`` imports."""
    here = module if is_pkg else module.rpartition(".")[0]    # the package of the module
    out: set[str] = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here
                for _ in range(node.level - 1):
                    base = base.rpartition(".")[0]
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            # "from pkg import mod" imports the module pkg.mod; "from mod import name" mod
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base
                     for a in node.names]
        else:
            continue
        for n in names:
            target = _resolve(n, known)
            if target is not None and target != module:
                out.add(target)
    return out


def imports_of(module: str) -> set[str]:
    """The internal modules ``module`` imports (edges of the import graph)."""
    path, is_pkg = MODULES[module]
    return edges(path.read_text(encoding="utf-8"), module, is_pkg, MODULES)


GRAPH = {m: imports_of(m) for m in MODULES}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_graph_is_read():
    # the parser sees the modules and their edges, relative and function-level imports included
    assert "rlgsim.sim.study" in MODULES and "rlgsim.estimators.metrics" in MODULES
    assert "rlgsim.ground.errors" in GRAPH["rlgsim.sim.study"]
    known = {"rlgsim", "rlgsim.ground", "rlgsim.ground.errors", "rlgsim.sim", "rlgsim.sim.study",
             "rlgsim.sim.studies", "rlgsim.sim.studies.runs", "rlgsim.sim.studies.fitting"}
    text = ("from . import runs\nfrom ..study import Study\nimport numpy\n"
            "def f():\n    from rlgsim.ground.errors import UserInputError\n")
    assert edges(text, "rlgsim.sim.studies.fitting", False, known) == {
        "rlgsim.sim.studies.runs", "rlgsim.sim.study", "rlgsim.ground.errors"}
    assert edges("from .studies import runs\n", "rlgsim.sim", True, known) == {
        "rlgsim.sim.studies.runs"}
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


#: Circles committed by other work while this test was written, each closed by a
#: function-level import; listed so that the suite stays green while their owners break them.
#: The list may only shrink: a new circle fails the test, and so does a listed one that is gone
#: (delete its entry then).
KNOWN_CIRCLES: list[list[str]] = []


def test_no_import_circles():
    # a circle is broken by moving what both sides need into a module that neither imports
    cycles = _cycles(GRAPH)
    assert [c for c in cycles if c not in KNOWN_CIRCLES] == []
    assert [c for c in KNOWN_CIRCLES if c not in cycles] == [], "remove it from KNOWN_CIRCLES"


@pytest.mark.parametrize("prefix", ["rlgsim.estimators", "rlgsim.ground"])
def test_estimators_and_ground_never_import_sim(prefix):
    bad = {m: sorted(t for t in GRAPH[m] if t == "rlgsim.sim" or t.startswith("rlgsim.sim."))
           for m in MODULES if m == prefix or m.startswith(prefix + ".")}
    assert {m: t for m, t in bad.items() if t} == {}


def test_the_study_runner_does_not_import_its_recipes():
    assert sorted(t for t in GRAPH["rlgsim.sim.study"]
                  if t.startswith("rlgsim.sim.studies")) == []


def test_every_recipe_module_is_registered_and_has_the_recipe_shape():
    import importlib

    from rlgsim.sim.study import RECIPES
    found = []
    for m in MODULES:
        if m.startswith("rlgsim.sim.studies."):
            tree = ast.parse(MODULES[m][0].read_text(encoding="utf-8"))
            defs = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
            if {"check", "run"} <= defs:
                found.append(m.rpartition(".")[2])
    assert sorted(found) == sorted(RECIPES)
    for name in RECIPES:
        module = importlib.import_module(f"rlgsim.sim.studies.{name}")
        assert callable(module.check) and callable(module.run)
        assert callable(getattr(module, "report", print))       # the optional hook
