"""The configuration of the ``gradient_selection`` recipe (paper 003; the study file's tables
are described in :mod:`rlgsim.lab.studies.gradient_selection`) and the outcome its run hands to
its report (:mod:`rlgsim.lab.studies.gradient_selection_report`)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rlgsim.sim.config import (Ctx, check_known_keys, get_float, get_list, get_section, get_str,
                               get_table)
from rlgsim.lab.study import Study
from rlgsim.lab.studies.compensators import CompensatorSpec, parse_compensators
from rlgsim.lab.studies.fitting import Fitted
from rlgsim.lab.studies.runs import LoadedRun
from rlgsim.lab.studies.study_tables import (FeatureSpec, RunSpec, parse_experiment, parse_metrics,
                                             str_list)

TOP_KEYS = ("study", "data", "features", "compensator", "correlation", "paper_table", "metrics",
            "navigation")
DATA_KEYS = ("train", "test", "window_s", "gyro")
SELECT_KEYS = ("among", "min_abs_r")
CORRELATION_KEYS = ("points", "published")
TABLE_KEYS = ("title", "test", "traditional", "proposed", "before_deg_per_h", "after_deg_per_h",
              "improvement_pct", "improvement_over_traditional_pct")
METRIC_KEYS = ("cluster_s", "ddof")


@dataclass(frozen=True)
class Selection:
    """Inputs a compensator adds from the train data: the pairwise gradients of ``among`` with
    |r(bias, gradient)| ≥ ``min_abs_r`` (paper 003 §4.3: 0.90)."""

    among: tuple[str, ...]
    min_abs_r: float

    def candidates(self) -> list[str]:
        return [f"{a}-{b}" for a, b in itertools.combinations(self.among, 2)]


@dataclass(frozen=True)
class PaperTable:
    title: str
    test: str
    traditional: str
    proposed: str
    before: float | None            # the paper's bias STD before compensation [°/h]
    after: dict[str, float]         # after, per compensator name [°/h]
    improvement_pct: dict[str, float]
    improvement_over_traditional_pct: float | None


@dataclass(frozen=True)
class Config(FeatureSpec):
    """A validated gradient_selection study."""

    train: tuple[RunSpec, ...] = ()
    test: tuple[RunSpec, ...] = ()
    compensators: tuple[CompensatorSpec, ...] = ()
    selections: dict[str, Selection] = field(default_factory=dict)
    points: tuple[str, ...] = ()
    published_matrix: np.ndarray | None = None
    paper_tables: tuple[PaperTable, ...] = ()
    cluster_s: float = 100.0
    ddof: int = 1


# ------------------------------------------------------------------------------ configuration
def _gradient_probe_list(table: dict, key: str, ctx: Ctx, gradients: tuple[str, ...]
                         ) -> tuple[str, ...]:
    names = str_list(table, key, ctx, min_len=2)
    for n in names:
        if n not in gradients:
            raise ctx.error(key, f"probe {n!r} is not in features.gradients "
                                 f"({', '.join(gradients) or 'none'})")
    return names


def _selections(data: dict, ctx: Ctx, gradients: tuple[str, ...]
                ) -> tuple[dict, dict[str, Selection]]:
    """Take the ``select`` tables out of the compensators (:mod:`.compensators` parses the
    rest)."""
    items = data.get("compensator")
    if not isinstance(items, list):
        return data, {}
    stripped, selections = [], {}
    for i, item in enumerate(items):
        if isinstance(item, dict) and "select" in item:
            cctx = ctx.child("compensator").item(i)
            sel = get_table(item, "select", cctx)
            sctx = cctx.child("select")
            check_known_keys(sel, SELECT_KEYS, sctx)
            selections[str(item.get("name"))] = Selection(
                among=_gradient_probe_list(sel, "among", sctx, gradients),
                min_abs_r=get_float(sel, "min_abs_r", sctx, min=0.0, max=1.0,
                                    min_exclusive=True))
            item = {k: v for k, v in item.items() if k != "select"}
        stripped.append(item)
    return {**data, "compensator": stripped}, selections


def _matrix(value: Any, n: int, ctx: Ctx, key: str) -> np.ndarray:
    rows = value if isinstance(value, list) else None
    ok = rows is not None and len(rows) == n and all(isinstance(r, list) and len(r) == n
                                                      for r in rows)
    if ok:
        try:
            m = np.array(rows, dtype=float)
        except (TypeError, ValueError):
            ok = False
    if not ok or not np.all(np.isfinite(m)) or np.any(np.abs(m) > 1):
        raise ctx.error(key, f"expected a {n}×{n} array of correlation coefficients in "
                             f"[-1, 1] (one row per point), got {value!r}")
    return m


def _paper_table(item: Any, i: int, ctx: Ctx, labels: list[str], names: list[str]
                 ) -> PaperTable:
    tctx = ctx.item(i)
    if not isinstance(item, dict):
        raise Ctx(ctx.source).error(tctx.path, f"expected a table, got {item!r}")
    check_known_keys(item, TABLE_KEYS, tctx)
    test = get_str(item, "test", tctx, choices=labels)
    trad = get_str(item, "traditional", tctx, choices=names)
    prop = get_str(item, "proposed", tctx, choices=names)
    if trad == prop:
        raise tctx.error("proposed", f"value {prop!r} not allowed; must differ from traditional")

    def per_model(key: str) -> dict[str, float]:
        t = get_table(item, key, tctx, {})
        kctx = tctx.child(key)
        check_known_keys(t, names, kctx)
        return {k: get_float(t, k, kctx) for k in t}

    return PaperTable(title=get_str(item, "title", tctx, f"Test run {test}"), test=test,
                      traditional=trad, proposed=prop,
                      before=get_float(item, "before_deg_per_h", tctx, None, min=0.0),
                      after=per_model("after_deg_per_h"),
                      improvement_pct=per_model("improvement_pct"),
                      improvement_over_traditional_pct=get_float(
                          item, "improvement_over_traditional_pct", tctx, None))


def parse(study: Study) -> Config:
    """Validate the recipe's tables; :class:`UserInputError` naming file/key/value."""
    data, ctx = study.tables, study.ctx()
    d, features = parse_experiment(study, TOP_KEYS, DATA_KEYS)
    train, test, window_s = d.train, d.test, d.window_s
    stripped, selections = _selections(data, ctx, features.gradients)
    comps = parse_compensators(stripped, ctx, features.feature_names(), (), min_inputs=0,
                               base_dir=study.base_dir)
    for c in comps:
        if not c.inputs and c.name not in selections:
            raise c.ctx.error("inputs", "empty: give inputs or a select table")
    names = [c.name for c in comps]
    from rlgsim.lab.studies.imu_axes import parse_navigation
    parse_navigation(study, names)              # the three-gyro IMU's [navigation] table

    ctable, cctx = get_section(data, "correlation", ctx, CORRELATION_KEYS, {})
    points: tuple[str, ...] = ()
    matrix = None
    if ctable:
        points = _gradient_probe_list(ctable, "points", cctx, features.gradients)
        if "published" in ctable:
            matrix = _matrix(ctable["published"], len(points), cctx, "published")

    labels = [r.label for r in test]
    tables = tuple(_paper_table(item, i, ctx.child("paper_table"), labels, names)
                   for i, item in enumerate(get_list(data, "paper_table", ctx, [])))

    mtable, mctx, cluster_s, ddof = parse_metrics(data, ctx, window_s, METRIC_KEYS)
    return Config(**vars(features), train=train, test=test, compensators=comps,
                  selections=selections, points=points, published_matrix=matrix,
                  paper_tables=tables, cluster_s=cluster_s,
                  ddof=ddof)


def column_name(a: str, b: str, names: set[str]) -> str:
    """The gradient column of probes a and b among ``names`` ("a-b" or "b-a")."""
    return f"{a}-{b}" if f"{a}-{b}" in names else f"{b}-{a}"


# ------------------------------------------------------------------------------ the run
@dataclass
class Outcome:
    """What :func:`run` hands to :func:`report` (in ``StudyResult.details``)."""

    runs: dict[tuple[str, float], LoadedRun]
    fitted: list[Fitted]
    listings: dict[str, list[tuple[str, float, bool]]]  # selection: (gradient, r, kept)
    per_test: dict[str, dict[str, dict[str, float]]]    # test label → compensator → scores
    predictions: dict[str, dict[str, np.ndarray]]       # test label → compensator → ŷ [°/h]
    corr: np.ndarray | None                             # Table 3 of the train windows
    Xtr: Any                    # the train windows' inputs (Columns)
    unit: int
    t_data: float               # wall time of simulating/reading the runs [s]
    t_total: float              # wall time of the run [s]
