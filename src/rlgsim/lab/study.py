"""Studies: replay an experiment end to end on simulated hardware and score it against truth.

A study file (TOML, shipped in ``scenarios/studies/`` or given by path) has a ``[study]`` table::

    [study]
    name = "paper001"                 # default: the file name
    description = "one line for 'rlgsim study --list'"
    paper = "001"                     # which paper it replays (shared/papers/README.md), or ""
    recipe = "bias_compensation"      # how it runs: a module src/rlgsim/lab/studies/<recipe>.py
    device_seed = 1001                # optional: the unit simulated (default: each scenario's)
    export_models = true              # optional: each fitted compensator as models/<name>.json,
                                      # .c, .h in the report folder (docs/compensator_export.md)

and further tables that belong to its *recipe*. A recipe is a module ``src/rlgsim/lab/studies/<recipe>.py``
named in :data:`RECIPES`, with one shape:

    check(study: Study) -> config
        validate the recipe's tables (raise :class:`~rlgsim.ground.errors.UserInputError` naming
        file/key/value) and return whatever the recipe needs;
    run(study: Study, config, workdir: pathlib.Path, *, unit: int, progress: bool) -> StudyResult
        simulate, fit, score; ``workdir`` holds the datasets (``workdir/data/``) and any files
        the recipe writes; ``StudyResult.details`` carries what its report needs;
    report(study: Study, config, result: StudyResult) -> Report        (optional)
        the report of a run; the runner calls it for ``rlgsim study`` (never for a Monte Carlo
        unit) and ends it with the study file and the scenario and preset files. A recipe
        without it gets a report of its score rows.
    fitted_models(config, result: StudyResult) -> list[FittedModel]        (optional)
        the fitted compensators of a run (:mod:`rlgsim.lab.study_models`), written as JSON and
        C when the study exports its models (``export_models``, ``--export-models``).

The runner (this module) knows its recipes by name only: it imports ``src/rlgsim/lab/studies/<recipe>.py``
when a study names it, and nothing in ``src/rlgsim/lab/studies/`` is imported here, so the recipes and
their building blocks may import this module. The study runner and the CLI are the only places
that join ``sim`` and ``estimators``. :func:`study_unit` is the Monte Carlo unit function: the
same study for unit ``i`` (another drawn device, other noise), without the report.
"""

from __future__ import annotations

import dataclasses
import importlib
import pathlib
import tempfile
from dataclasses import dataclass, field
from typing import Any

from rlgsim.ground.errors import UserInputError
from rlgsim.sim import presets
from rlgsim.sim.config import Ctx, check_known_keys, get_bool, get_int, get_str, get_table
from rlgsim.lab.report import Report, Table, output_folder

__all__ = ["Study", "StudyResult", "parse_study", "load_study", "list_studies", "recipe_module",
           "scenario_for", "scenario_refs", "run_study", "study_unit"]

STUDY_KEYS = ("name", "description", "paper", "recipe", "device_seed", "export_models")
#: The recipes, each a module ``rlgsim.lab.studies.<name>`` (a new recipe adds its name here).
RECIPES = ("bias_compensation", "environments", "gradient_selection", "paper000_system",
           "vehicle")


@dataclass(frozen=True)
class Study:
    """A validated study file. ``tables`` holds the parsed TOML for the recipe."""

    name: str
    description: str
    paper: str
    recipe: str
    source: str
    text: str
    base_dir: pathlib.Path | None
    device_seed: int | None = None
    tables: dict = field(default_factory=dict, repr=False)
    export_models: bool = False

    @property
    def title(self) -> str:
        """The report's title: "Study <name>", with " — paper <paper>" if it replays one."""
        return f"Study {self.name}" + (f" — paper {self.paper}" if self.paper else "")

    def ctx(self, *path: str) -> Ctx:
        """A :class:`~rlgsim.sim.config.Ctx` for messages about ``path`` in this study's file."""
        return Ctx(self.source, ".".join(path))


@dataclass
class StudyResult:
    """What a study run gives back: the scores of every compensator, and what its report needs.

    ``rows`` are (compensator, metric, value) — the Monte Carlo results table —, ``params``
    the drawn device parameters worth showing next to a unit's scores (name → value) and
    ``details`` whatever the recipe's ``report`` hook reads (the recipe's own type)."""

    rows: list[tuple[str, str, float]]
    params: dict[str, float] = field(default_factory=dict)
    details: Any = None


def parse_study(text: str, source: str = "<string>", *, base_dir: pathlib.Path | None = None,
                default_name: str = "study") -> Study:
    """Parse and validate the ``[study]`` table, then the recipe's own tables."""
    data = presets.parse_toml(text, source)
    ctx = Ctx(source)
    table = get_table(data, "study", ctx)
    sctx = ctx.child("study")
    check_known_keys(table, STUDY_KEYS, sctx)
    study = Study(
        name=get_str(table, "name", sctx, default_name),
        description=get_str(table, "description", sctx, ""),
        paper=get_str(table, "paper", sctx, ""),
        recipe=get_str(table, "recipe", sctx, choices=RECIPES),
        source=source, text=text, base_dir=base_dir,
        device_seed=get_int(table, "device_seed", sctx, None, min=0, max=2**63 - 1),
        tables=data, export_models=get_bool(table, "export_models", sctx, False))
    recipe_module(study).check(study)
    return study


def load_study(ref: str) -> Study:
    """A study by shipped name (``rlgsim study --list``) or by path."""
    f = presets.load(ref, "study")
    return parse_study(f.text, f.source, base_dir=f.base_dir, default_name=f.name)


def list_studies() -> list[tuple[str, str]]:
    """(name, one-line description) of every shipped study."""
    out = []
    for name in presets.list_names("study"):
        f = presets.load(name, "study")
        desc = f.data.get("study", {}).get("description", "") if isinstance(f.data, dict) else ""
        out.append((name, " ".join(str(desc).split())))
    return out


def recipe_module(study: Study):
    """The recipe module of ``study`` (found by name: ``rlgsim.lab.studies.<recipe>``)."""
    return importlib.import_module(f"rlgsim.lab.studies.{study.recipe}")


def scenario_for(study: Study, ref: str, *, unit: int = 0, ctx: Ctx | None = None):
    """Load scenario ``ref`` (name, or path relative to the study file) for this study's unit.

    The study's ``device_seed`` (if any) replaces the scenario's, so all runs of a study are
    the same physical unit; ``unit`` selects the Monte Carlo unit (another drawn device and
    other noise)."""
    from rlgsim.sim.run.scenario import load_scenario

    path = (study.base_dir / ref) if study.base_dir is not None else None
    try:
        scenario = load_scenario(str(path) if path is not None and path.is_file() else ref)
    except UserInputError as exc:
        where = f"{(ctx or study.ctx()).source}: {(ctx.path if ctx else '') or 'scenario'}"
        raise UserInputError(f"{where}: {exc}") from None
    changes: dict[str, Any] = {"unit": int(unit)}
    if study.device_seed is not None:
        changes["device_seed"] = study.device_seed
    from rlgsim.sim.run.unit_variations import apply      # Monte Carlo chamber variations, if any
    return apply(dataclasses.replace(scenario, **changes))


def scenario_refs(tables: dict) -> list[str]:
    """Scenario references found in a study's recipe tables (``scenario = "..."`` entries and
    plain strings in ``train``/``test``-like lists), in file order."""
    refs: list[str] = []

    def walk(obj: Any, key: str = "") -> None:
        if isinstance(obj, dict):
            for k, v in obj.items():
                if k == "scenario" and isinstance(v, str):
                    refs.append(v)
                else:
                    walk(v, k)
        elif isinstance(obj, list):
            for v in obj:
                if isinstance(v, str) and key in ("train", "test", "runs", "scenarios"):
                    refs.append(v)
                else:
                    walk(v, key)

    walk({k: v for k, v in tables.items() if k != "study"})
    return list(dict.fromkeys(refs))


def run_study(study: Study, out_dir: str | pathlib.Path, *, progress: bool = True,
              export_models: bool | None = None) -> pathlib.Path:
    """Run ``study`` (unit 0) and write its report folder; returns the path of report.md.
    ``export_models`` (default: the study file's ``export_models``) also writes every fitted
    compensator as ``models/<name>.json``, ``.c`` and ``.h`` (docs/compensator_export.md)."""
    out_dir = output_folder(out_dir)
    recipe = recipe_module(study)
    config = recipe.check(study)
    export = study.export_models if export_models is None else export_models
    models_hook = getattr(recipe, "fitted_models", None)
    if export and models_hook is None:
        raise UserInputError(f"{study.source}: study.export_models: the {study.recipe} recipe "
                             "does not export its compensators (their fits stay inside the "
                             "study); leave out --export-models / export_models")
    result = recipe.run(study, config, out_dir, unit=0, progress=progress)
    hook = getattr(recipe, "report", None)
    report = hook(study, config, result) if hook is not None else _rows_report(study, result)
    if export:
        from rlgsim.lab.study_models import MODELS_DIR, report_models, write_models
        report_models(report, write_models(models_hook(config, result), out_dir / MODELS_DIR))
    report.heading("Study file", 2)
    report.verbatim(study.text, title=study.source, language="toml")
    _input_files(study, report)
    return report.write(out_dir)


def _rows_report(study: Study, result: StudyResult) -> Report:
    """The report of a recipe without a ``report`` hook: its score rows as one table."""
    rep = Report(study.title)
    if study.description:
        rep.paragraph(study.description)
    rep.table(Table("Scores", ["compensator", "metric", "value"],
                    [list(row) for row in result.rows], csv_name="scores.csv"))
    return rep


def _input_files(study: Study, report: Report) -> None:
    """The exact text of every scenario the study simulates and of their device and thermal
    presets (each once), so that the report alone says what was simulated."""
    report.heading("Scenario and preset files", 2)
    shown: set[str] = set()
    for ref in scenario_refs(study.tables):
        from rlgsim.lab.recordings import recording_path
        rec = recording_path(ref, study.base_dir, str(study.source))
        if rec is not None:                    # a recording: its sidecar (docs/recordings.md)
            from rlgsim.ground.recording import sidecar_path
            side = rec if rec.suffix.lower() == ".toml" else sidecar_path(rec)
            if ("recording", str(side)) not in shown:
                shown.add(("recording", str(side)))
                report.verbatim(side.read_text(encoding="utf-8"),
                                title=f"recording {rec.name}: sidecar {side}", language="toml")
            continue
        sc = scenario_for(study, ref)
        for kind, name, source, text in (
                ("scenario", sc.name, sc.source, sc.text),
                ("device preset", sc.device.name, sc.device.source, sc.device.text),
                ("thermal preset", sc.device.thermal.name, sc.device.thermal.source,
                 sc.device.thermal.text)):
            if (kind, source) in shown:
                continue
            shown.add((kind, source))
            report.verbatim(text, title=f"{kind} {name} ({source})", language="toml")


def study_unit(payload: dict[str, Any], unit: int) -> dict[str, Any]:
    """Monte Carlo unit function (see :mod:`rlgsim.lab.montecarlo`): run the study for ``unit`` in a
    temporary folder and return its scores and drawn parameters. ``payload`` carries the study
    text and source so that workers need no access to the user's files."""
    study = parse_study(payload["text"], payload["source"],
                        base_dir=pathlib.Path(payload["base_dir"]) if payload.get("base_dir")
                        else None, default_name=payload.get("name", "study"))
    recipe = recipe_module(study)
    config = recipe.check(study)
    with tempfile.TemporaryDirectory(prefix=f"rlgsim-unit{unit}-") as tmp:
        result = recipe.run(study, config, pathlib.Path(tmp), unit=unit, progress=False)
        rows = list(result.rows)
        nav_hook = getattr(recipe, "navigation", None)
        nav = nav_hook(study, config, result) if nav_hook is not None else None
        if nav is not None:                 # the unit's navigation scores (docs/navigation.md)
            from rlgsim.lab.navigation import nav_rows
            rows += nav_rows(nav[0])
    return {"rows": rows, "params": result.params}
