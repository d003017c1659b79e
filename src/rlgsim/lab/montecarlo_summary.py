"""Summaries of a Monte Carlo campaign: distributions per compensator and metric, and the
units where a compensator fails worst (with their drawn parameters), so a user sees *when* a
compensator breaks."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from rlgsim.lab.montecarlo import UnitRecord

#: Metrics for which a larger value is better; every other metric is better when smaller.
#: A study's variants count too: ``r2_true``, ``improvement_pct@test2`` (name before ``@``,
#: and the ``_true``/``_test`` suffixes of truth-based scores).
HIGHER_IS_BETTER = {"r2", "improvement_pct", "improvement_factor"}


def higher_is_better(metric: str) -> bool:
    base = metric.split("@")[0]
    return base in HIGHER_IS_BETTER or base.rsplit("_", 1)[0] in HIGHER_IS_BETTER


def metric_unit(metric: str) -> str:
    """Unit of a study metric: % for improvements, 1 for R² and factors, °/h for the
    single-gyro recipes' stabilities and errors; "" when a per-parameter metric of paper 000
    (``gyro_bias_x.rmse``: the parameter's own unit) or unknown."""
    base = metric.split("@")[0]
    name = base.rsplit(".", 1)[-1]
    name = name.removesuffix("_true").removesuffix("_test")
    if name.startswith(("improvement_pct", "avg_improvement", "outside_")):
        return "%"
    if name in ("r2", "improvement_factor"):
        return "1"
    if name.startswith("nav_"):                   # the navigation scores (docs/navigation.md)
        return {"m": "m", "h": "nmi/h", "arcmin": "′"}.get(name.rsplit("_", 1)[-1], "")
    if "." not in base and name.startswith(("stability", "rmse", "mae", "residual", "resid_",
                                            "law_resid", "floor", "bias", "std")):
        return "°/h"
    return ""


def clean_tiny(values: Sequence[float | None], scale: float, rel: float = 1e-9
               ) -> list[float | None]:
    """Values below ``rel`` × ``scale`` in magnitude (rounding noise such as -1.084e-14 for a
    quantity that is zero by construction) as 0.0; None and NaN kept."""
    out: list[float | None] = []
    for v in values:
        if v is not None and np.isfinite(v) and abs(v) <= rel * scale:
            v = 0.0
        out.append(v)
    return out


def better(metric: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Element-wise: is ``a`` better than ``b`` for ``metric``?"""
    return a > b if higher_is_better(metric) else a < b


@dataclass
class MetricSummary:
    compensator: str
    metric: str
    n_units: int
    median: float
    p5: float
    p95: float
    beats_baseline: float      # share of units (0..1) where it beats the baseline; nan if none
    same_as_baseline: bool = False  # equal to the baseline on every unit (e.g. the stability
                                    # before compensation): says nothing about the compensator


def metric_matrix(records: Sequence[UnitRecord]) -> dict[tuple[str, str], dict[int, float]]:
    """{(compensator, metric): {unit: value}} over the successful units."""
    out: dict[tuple[str, str], dict[int, float]] = {}
    for rec in records:
        if rec.status != "ok":
            continue
        for comp, metric, value in rec.rows:
            out.setdefault((comp, metric), {})[rec.unit] = value
    return out


def summarise(records: Sequence[UnitRecord], baseline: str | None) -> list[MetricSummary]:
    """Median, 5th/95th percentiles and share of units beating ``baseline`` per metric."""
    matrix = metric_matrix(records)
    out = []
    for (comp, metric), per_unit in sorted(matrix.items()):
        units = sorted(per_unit)
        values = np.array([per_unit[u] for u in units])
        share = float("nan")
        same = False
        base = matrix.get((baseline, metric)) if baseline else None
        if base is not None and comp != baseline:
            common = [u for u in units if u in base]
            if common:
                a = np.array([per_unit[u] for u in common])
                b = np.array([base[u] for u in common])
                same = len(common) == len(units) == len(base) and np.array_equal(a, b)
                share = float("nan") if same else float(np.mean(better(metric, a, b)))
        p5, med, p95 = np.nanpercentile(values, [5, 50, 95]) if values.size else (np.nan,) * 3
        out.append(MetricSummary(comp, metric, len(units), float(med), float(p5), float(p95),
                                 share, same))
    return out


def worst_units(records: Sequence[UnitRecord], compensator: str, metric: str,
                count: int = 5) -> list[tuple[int, float, dict[str, float]]]:
    """The ``count`` units where ``compensator`` scores worst on ``metric``, with parameters."""
    per_unit = metric_matrix(records).get((compensator, metric), {})
    params = {rec.unit: rec.params for rec in records}
    order = sorted(per_unit, key=lambda u: per_unit[u], reverse=not higher_is_better(metric))
    return [(u, per_unit[u], params.get(u, {})) for u in order[:count]]
