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
