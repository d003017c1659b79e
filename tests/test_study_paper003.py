"""The paper-003 recipe (gradient_selection) on a short study: Table 3 correlation matrix,
correlation-based input selection, Tables 4-5, and the scores recomputed independently from the
dataset files and the exported window series; the shipped study validates; bad files are user
errors."""

from __future__ import annotations

import csv
import itertools
import math
import pathlib

import numpy as np
import pytest

from independent_windows import read_windows
from html_render import CHROMIUM, SKIP_REASON, check_report_renders
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import list_studies, load_study, parse_study, run_study
from rlgsim.lab.studies.gradient_selection import improvement_over_traditional

ROOT = pathlib.Path(__file__).resolve().parents[1]
POINTS = ["g.A", "g.B", "g.D", "g.G", "g.H"]

CYCLE = """
name = "{name}"
description = "short paper-003 test run"
device = "rlg8_003"
seed = {seed}

[acquisition]
sample_rate_hz = 10
thermal_step_s = 1

[power]
on_at_s = 0

[chamber]
start_c = 20.0

[[chamber.segments]]
type = "hold"
duration_h = 1

[[chamber.segments]]
type = "ramp"
to_c = -20.0
rate_c_per_min = {rate}

[[chamber.segments]]
type = "hold"
duration_h = 1

[[chamber.segments]]
type = "ramp"
to_c = 50.0
rate_c_per_min = {rate}

[[chamber.segments]]
type = "hold"
duration_h = 1
"""

STUDY = """
[study]
name = "p003short"
description = "short paper-003 study"
paper = "003"
recipe = "gradient_selection"
device_seed = 3000

[data]
train = ["train.toml"]
test = [{ scenario = "train.toml", seed = 3100 }, "test.toml"]
window_s = 100

[features]
temperature = "g.A"
gradients = ["g.A", "g.B", "g.D", "g.G", "g.H", "housing"]

[[compensator]]
name = "3-point"
kind = "pso_svr"
inputs = ["T", "g.A-g.D", "g.A-housing", "g.D-housing"]
params = { n_agents = 5, max_iter = 3, C_bounds = [0.1, 100.0] }

[[compensator]]
name = "multi-point"
kind = "pso_svr"
inputs = ["T"]
select = { among = ["g.A", "g.B", "g.D", "g.G", "g.H"], min_abs_r = 0.5 }
params = { n_agents = 5, max_iter = 3, C_bounds = [0.1, 100.0] }

[[compensator]]
name = "LS cubic T"
kind = "polynomial"
inputs = ["T"]
params = { degree = 3 }

[correlation]
points = ["g.A", "g.B", "g.D", "g.G", "g.H"]
published = [
  [0.0,   0.939, 0.913, 0.935, 0.942],
  [0.939, 0.0,   0.888, 0.913, 0.739],
  [0.913, 0.888, 0.0,   0.904, 0.647],
  [0.935, 0.913, 0.904, 0.0,   0.932],
  [0.942, 0.739, 0.647, 0.932, 0.0],
]

[[paper_table]]
title = "Table 4: verification"
test = "train-seed3100"
traditional = "3-point"
proposed = "multi-point"
before_deg_per_h = 0.0258
after_deg_per_h = { "3-point" = 0.0089, "multi-point" = 0.0021 }
improvement_pct = { "3-point" = 65.5, "multi-point" = 91.9 }
improvement_over_traditional_pct = 40.3

[[paper_table]]
title = "Table 5: random"
test = "test"
traditional = "3-point"
proposed = "multi-point"
before_deg_per_h = 0.0283
"""


def _write(folder: pathlib.Path, study: str = STUDY) -> pathlib.Path:
    (folder / "train.toml").write_text(CYCLE.format(name="train", seed=3000, rate=2.0))
    (folder / "test.toml").write_text(CYCLE.format(name="test", seed=3001, rate=4.0))
    path = folder / "study.toml"
    path.write_text(study)
    return path


@pytest.fixture(scope="module")
def short(tmp_path_factory) -> pathlib.Path:
    folder = tmp_path_factory.mktemp("p003")
    study = load_study(str(_write(folder)))
    run_study(study, folder / "out", progress=False)
    return folder / "out"


def _csv(path: pathlib.Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _scores(folder: pathlib.Path, label: str) -> dict[str, dict[str, float]]:
    return {r["compensator"]: {k: float(v) for k, v in r.items() if k != "compensator" and v}
            for r in _csv(folder / f"scores_{label}.csv")}


def _windows(path: pathlib.Path):
    w = read_windows(path)
    return w["y"], w["b"], w["r"], w["probes"]


def test_correlation_matrix_matches_an_independent_recomputation(short):
    y, _, _, probes = _windows(short / "data" / "train.h5")
    rows = _csv(short / "correlation_matrix.csv")
    short_names = [p.split(".")[1] for p in POINTS]
    assert [r["thermometer"] for r in rows] == short_names
    for (i, a), (j, b) in itertools.combinations(enumerate(POINTS), 2):
        expected = np.corrcoef(probes[a] - probes[b], y)[0, 1]
        assert float(rows[i][short_names[j]]) == pytest.approx(expected, abs=1e-9)
        assert float(rows[j][short_names[i]]) == pytest.approx(expected, abs=1e-9)
        assert rows[i][short_names[i]] == ""


def test_selection_keeps_exactly_the_gradients_above_the_threshold(short):
    y, _, _, probes = _windows(short / "data" / "train.h5")
    listing = _csv(short / "selection_multi_point.csv")
    assert len(listing) == math.comb(len(POINTS), 2)
    for row in listing:
        a, b = row["gradient"].split("-")
        r = np.corrcoef(probes[a] - probes[b], y)[0, 1]
        assert float(row["r"]) == pytest.approx(r, abs=1e-9)
        assert (row["selected"] == "yes") == (abs(r) >= 0.5)
    models = {r["compensator"]: r for r in _csv(short / "hyperparameters.csv")}
    chosen = [r["gradient"] for r in listing if r["selected"] == "yes"]
    assert models["multi-point"]["inputs"] == ", ".join(["T"] + chosen)


@pytest.mark.parametrize("label, data", [("train_seed3100", "train-seed3100.h5"),
                                         ("test", "test.h5")])
def test_truth_scores_match_an_independent_recomputation(short, label, data):
    y, b, r, probes = _windows(short / "data" / data)
    series = _csv(short / f"series_{label}.csv")
    assert len(series) == y.size                      # powered from t = 0: every window kept
    np.testing.assert_allclose([float(s["y_deg_per_h"]) for s in series], y, rtol=0,
                               atol=1e-9)
    np.testing.assert_allclose([float(s["true_bias_deg_per_h"]) for s in series], b, rtol=1e-9)
    scores = _scores(short, label)
    for name in ("3-point", "multi-point", "LS cubic T"):
        pred = np.array([float(s[f"pred: {name}"]) for s in series])
        sc = scores[name]
        assert sc["rmse_true"] == pytest.approx(np.sqrt(np.mean((pred - b) ** 2)), rel=1e-7)
        assert sc["mae_true"] == pytest.approx(np.mean(np.abs(pred - b)), rel=1e-7)
        assert sc["resid_std_true"] == pytest.approx(np.std(pred - b, ddof=1), rel=1e-7)
        assert sc["law_resid_std"] == pytest.approx(np.std(pred - (b - r), ddof=1), rel=1e-7)
        assert sc["stability_before"] == pytest.approx(np.std(y, ddof=1), rel=1e-7)
        assert sc["stability_after"] == pytest.approx(np.std(y - pred, ddof=1), rel=1e-7)
        assert sc["improvement_factor"] == pytest.approx(
            sc["stability_before"] / sc["stability_after"], rel=1e-12)
    oracle = scores["truth: temperature law"]
    assert oracle["rmse_true"] == pytest.approx(np.sqrt(np.mean(r ** 2)), rel=1e-7)
    assert oracle["stability_after"] == pytest.approx(np.std(y - (b - r), ddof=1), rel=1e-7)
    # compensation by the T polynomial refitted here on the independently read train windows
    y_tr, _, _, p_tr = _windows(short / "data" / "train.h5")
    coef = np.polyfit(p_tr["g.A"], y_tr, 3)
    pred = np.polyval(coef, probes["g.A"])
    assert scores["LS cubic T"]["rmse_true"] == pytest.approx(
        np.sqrt(np.mean((pred - b) ** 2)), rel=1e-6)


def test_paper_tables_put_ours_beside_the_paper(short):
    t4 = {r["RLG bias (°/h)"]: r for r in _csv(short / "paper_table_4_verification.csv")}
    sc = _scores(short, "train_seed3100")
    after = t4["after compensation"]
    assert float(after["3-point (ours)"]) == pytest.approx(sc["3-point"]["stability_after"])
    assert float(after["multi-point (paper)"]) == 0.0021
    over = t4["improvement from traditional method (%)"]
    assert float(over["multi-point (paper)"]) == 40.3
    assert float(over["multi-point (ours)"]) == pytest.approx(improvement_over_traditional(
        sc["3-point"]["improvement_pct"], sc["multi-point"]["improvement_pct"]))
    t5 = {r["RLG bias (°/h)"]: r for r in _csv(short / "paper_table_5_random.csv")}
    assert t5["after compensation"]["multi-point (paper)"] == ""      # not given
    md = (short / "report.md").read_text()
    assert "Table 3" in md and "Ranking" in md and "within a factor 1.5" in md
    for png in ("correlation_heatmap.png", "bias_over_time_test.png", "allan_deviation_test.png",
                "bias_vs_gradient.png"):
        assert (short / png).stat().st_size > 10_000


def test_improvement_over_traditional_is_the_papers_definition():
    assert improvement_over_traditional(65.5, 91.9) == pytest.approx(40.3, abs=0.05)
    assert improvement_over_traditional(67.8, 91.9) == pytest.approx(35.5, abs=0.05)


def test_same_study_gives_the_same_scores(short, tmp_path):
    study = load_study(str(_write(tmp_path)))
    run_study(study, tmp_path / "again", progress=False)
    for label in ("train_seed3100", "test"):
        assert _scores(tmp_path / "again", label) == _scores(short, label)


def test_shipped_paper003_study_validates_and_is_listed():
    study = load_study("paper003")
    assert study.recipe == "gradient_selection" and study.paper == "003"
    assert "paper003" in dict(list_studies())


@pytest.mark.parametrize("old, new, expected", [
    ("[correlation]", "[correlations]", "correlations: unknown key"),
    ('among = ["g.A", "g.B"', 'among = ["g.A", "g.Z"', "probe 'g.Z' is not in features.gradients"),
    ("min_abs_r = 0.5", "min_abs_r = 1.5", "min_abs_r"),
    ('test = "test"', 'test = "tset"', "value 'tset' not allowed"),
    ('proposed = "multi-point"\nbefore', 'proposed = "3-point"\nbefore',
     "must differ from traditional"),
    ("before_deg_per_h = 0.0283", "before = 0.0283", "paper_table[1].before: unknown key"),
    ("before_deg_per_h = 0.0283", "before_deg_per_h = -0.0283", "before_deg_per_h"),
    ("[0.942, 0.739, 0.647, 0.932, 0.0],", "[0.942, 0.739, 0.647, 0.932],",
     "5×5 array"),
    ('after_deg_per_h = { "3-point" = 0.0089', 'after_deg_per_h = { "4-point" = 0.0089',
     "paper_table[0].after_deg_per_h.4-point"),
    ("select = {", "choose = {", "choose: unknown key"),
])
def test_bad_study_files_are_user_errors(old, new, expected, tmp_path):
    assert old in STUDY
    path = _write(tmp_path, STUDY.replace(old, new, 1))
    with pytest.raises(UserInputError, match="study.toml") as err:
        parse_study(path.read_text(), str(path), base_dir=tmp_path)
    assert expected in str(err.value) and "\n" not in str(err.value)


def test_a_threshold_nothing_reaches_is_a_user_error(tmp_path):
    text = STUDY.replace("min_abs_r = 0.5", "min_abs_r = 0.99999").replace(
        'inputs = ["T"]\nselect', "inputs = []\nselect")
    study = load_study(str(_write(tmp_path, text)))
    with pytest.raises(UserInputError, match="no gradient among .* reaches"):
        run_study(study, tmp_path / "out", progress=False)


def test_monte_carlo_unit_draws_another_block_without_a_report(tmp_path):
    """Unit 1 draws another device and thermal network: other correlations, same row keys,
    the same result again for the same unit."""
    from rlgsim.lab.study import study_unit
    path = _write(tmp_path)
    payload = {"text": path.read_text(), "source": str(path), "name": "p003short",
               "base_dir": str(tmp_path)}
    u0, u1 = study_unit(payload, 0), study_unit(payload, 1)
    r0 = {m: v for c, m, v in u0["rows"] if c == "correlation"}
    r1 = {m: v for c, m, v in u1["rows"] if c == "correlation"}
    assert set(r0) == {f"r[{a}-{b}]" for a, b in itertools.combinations(POINTS, 2)}
    assert all(np.isfinite(v) for _, _, v in u1["rows"])
    metrics = {(c, m) for c, m, _ in u1["rows"]}
    assert ("multi-point", "stability_after@test") in metrics
    assert ("truth: temperature law", "rmse_true@train-seed3100") in metrics
    assert r1 != r0
    assert study_unit(payload, 1) == u1


@pytest.mark.skipif(not CHROMIUM.exists(), reason=SKIP_REASON)
def test_html_report_renders_in_headless_chromium(short, tmp_path):
    check_report_renders(short / "report.html", tmp_path, min_figures=6)


def test_window_series_do_not_depend_on_the_read_block(short, monkeypatch):
    """read_run reads a block of windows at a time (bounded memory); the series are the same
    bytes whatever the block size."""
    from rlgsim.sim.config import Ctx
    from rlgsim.lab import windows
    from rlgsim.lab.studies import runs
    from rlgsim.lab.studies.study_tables import FeatureSpec
    spec = FeatureSpec(100.0, None, "g.A", False, ("housing",), tuple(POINTS))
    path = short / "data" / "test.h5"
    ref = runs.read_run(path, spec, "test", Ctx("s.toml"))
    for block in (1000, 7777, 123_457):
        monkeypatch.setattr(windows, "READ_BLOCK_SAMPLES", block)
        got = runs.read_run(path, spec, "test", Ctx("s.toml"))
        for a, b in ((ref.y, got.y), (ref.true_bias, got.true_bias), (ref.time_s, got.time_s)):
            assert a.tobytes() == b.tobytes()
        assert ref.X.names == got.X.names
        assert all(ref.X[n].tobytes() == got.X[n].tobytes() for n in ref.X.names)


CHEAP = STUDY.replace('kind = "pso_svr"', 'kind = "stepwise"').replace(
    'params = { n_agents = 5, max_iter = 3, C_bounds = [0.1, 100.0] }\n', '')


def test_study_on_exported_recordings_gives_the_datasets_paper_tables(tmp_path):
    """The short study (cheap compensators) on its simulated datasets, and on the same runs
    exported as recordings (CSV and Parquet): Table 3, the selection and Tables 4-5 agree; the
    truth is absent from the recordings' report, which says why."""
    from rlgsim.lab.cli import main
    sim = tmp_path / "sim"
    run_study(load_study(str(_write(tmp_path, CHEAP))), sim, progress=False)
    for name, fmt in (("train", "csv"), ("train-seed3100", "parquet"), ("test", "csv")):
        assert main(["export", str(sim / "data" / f"{name}.h5"), "--format", fmt, "-o",
                     str(tmp_path / f"r_{name}.{fmt}"), "-q"]) == 0
    text = CHEAP.replace('train = ["train.toml"]', 'train = ["r_train.csv"]')
    text = text.replace('test = [{ scenario = "train.toml", seed = 3100 }, "test.toml"]',
                        'test = ["r_train-seed3100.parquet", "r_test.csv"]')
    text = text.replace('test = "train-seed3100"', 'test = "r_train-seed3100.parquet"')
    text = text.replace('test = "test"', 'test = "r_test.csv"')
    assert text.count("\"r_") == 5
    (tmp_path / "rec.toml").write_text(text)
    rec = tmp_path / "rec"
    assert main(["study", str(tmp_path / "rec.toml"), "-o", str(rec), "--quiet"]) == 0
    names = ["correlation_matrix.csv", "table3_figures.csv", "selection_multi_point.csv",
             "paper_table_4_verification.csv", "paper_table_5_random.csv"]
    assert sorted(p.name for p in sim.glob("paper_*.csv")) == names[3:]
    assert sorted(p.name for p in rec.glob("paper_*.csv")) == names[3:]
    for name in names:
        a, b = _csv(sim / name), _csv(rec / name)
        assert len(a) == len(b) and a and list(a[0]) == list(b[0]), name
        for ra, rb in zip(a, b):
            for k in ra:
                try:
                    va = float(ra[k]) if ra[k] else math.nan
                except ValueError:
                    assert ra[k] == rb[k], (name, k)
                    continue
                vb = float(rb[k]) if rb[k] else math.nan
                assert vb == pytest.approx(va, rel=1e-9, abs=1e-12, nan_ok=True), (name, k)
    report = (rec / "report.md").read_text()
    assert "Recorded runs (docs/recordings.md): r_train.csv" in report
    assert "Absent for r_train-seed3100.parquet, r_test.csv: recordings" in report
    assert "recording r_test.csv (no truth)" in report
    assert "no oracle floor, no truth" in report
    assert not list(rec.glob("scores_*.csv"))
    series = _csv(rec / "series_r_test_csv.csv")
    assert series and all(s["true_bias_deg_per_h"] == "nan" for s in series)
