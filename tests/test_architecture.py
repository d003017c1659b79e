"""The house rules of the import graph, read from the source with ``ast`` (nothing is imported):

* no import circles among the modules of ``sim/``, ``estimators/`` and ``src/rlgsim/``;
* the wings: ``rlgsim.sim`` (the simulator) and ``rlgsim.estimators`` never import each other;
  ``rlgsim.lab`` may import both; the ground package ``rlgsim.ground`` imports none of the three;
  nothing inside the package imports the public facade (``rlgsim.api``, the root ``rlgsim``);
* the study runner ``src/rlgsim/lab/study.py`` never imports the recipes or building blocks in
  ``src/rlgsim/lab/studies/`` (it finds a recipe by name), and every recipe module there is registered;
* one reader: only the dataset room (``rlgsim.ground.dataset_format``), the writer
  (``rlgsim.sim.writer``) and the recordings room (``rlgsim.ground.recording``, HDF5 tables that
  are no dataset) import h5py;
* small files with one job: none over 700 lines, none over 400 without a paragraph
  "Why this file is long:" in its docstring, no function over 100 lines.

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
    assert "rlgsim.lab.study" in MODULES and "rlgsim.estimators.metrics" in MODULES
    assert "rlgsim.ground.errors" in GRAPH["rlgsim.lab.study"]
    known = {"rlgsim", "rlgsim.ground", "rlgsim.ground.errors", "rlgsim.sim", "rlgsim.lab.study",
             "rlgsim.lab.studies", "rlgsim.lab.studies.runs", "rlgsim.lab.studies.fitting"}
    text = ("from . import runs\nfrom ..study import Study\nimport numpy\n"
            "def f():\n    from rlgsim.ground.errors import UserInputError\n")
    assert edges(text, "rlgsim.lab.studies.fitting", False, known) == {
        "rlgsim.lab.studies.runs", "rlgsim.lab.study", "rlgsim.ground.errors"}
    assert edges("from .studies import runs\n", "rlgsim.lab", True, known | {"rlgsim.lab"}) == {
        "rlgsim.lab.studies.runs"}
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


def _inside(module: str, wing: str) -> bool:
    return module == wing or module.startswith(wing + ".")


#: wing -> the wings it must never import
FORBIDDEN = {
    "rlgsim.sim": ("rlgsim.estimators", "rlgsim.lab"),
    "rlgsim.estimators": ("rlgsim.sim", "rlgsim.lab"),
    "rlgsim.ground": ("rlgsim.sim", "rlgsim.estimators", "rlgsim.lab"),
}


@pytest.mark.parametrize("wing", sorted(FORBIDDEN))
def test_the_wings_import_only_downwards(wing):
    bad = {m: sorted(t for t in GRAPH[m] if any(_inside(t, w) for w in FORBIDDEN[wing]))
           for m in MODULES if _inside(m, wing)}
    assert {m: t for m, t in bad.items() if t} == {}


def test_sim_and_estimators_share_no_arrow_either_way():
    sim_est = sum(1 for m in MODULES if _inside(m, "rlgsim.sim")
                  for t in GRAPH[m] if _inside(t, "rlgsim.estimators"))
    est_sim = sum(1 for m in MODULES if _inside(m, "rlgsim.estimators")
                  for t in GRAPH[m] if _inside(t, "rlgsim.sim"))
    assert (sim_est, est_sim) == (0, 0)


def test_nothing_inside_imports_the_public_facade():
    # the facade (rlgsim.api, the lazy public names of the root) is for users; inside, a module
    # imports the room that holds the name (the root's __version__ is no facade)
    bad = sorted(m for m in MODULES if m != "rlgsim.api" and "rlgsim.api" in GRAPH[m])
    for m, (path, _) in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module == "rlgsim" and not node.level:
                bad += [f"{m}: {a.name}" for a in node.names if a.name != "__version__"]
            elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) \
                    and node.value.id == "rlgsim" and not node.attr.startswith("_") \
                    and node.attr not in ("sim", "estimators", "lab", "ground", "scenarios"):
                bad.append(f"{m}: rlgsim.{node.attr}")
    assert bad == []


def test_the_study_runner_does_not_import_its_recipes():
    assert sorted(t for t in GRAPH["rlgsim.lab.study"]
                  if t.startswith("rlgsim.lab.studies")) == []


def test_every_recipe_module_is_registered_and_has_the_recipe_shape():
    import importlib

    from rlgsim.lab.study import RECIPES
    found = []
    for m in MODULES:
        if m.startswith("rlgsim.lab.studies."):
            tree = ast.parse(MODULES[m][0].read_text(encoding="utf-8"))
            defs = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
            if {"check", "run"} <= defs:
                found.append(m.rpartition(".")[2])
    assert sorted(found) == sorted(RECIPES)
    for name in RECIPES:
        module = importlib.import_module(f"rlgsim.lab.studies.{name}")
        assert callable(module.check) and callable(module.run)
        assert callable(getattr(module, "report", print))       # the optional hook


# ------------------------------------------------------------------------------ one reader
#: The rooms that may import h5py: the dataset reader, the dataset writer, the recordings
#: (an HDF5 recording table is no rlgsim dataset).
H5PY_ROOMS = ("rlgsim.ground.dataset_format", "rlgsim.sim.writer", "rlgsim.ground.recording",
              "rlgsim.ground.recording_read")     # the recordings' reader of HDF5 tables
#: Modules that still read or write HDF5 themselves, waiting for their owners to move the work
#: into a room above. The list may only shrink (delete an entry when its module is clean).
KNOWN_H5PY: list[str] = [
    "rlgsim.lab.mission", "rlgsim.lab.mission_report",         # navigation (issues 25, 26)
    "rlgsim.lab.navigation_source",
    "rlgsim.sim.run.run_budget",            # sizes the writer's open file (the sim wing's)
]


def _imports_h5py(path: pathlib.Path) -> bool:
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import) and any(a.name.split(".")[0] == "h5py" for a in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "h5py":
            return True
    return False


def test_only_the_dataset_rooms_import_h5py():
    found = sorted(m for m, (path, _) in MODULES.items()
                   if _imports_h5py(path) and not any(_inside(m, r) for r in H5PY_ROOMS))
    assert [m for m in found if m not in KNOWN_H5PY] == [], "read through open_dataset"
    assert [m for m in KNOWN_H5PY if m not in found] == [], "remove it from KNOWN_H5PY"
    text = "def f():\n    import h5py.h5f\n"
    assert any(isinstance(n, ast.Import) for n in ast.walk(ast.parse(text)))


# ------------------------------------------------------------------------------ sizes
MAX_FILE_LINES = 700
REASON_FILE_LINES = 400
MAX_FUNCTION_LINES = 100
#: the words a file over 400 lines gives its reason after (in its module docstring): "Why this
#: file is long:" or, as tests/test_sim_rooms.py asks of the simulator, "Why this file is over
#: 400 lines:"
LONG_REASONS = ("Why this file is long:", "Why this file is over 400 lines:")
#: Files and functions over the limits that their owners are splitting (file, or
#: "file:function"); the lists may only shrink.
KNOWN_LONG_FILES: list[str] = []
KNOWN_LONG_FUNCTIONS: list[str] = []


def _lines(path: pathlib.Path) -> int:
    return path.read_text(encoding="utf-8").count("\n")


def _rel(path: pathlib.Path) -> str:
    return path.relative_to(ROOT).as_posix()


def test_no_file_is_too_long_and_a_long_one_says_why():
    over, unexplained = [], []
    for path, _ in MODULES.values():
        n = _lines(path)
        if n > MAX_FILE_LINES:
            over.append(_rel(path))
        elif n > REASON_FILE_LINES:
            doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
            if not any(reason in doc for reason in LONG_REASONS):
                unexplained.append(_rel(path))
    assert [f for f in over + unexplained if f not in KNOWN_LONG_FILES] == []
    assert [f for f in KNOWN_LONG_FILES if f not in over + unexplained] == [], \
        "remove it from KNOWN_LONG_FILES"


def test_no_function_is_over_100_lines():
    long = []
    for path, _ in MODULES.values():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES:
                long.append(f"{_rel(path)}:{node.name}")
    assert [f for f in long if f not in KNOWN_LONG_FUNCTIONS] == []
    assert [f for f in KNOWN_LONG_FUNCTIONS if f not in long] == [], \
        "remove it from KNOWN_LONG_FUNCTIONS"


def test_the_benchmark_scripts_keep_the_same_size_rules():
    # benchmarks/ is not a package of the wings, but it is code a reader opens: the same limits
    bad = []
    for path in sorted((ROOT / "benchmarks").glob("*.py")):
        text = path.read_text(encoding="utf-8")
        tree = ast.parse(text)
        n = text.count("\n")
        if n > MAX_FILE_LINES or (n > REASON_FILE_LINES and not any(
                reason in (ast.get_docstring(tree) or "") for reason in LONG_REASONS)):
            bad.append(f"{_rel(path)}: {n} lines")
        bad += [f"{_rel(path)}:{node.name}" for node in ast.walk(tree)
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES]
    assert bad == []


# ------------------------------------------------------------------------------ registries
def test_one_registry_of_compensator_kinds():
    # a study's kinds and the export's class map are the one registry: every kind's estimator
    # imports, exports as that kind, and its closed form is one the export reads
    from rlgsim.estimators import compensator_kinds as reg
    from rlgsim.estimators import model_export
    from rlgsim.lab.studies import compensators
    assert compensators.KINDS is reg.KINDS
    assert set(model_export.KINDS.values()) == set(reg.KINDS)
    for kind, spec in reg.KINDS.items():
        cls = reg.estimator_class(kind)
        assert f"{cls.__module__}.{cls.__qualname__}" == spec.estimator
        assert all(model_export.KINDS[c] == kind for c in spec.classes)
        assert spec.closed_form in reg.CLOSED_FORMS
    assert set(compensators.EQUATION_KINDS) == {"polynomial", "stepwise", "mlr_bic"}


def test_one_registry_of_recording_formats():
    import argparse

    from rlgsim.ground import recording, recording_export, recording_formats
    from rlgsim.lab.cli import export as cli_export
    assert recording.DATA_SUFFIXES is recording_formats.DATA_SUFFIXES
    assert recording_export.FORMATS is recording_formats.EXPORT_FORMATS
    parser = argparse.ArgumentParser()
    cli_export.add_subparser(parser.add_subparsers())
    action = next(a for a in parser._subparsers._group_actions[0].choices["export"]._actions
                  if "--format" in a.option_strings)
    assert tuple(action.choices) == tuple(recording_formats.EXPORT_FORMATS)
