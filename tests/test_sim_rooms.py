"""The rooms of the simulator wing (``sim/``), read from the source with ``ast``:

* the models (``sim/thermal``, ``sim/sensors``, ``sim/motion``) import neither the dataset
  schema and writer (``sim/writer``) nor the stages (``sim/stages``) nor the run
  (``sim/run``): a stage (``sim/stages/``) is the one place where a model meets the schema;
* every stage module of ``sim/stages/`` is in the registry's list, once, and its stage class
  has the interface of :class:`rlgsim.sim.stages.base.Stage`.

The import graph is the one tests/test_architecture.py reads (every import counts, wherever it
stands).
"""

from __future__ import annotations

import ast
import pathlib

import pytest

from test_architecture import GRAPH, MODULES

SIM = pathlib.Path(__file__).resolve().parents[1] / "sim"
MODEL_ROOMS = ("rlgsim.sim.thermal", "rlgsim.sim.sensors", "rlgsim.sim.motion")
#: what a model may not import: the dataset's schema and writer, the stages, the run
ABOVE_THE_MODELS = ("rlgsim.sim.writer", "rlgsim.sim.stages", "rlgsim.sim.run")


def _in(module: str, rooms: tuple[str, ...]) -> bool:
    return any(module == r or module.startswith(r + ".") for r in rooms)


MODELS = sorted(m for m in MODULES if _in(m, MODEL_ROOMS))


def test_the_model_rooms_are_found():
    assert {"rlgsim.sim.sensors.imu", "rlgsim.sim.sensors.anomalies",
            "rlgsim.sim.thermal.network", "rlgsim.sim.motion.kinematics"} <= set(MODELS)


@pytest.mark.parametrize("model", MODELS)
def test_a_model_imports_no_schema_writer_stage_or_run(model):
    above = sorted(t for t in GRAPH[model] if _in(t, ABOVE_THE_MODELS))
    assert not above, f"{model} imports {above}: a model must not know the dataset's layout"


def test_the_stages_and_the_writer_import_nothing_of_the_run():
    """The run (sim/run) calls the stages and the writer; neither imports the run back (the
    timeline and scenario reach them as arguments; the track names are the format's)."""
    for m in MODULES:
        if _in(m, ("rlgsim.sim.stages", "rlgsim.sim.writer")):
            back = sorted(t for t in GRAPH[m] if _in(t, ("rlgsim.sim.run",)))
            assert not back, f"{m} imports {back}"


def test_the_schema_is_reached_from_the_stages_and_the_loop_only():
    users = sorted(m for m, targets in GRAPH.items() if "rlgsim.sim.writer.schema" in targets)
    assert users and all(_in(m, ("rlgsim.sim.stages", "rlgsim.sim.run.simulate"))
                         for m in users), users


def _stage_modules() -> list[str]:
    not_stages = {"__init__", "base", "registry", "thermal"}
    return sorted(p.stem for p in (SIM / "stages").glob("*.py") if p.stem not in not_stages)


def test_every_stage_module_is_in_the_registry_once():
    from rlgsim.sim.stages.base import Stage
    from rlgsim.sim.stages.registry import STAGES

    owners = [f.__self__.__module__.rpartition(".")[2] for f in STAGES]
    assert sorted(owners) == _stage_modules()
    assert len(set(owners)) == len(owners)
    for f in STAGES:
        cls = f.__self__
        assert issubclass(cls, Stage), cls
        for name in ("declare", "initial_state", "block"):
            assert getattr(cls, name) is not getattr(Stage, name), (cls, name)
        assert hasattr(cls, "group") or hasattr(cls, "groups"), cls


def test_the_stage_modules_are_read_by_ast_too():
    """The registry imports each stage module by name (no import machinery a reader cannot
    follow)."""
    tree = ast.parse((SIM / "stages" / "registry.py").read_text(encoding="utf-8"))
    imported = {n.module.rpartition(".")[2] for n in ast.walk(tree)
                if isinstance(n, ast.ImportFrom) and n.module
                and n.module.startswith("rlgsim.sim.stages.")}
    assert set(_stage_modules()) <= imported


# --------------------------------------------------------------------------- sizes

#: a non-test file over this many lines needs a reason at its top (docs/contributing.md)
REASON_LINES = 400
MAX_LINES = 700
MAX_FUNCTION_LINES = 100
SIM_FILES = sorted(p for p in SIM.rglob("*.py") if "__pycache__" not in p.parts)


@pytest.mark.parametrize("path", SIM_FILES, ids=lambda p: str(p.relative_to(SIM)))
def test_a_sim_file_is_small_or_says_why(path):
    text = path.read_text(encoding="utf-8")
    n = len(text.splitlines())
    assert n <= MAX_LINES, f"{path.relative_to(SIM)}: {n} lines; split it along its seams"
    if n > REASON_LINES:
        doc = ast.get_docstring(ast.parse(text)) or ""
        assert "over 400 lines" in doc.lower(), (
            f"{path.relative_to(SIM)}: {n} lines and no reason at its top ('Why this file is "
            f"over 400 lines: ...' in the module docstring)")


@pytest.mark.parametrize("path", SIM_FILES, ids=lambda p: str(p.relative_to(SIM)))
def test_no_sim_function_is_over_100_lines(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    long = sorted((node.end_lineno - node.lineno + 1, node.name) for node in ast.walk(tree)
                  if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.end_lineno - node.lineno + 1 > MAX_FUNCTION_LINES)
    assert not long, f"{path.relative_to(SIM)}: functions over {MAX_FUNCTION_LINES} lines {long}"


# --------------------------------------------------------------------------- names


class _Recorder:
    """Stands in for a group writer: records what is declared."""

    def __init__(self) -> None:
        self.declared: list[str] = []

    def dimension(self, name):
        self.declared.append(name)

    def coordinate(self, name, *args, **kwargs):
        self.declared.append(name)

    def variable(self, name, *args, **kwargs):
        self.declared.append(name)


def test_the_schema_declares_only_names_the_ground_format_lists():
    """The variable names are declared once, in rlgsim.ground.dataset_format; the schema
    refuses to declare any other (the format owns the names, the schema adds the rest)."""
    from rlgsim.ground import dataset_format as fmt
    from rlgsim.sim.writer.schema import _Listed

    rec = _Recorder()
    g = _Listed(rec, fmt.IMU)
    g.dimension("sample")
    g.variable("gyro_pulses", ("sample", "gyro"), units="1", description="x")
    g.variable("sample_valid", ("sample",), units="1", description="x")      # optional part
    assert rec.declared == ["sample", "gyro_pulses", "sample_valid"]
    for bad in (lambda: g.variable("gyro_pulse", ("sample",), description="x"),
                lambda: g.coordinate("node", ["a"], description="x"),    # a thermal name
                lambda: g.dimension("samples")):
        with pytest.raises(ValueError, match="dataset_format does not list"):
            bad()
    assert rec.declared == ["sample", "gyro_pulses", "sample_valid"]       # nothing written


def test_every_schema_declaration_goes_through_the_guard():
    """Every declare_* function (and write_timeline) of the schema wraps its group writer in
    the guard before declaring anything."""
    tree = ast.parse((SIM / "writer" / "schema.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and (node.name.startswith("declare_")
                                                  or node.name == "write_timeline"):
            src = ast.unparse(node)
            guard = src.find("_Listed(g, fmt.")
            first = min((i for i in (src.find("g.variable("), src.find("g.coordinate("),
                                     src.find("g.dimension(")) if i >= 0), default=-1)
            assert guard >= 0 and (first < 0 or guard < first), node.name
