"""The Monte Carlo summary report: units on the metrics, rounding noise shown as 0, no rows that
only repeat the baseline (the stability before compensation is the same for every compensator)."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.lab.cli.montecarlo import summary_report
from rlgsim.lab.montecarlo import UnitRecord
from rlgsim.lab.montecarlo_summary import clean_tiny, metric_unit, summarise


def _records(n: int = 8) -> list[UnitRecord]:
    rng = np.random.default_rng(0)
    out = []
    for u in range(n):
        before = 0.015 + 0.002 * rng.standard_normal()
        after = before * (0.5 + 0.1 * rng.random())
        out.append(UnitRecord(u, "ok", rows=[
            ("raw", "stability_before", before), ("raw", "stability_after", before),
            ("raw", "improvement_pct", -1.084e-14 * (1 + u)),
            ("LS", "stability_before", before), ("LS", "stability_after", after),
            ("LS", "improvement_pct", 100 * (1 - after / before)),
            ("LS", "r2_true", 0.9 + 0.01 * rng.random())], params={"k": float(u)}))
    return out


@pytest.mark.parametrize("metric, unit", [
    ("stability_after", "°/h"), ("rmse_true", "°/h"), ("improvement_pct@test2", "%"),
    ("r2_true", "1"), ("improvement_factor", "1"), ("gyro_bias_x.rmse", ""),
    ("gyro_bias_x.residual_variance", ""), ("avg_improvement_rmse_pct", "%"),
    ("nav_error_end_m", "m"), ("nav_radial_rate_nmi_per_h", "nmi/h"),
    ("nav_heading_end_arcmin", "′"),
    ("resid_std_true", "°/h"), ("law_resid_std", "°/h"), ("law_resid_std@test2", "°/h")])
def test_metric_units(metric, unit):
    assert metric_unit(metric) == unit


def test_clean_tiny():
    assert clean_tiny([-1.084e-14, 3.2, None, float("nan")], 30.0)[:3] == [0.0, 3.2, None]


def test_summary_drops_baseline_repeats_and_rounding_noise():
    records = _records()
    same = {(s.compensator, s.metric) for s in summarise(records, "raw") if s.same_as_baseline}
    assert same == {("LS", "stability_before")}
    rep = summary_report(records, 8, title="toy", baseline="raw")
    table = next(t for t in rep.tables if t.title == "Distributions")
    rows = {(r[0], r[1]): dict(zip(table.columns, r)) for r in table.rows}
    assert ("LS", "stability_before") not in rows and ("raw", "stability_before") in rows
    raw_imp = rows[("raw", "improvement_pct")]
    assert (raw_imp["median"], raw_imp["p5"], raw_imp["p95"]) == (0.0, 0.0, 0.0)
    assert raw_imp["unit"] == "%" and rows[("LS", "stability_after")]["unit"] == "°/h"
    assert rows[("LS", "stability_after")]["beats baseline"] == 1.0
    assert "-1.084e-14" not in rep.markdown()


def test_navigation_metrics_get_their_spread_figures():
    """Units that navigated (docs/navigation.md) get the radial-rate and heading figures even
    beyond the cap of figures of the other metrics."""
    records = _records()
    for k, r in enumerate(records):
        r.rows += [(c, m, 0.1 * (k + 1) + (c == "raw"))
                   for c in ("raw", "LS", "truth")
                   for m in ("nav_error_end_m", "nav_radial_rate_nmi_per_h",
                             "nav_heading_end_arcmin")]
    md = summary_report(records, 8, title="toy", baseline="raw").markdown()
    assert "spread_nav_radial_rate_nmi_per_h.png" in md
    assert "spread_nav_heading_end_arcmin.png" in md


def test_navigation_figures_per_environment():
    """Paper 002's units navigate every environment (metrics ``nav_…@<environment>``): each
    environment gets its radial-rate and heading figures."""
    records = _records()
    for k, r in enumerate(records):
        r.rows += [(c, f"{m}@{env}", 0.1 * (k + 1) + (c == "raw"))
                   for c in ("raw", "LS", "truth") for env in ("-40 °C", "5 °C/min")
                   for m in ("nav_error_end_m", "nav_radial_rate_nmi_per_h",
                             "nav_heading_end_arcmin")]
    md = summary_report(records, 8, title="toy", baseline="raw").markdown()
    for env in ("m40_c", "5_c_min"):
        assert f"spread_nav_radial_rate_nmi_per_h_{env}.png" in md
        assert f"spread_nav_heading_end_arcmin_{env}.png" in md
