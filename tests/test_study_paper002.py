"""The ``environments`` recipe (src/rlgsim/lab/studies/environments.py) and the shipped paper002 study.

A short two-environment study (constant 20 °C and a 5 °C/min cycle, 2.5 h at 10 Hz each, train
and test seeds, the rlg_002 device) runs once per module; the tests check its report and
Table 1, recompute its truth-based scores from the HDF5 files with h5py/numpy alone, check
that a study's rows depend on the study and the unit only, and that mistakes in study files
are one-line user errors naming the key.
"""

from __future__ import annotations

import csv
import math
import pathlib

import h5py
import numpy as np
import pytest

from independent_windows import read_windows
from html_render import CHROMIUM, SKIP_REASON, check_report_renders
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import list_studies, load_study, parse_study, recipe_module, run_study, study_unit

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEG_PER_H = 180.0 / math.pi * 3600.0
WINDOW_S = 100.0
SKIP_S = 1800.0

CONST = """
name = "p002_short_const"
device = "rlg_002"
seed = 1
duration_h = 2.5
[acquisition]
sample_rate_hz = 10
thermal_step_s = 1
[power]
on_at_s = 0
[chamber]
start_c = 20.0
[[chamber.segments]]
type = "hold"
duration_h = 2.5
"""

CYCLE = """
name = "p002_short_cycle"
device = "rlg_002"
seed = 2
duration_h = 2.5
[acquisition]
sample_rate_hz = 10
thermal_step_s = 1
[power]
on_at_h = 0.5
[chamber]
start_c = 0.0
[[chamber.segments]]
type = "hold"
duration_h = 0.5
[[chamber.segments]]
type = "repeat"
count = 3
segments = [
  { type = "ramp", to_c = 40.0, rate_c_per_min = 5.0 },
  { type = "hold", duration_min = 10 },
  { type = "ramp", to_c = -10.0, rate_c_per_min = 5.0 },
  { type = "hold", duration_min = 10 },
]
"""

STUDY = """
[study]
name = "p002_short"
description = "short paper-002-like study for the tests"
paper = "002"
recipe = "environments"
device_seed = 2002

[data]
window_s = 100

[features]
temperature = "g.A"

[metrics]
cluster_s = 100
ddof = 1

[[compensator]]
name = "MLR"
kind = "mlr_bic"
inputs = ["T", "dT/dt"]
params = { candidate_terms = ["T", "dT/dt"], forced_terms = ["T", "dT/dt"] }
published = { equation = "constant + T + dT/dt" }

[[compensator]]
name = "RBFNN"
kind = "rbf"
inputs = ["T", "dT/dt"]
params = { goal = 1e-6, spread = 1.0, max_centers = 30 }

[[compensator]]
name = "Modified RBFNN"
kind = "rbf_modified"
inputs = ["T", "dT/dt"]
params = { rho = 0.05, spread = 1.0 }

[[environment]]
name = "20 °C"
train = [{ scenario = "const.toml", seed = 11, skip_h = 0.5 }]
test = [{ scenario = "const.toml", seed = 12, skip_h = 0.5 }]
[environment.published]
stability_before_deg_per_h = 6.796e-3
stability_after_deg_per_h = { "MLR" = 13.953e-4, "RBFNN" = 8.944e-4, "Modified RBFNN" = 6.922e-4 }
improvement_factor = { "MLR" = 4.87, "RBFNN" = 7.60, "Modified RBFNN" = 9.82 }
running_time_s = { "RBFNN" = 142.4, "Modified RBFNN" = 82.6 }

[[environment]]
name = "5 °C/min"
train = [{ scenario = "cycle.toml", seed = 21, skip_h = 0.5 }]
test = [{ scenario = "cycle.toml", seed = 22, skip_h = 0.5 }]
"""

METHODS = ("MLR", "RBFNN", "Modified RBFNN")


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> pathlib.Path:
    """Study file and its two scenarios in one folder (scenario paths are relative to it)."""
    d = tmp_path_factory.mktemp("p002_files")
    (d / "const.toml").write_text(CONST)
    (d / "cycle.toml").write_text(CYCLE)
    (d / "study.toml").write_text(STUDY)
    return d


@pytest.fixture(scope="module")
def study(folder):
    return load_study(str(folder / "study.toml"))


@pytest.fixture(scope="module")
def ran(study, tmp_path_factory) -> pathlib.Path:
    out = tmp_path_factory.mktemp("p002_run")
    assert run_study(study, out, progress=False) == out / "report.md"
    return out


def _csv(path: pathlib.Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _num(cell: str) -> float | None:
    return float(cell) if cell != "" else None


# ------------------------------------------------------------------------------ shipped study
def test_shipped_paper002_validates_and_lists():
    study = load_study("paper002")
    assert (study.recipe, study.paper, study.device_seed) == ("environments", "002", 2002)
    cfg = recipe_module(study).check(study)
    assert [e.name for e in cfg.environments] == ["-40 °C", "20 °C", "60 °C", "1 °C/min",
                                                  "3 °C/min", "5 °C/min"]
    assert [c.kind for c in cfg.compensators] == ["mlr_bic", "rbf", "rbf_modified"]
    assert cfg.window_s == 100.0 and cfg.cluster_s == 100.0 and cfg.temperature == "g.A"
    seeds = []
    for env in cfg.environments:
        (train,), (test,) = env.train, env.test
        assert train.ref == test.ref and train.seed != test.seed      # data sets 1 and 2
        assert train.skip_s == test.skip_s == 3600.0                  # the 1 h warm-up
        seeds += [train.seed, test.seed]
    assert len(set(seeds)) == 12
    m40, c5 = cfg.environments[0].published, cfg.environments[5].published
    assert m40.stability_before == pytest.approx(7.218e-3)
    assert m40.stability_after["MLR (BIC)"] == pytest.approx(13.953e-4)
    assert m40.improvement_factor["Modified RBFNN"] == pytest.approx(10.43)
    assert "MLR (BIC)" not in m40.running_time_s                     # "—" in the paper
    assert c5.improvement_factor["RBFNN"] == pytest.approx(7.61)
    # Table 1 is before/after: its factors agree with its own σ to the printed digits
    for env in cfg.environments:
        p = env.published
        for name, after in p.stability_after.items():
            assert p.stability_before / after == pytest.approx(p.improvement_factor[name],
                                                               rel=0.03)
    listed = dict(list_studies())
    assert "paper002" in listed and "modified RBFNN" in listed["paper002"]


# ------------------------------------------------------------------------------ bad files
GOOD = (ROOT / "scenarios" / "studies" / "paper002.toml").read_text()
LAST_ENV = GOOD.index('[[environment]]\nname = "5 °C/min"')


@pytest.mark.parametrize("old, new, expected", [
    ("window_s = 100", "window_secs = 100", "data.window_secs: unknown key"),
    ('name = "20 °C"\ntrain', 'name = "20 °C"\ntrian', "environment[1].trian: unknown key"),
    ('inputs = ["T", "dT/dt"]\nparams = { degree = 2 }',
     'inputs = ["T", "dT/dx"]\nparams = { degree = 2 }', "unknown input 'dT/dx'"),
    ("stability_before_deg_per_h = 7.218e-3", "stability_before_deg_per_h = -7.218e-3",
     "environment[0].published.stability_before_deg_per_h: value -0.007218 not allowed"),
    ("stability_before_deg_per_h = 7.218e-3", 'stability_before_deg_per_h = "7.218e-3"',
     "environment[0].published.stability_before_deg_per_h: expected a number"),
    ('improvement_factor = { "MLR (BIC)" = 5.17',
     'improvement_factor = { "MLR" = 5.17',
     "environment[0].published.improvement_factor.MLR: unknown key"),
    ('running_time_s = { "RBFNN" = 140.8', 'running_time_s = { "RBFNN" = -140.8',
     "environment[0].published.running_time_s.RBFNN: value -140.8 not allowed"),
    ('name = "60 °C"', 'name = "20 °C"', "environment '20 °C' is named twice"),
    ('name = "60 °C"', 'name = "60@C"', "environment[2].name: value '60@C' not allowed"),
    ('seed = 2201', 'seed = "2201"', "environment[0].test[0].seed: expected an integer"),
    ('scenario = "paper002_const_60", seed = 2103',
     'scenario = "paper002_const_70", seed = 2103', "unknown scenario 'paper002_const_70'"),
    ("ddof = 1", "ddof = 2", "metrics.ddof: value 2 not allowed"),
    ('published_before = "mean"', 'published_before = "median"',
     "metrics.published_before: value 'median' not allowed"),
])
def test_bad_study_files_are_one_line_user_errors(old, new, expected, tmp_path):
    assert old in GOOD
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new, 1))
    with pytest.raises(UserInputError) as err:
        load_study(str(path))
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and "\n" not in msg
    assert expected in msg


def test_missing_environments_and_compensators_are_user_errors(tmp_path):
    no_env = GOOD[:GOOD.index("[[environment]]")]
    path = tmp_path / "noenv.toml"
    path.write_text(no_env)
    with pytest.raises(UserInputError, match=r"noenv.toml: environment: missing: give at "
                                             r"least one \[\[environment\]\]"):
        load_study(str(path))
    one_env = GOOD[:LAST_ENV]
    start = one_env.index("[[compensator]]")
    end = one_env.index("# ------", start)
    path.write_text(one_env[:start] + one_env[end:])
    with pytest.raises(UserInputError, match="compensator: missing"):
        load_study(str(path))


# ------------------------------------------------------------------------------ the run
def test_report_files_and_table1_rows(ran):
    md = (ran / "report.md").read_text()
    html = (ran / "report.html").read_text()
    for heading in ("Runs, seeds and software", "Definitions", "Table 1 re-created",
                    "Truth-based scores", "Rankings: the paper's claims against ours", "Why",
                    "Figures", "Study file"):
        assert heading in md
    for fig in ("bias_over_time.png", "bias_vs_temperature.png", "allan_deviation.png",
                "navigation.png"):
        assert (ran / fig).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"({fig})" in md
    assert html.count("src='data:image/png;base64,") == 4
    assert "Navigation: free-inertial position and heading errors" in md
    nav = _csv(ran / "navigation.csv")              # every environment, every variant
    assert {r["environment"] for r in nav} == {"20 °C", "5 °C/min"}
    assert len(nav) == 2 * len({r["variant"] for r in nav})
    rows = _csv(ran / "table1.csv")
    cols = list(rows[0])
    assert cols == ["quantity", "method", "20 °C ours", "20 °C paper", "5 °C/min ours",
                    "5 °C/min paper"]
    keyed = {(r["quantity"], r["method"]): r for r in rows}
    before = keyed[("before σ (×10⁻³ °/h)", "raw")]
    assert _num(before["20 °C paper"]) == pytest.approx(6.796)
    assert before["5 °C/min paper"] == ""                          # no published numbers
    for m in METHODS:
        after = keyed[("after σ (×10⁻⁴ °/h)", m)]
        factor = keyed[("improvement factor (before/after)", m)]
        timing = keyed[("running time (s)", m)]
        for env in ("20 °C", "5 °C/min"):        # ours: factor = before / after
            assert _num(factor[f"{env} ours"]) == pytest.approx(
                _num(before[f"{env} ours"]) * 10 / _num(after[f"{env} ours"]), rel=1e-9)
            assert 0 < _num(timing[f"{env} ours"]) < 60
    assert _num(keyed[("improvement factor (before/after)", "Modified RBFNN")]
                ["20 °C paper"]) == pytest.approx(9.82)
    assert keyed[("running time (s)", "MLR")]["20 °C paper"] == ""
    assert ("after σ (×10⁻⁴ °/h)", "truth: temperature law") in keyed
    # the before check, the ranking table and the generated verdicts
    check = {r["environment"]: r for r in _csv(ran / "before_check.csv")}
    assert _num(check["20 °C"]["ours / paper"]) == pytest.approx(
        _num(before["20 °C ours"]) / 6.796, rel=1e-6)
    claims = _csv(ran / "ranking_checks.csv")
    assert {c["claim (paper)"] for c in claims} == {"modified RBFNN ≥ RBFNN", "RBFNN > MLR",
                                                    "modified RBFNN > MLR"}
    assert all(c["by σ after"] in ("holds", "holds (tie)", "tie", "does NOT hold")
               for c in claims)
    assert "Paper: RBFNN > MLR. Ours: holds by bias stability in" in md
    fits = {(r["environment"], r["compensator"]): r for r in _csv(ran / "fitted_models.csv")}
    assert fits[("20 °C", "MLR")]["terms / centres"] == "1 + T + dT/dt"     # forced terms
    assert len(_csv(ran / "spread_sensitivity.csv")) == 2 * 4


def _series(path: pathlib.Path) -> dict[str, np.ndarray]:
    """Independent re-reading (tests/independent_windows.py): the 100 s windows that start at
    or after SKIP_S with the gyro powered throughout — measured bias y, window-mean T and its
    least-squares slope (probe g.A), true bias b and its random part r."""
    w = read_windows(path, WINDOW_S, skip_s=SKIP_S, slope_of="g.A")
    return {"y": w["y"], "T": w["probes"]["g.A"], "dTdt": w["slope"], "b": w["b"], "r": w["r"]}


def test_truth_scores_match_an_independent_recomputation(ran):
    table = {(r["environment"], r["compensator"]): {k: _num(v) for k, v in r.items()
                                                    if k not in ("environment", "compensator")}
             for r in _csv(ran / "truth_scores.csv")}
    for env, stem in (("20 °C", "const"), ("5 °C/min", "cycle")):
        train = _series(ran / "data" / f"{stem}-seed{11 if stem == 'const' else 21}.h5")
        test = _series(ran / "data" / f"{stem}-seed{12 if stem == 'const' else 22}.h5")
        assert test["y"].size == 72                                # 2 h of 100 s windows
        raw = float(np.std(test["y"], ddof=1))
        # MLR with forced terms: constant + T + dT/dt by numpy least squares
        A = np.column_stack([np.ones_like(train["T"]), train["T"], train["dTdt"]])
        coef, *_ = np.linalg.lstsq(A, train["y"], rcond=None)
        pred = np.column_stack([np.ones_like(test["T"]), test["T"], test["dTdt"]]) @ coef
        mlr = table[(env, "MLR")]
        assert mlr["stability_before"] == pytest.approx(raw, rel=1e-6)
        assert mlr["stability_after"] == pytest.approx(np.std(test["y"] - pred, ddof=1),
                                                       rel=1e-6)
        assert mlr["improvement_factor"] == pytest.approx(
            raw / np.std(test["y"] - pred, ddof=1), rel=1e-6)
        assert mlr["rmse_true"] == pytest.approx(np.sqrt(np.mean((pred - test["b"]) ** 2)),
                                                 rel=1e-6)
        assert mlr["resid_std_true"] == pytest.approx(np.std(pred - test["b"], ddof=1),
                                                      rel=1e-6)
        assert mlr["law_resid_std"] == pytest.approx(
            np.std(pred - (test["b"] - test["r"]), ddof=1), rel=1e-6)
        # the oracle misses exactly the random part; raw predicts the train mean
        oracle = table[(env, "truth: temperature law")]
        assert oracle["rmse_true"] == pytest.approx(np.sqrt(np.mean(test["r"] ** 2)), rel=1e-6)
        assert oracle["stability_after"] == pytest.approx(
            np.std(test["y"] - (test["b"] - test["r"]), ddof=1), rel=1e-6)
        assert oracle["law_resid_std"] == pytest.approx(0.0, abs=1e-12)
        assert table[(env, "raw")]["rmse_true"] == pytest.approx(
            np.sqrt(np.mean((np.mean(train["y"]) - test["b"]) ** 2)), rel=1e-6)
    # the noise budget's white part from the truth's per-sample sigma: σ·√m / W
    with h5py.File(ran / "data" / "const-seed12.h5", "r") as f:
        sigma = float(f["truth/gyro_white_sigma"][0])
    budget = {r["environment"]: r for r in _csv(ran / "noise_budget.csv")}
    assert _num(budget["20 °C"]["white per window"]) == pytest.approx(
        sigma * math.sqrt(1000) / WINDOW_S * DEG_PER_H, rel=1e-9)


def test_rows_depend_on_study_and_unit_only(study, folder, tmp_path):
    recipe = recipe_module(study)
    cfg = recipe.check(study)
    res = recipe.run(study, cfg, tmp_path / "a", unit=0, progress=False)   # run: no report
    assert not list((tmp_path / "a").glob("*.md"))
    metrics = {(c, m) for c, m, _ in res.rows}
    for env in ("20 °C", "5 °C/min"):
        for name in METHODS + ("raw", "truth: temperature law"):
            assert (name, f"improvement_factor@{env}") in metrics
            assert (name, f"resid_std_true@{env}") in metrics
    assert not any(m.startswith("fit_s") for _, m in metrics)     # no wall times in rows
    assert all(math.isfinite(v) for _, _, v in res.rows)
    payload = {"text": study.text, "source": study.source, "name": study.name,
               "base_dir": str(folder)}
    again = study_unit(payload, 0)                      # fresh folder: simulated again
    # the unit's rows: the recipe's, then its navigation scores (docs/navigation.md)
    n = len(res.rows)
    assert again["rows"][:n] == res.rows and again["params"] == res.params
    nav = again["rows"][n:]
    assert nav and all(m.startswith("nav_") and math.isfinite(v) for _, m, v in nav)
    assert {c for c, _, _ in nav} == {"raw", *METHODS, "oracle (gyros)", "truth"}
    assert {m.split("@")[1] for _, m, _ in nav} == {"20 °C", "5 °C/min"}   # every environment
    other = study_unit(payload, 1)                      # Monte Carlo unit: another device
    assert other["params"].keys() == res.params.keys()
    assert other["params"]["gyro.bias.c1[x]"] != res.params["gyro.bias.c1[x]"]
    assert [(c, m) for c, m, _ in other["rows"]] == [(c, m) for c, m, _ in again["rows"]]


def test_table1_read_as_mean_before_sigma_after(folder, tmp_path):
    """published_before = "mean" (paper 002's reading, docs/studies.md): the reading's table
    holds the test run's mean raw bias, σ after on the test and train runs and |mean|/σ,
    recomputed here from the HDF5 files with numpy alone."""
    from rlgsim.lab.studies.environments_reading import reading_table, reading_text
    text = STUDY.replace("ddof = 1", 'ddof = 1\npublished_before = "mean"', 1)
    study = parse_study(text, str(folder / "mean.toml"), base_dir=folder)
    recipe = recipe_module(study)
    cfg = recipe.check(study)
    assert cfg.published_before == "mean"
    res = recipe.run(study, cfg, tmp_path, unit=0, progress=False)
    r = res.details.results[0]                                        # 20 °C, published
    table = reading_table(res.details.results, cfg)
    rec = dict(zip(table.columns, table.rows[0]))
    test = _series(r.tests[0].path)
    mean = float(np.mean(test["y"]))
    assert rec["ours: mean, test (×10⁻³ °/h)"] == pytest.approx(1e3 * mean, rel=1e-9)
    after = rec["ours σ after, test (×10⁻⁴ °/h)"] * 1e-4
    assert after == pytest.approx(r.scores["MLR"]["stability_after"], rel=1e-9)
    assert rec["ours factor, test"] == pytest.approx(abs(mean) / after, rel=1e-9)
    assert rec["paper factor"] == pytest.approx(4.87)
    assert rec["paper before: mean (×10⁻³ °/h)"] == pytest.approx(6.796)
    train = _series(r.train[0].path)
    assert rec["ours factor, in-sample"] == pytest.approx(
        abs(np.mean(train["y"])) / r.train_after["MLR"], rel=1e-9)
    assert len(table.rows) == 2 * len(METHODS)
    assert any(p.startswith("Read as the mean zero bias") for p in reading_text(
        res.details.results, cfg))


def test_reading_evidence_from_the_published_numbers():
    """The reading's evidence lines on the shipped study's published numbers: every factor is
    before/after (18 pairs); the expected range of k normal draws against the analytic 2/√π
    for k = 2 and a 200 000-sample Monte Carlo for k = 6 (its standard error ≈ 0.002)."""
    from types import SimpleNamespace
    from rlgsim.lab.studies.environment_tables import parse_config
    from rlgsim.lab.studies.environments_reading import evidence, expected_range
    assert expected_range(2) == pytest.approx(2.0 / math.sqrt(math.pi), rel=1e-8)
    draws = np.random.default_rng(1).standard_normal((200_000, 6))
    mc = float(np.mean(draws.max(axis=1) - draws.min(axis=1)))
    assert expected_range(6) == pytest.approx(mc, abs=0.01)
    cfg = parse_config(load_study("paper002"))
    res = [SimpleNamespace(env=e, tests=[SimpleNamespace(y=np.zeros(288))])
           for e in cfg.environments]
    lines = evidence(res)
    assert "(18 pairs, largest difference 0.11 %" in lines[0]
    assert "MLR (BIC) 2.30 %" in lines[1] and "spread by 10.6 %" in lines[1]


def test_several_test_runs_give_per_run_rows_and_their_mean(folder, tmp_path):
    text = STUDY.replace('test = [{ scenario = "cycle.toml", seed = 22, skip_h = 0.5 }]',
                         'test = [{ scenario = "cycle.toml", seed = 22, skip_h = 0.5 }, '
                         '{ scenario = "cycle.toml", seed = 23, skip_h = 0.5 }]')
    study = parse_study(text, str(folder / "two.toml"), base_dir=folder)
    recipe = recipe_module(study)
    res = recipe.run(study, recipe.check(study), tmp_path, unit=0, progress=False)
    rows = {(c, m): v for c, m, v in res.rows}
    a = rows[("MLR", "stability_after@5 °C/min:cycle-seed22")]
    b = rows[("MLR", "stability_after@5 °C/min:cycle-seed23")]
    assert a != b
    assert rows[("MLR", "stability_after@5 °C/min")] == pytest.approx((a + b) / 2, rel=1e-12)
    assert not any(m.startswith("stability_after@20 °C:") for _, m in rows)


def test_a_bad_parameter_value_is_a_user_error_at_fit_time(folder, tmp_path):
    text = STUDY.replace("rho = 0.05", "rho = 1.5")
    study = parse_study(text, "badrho.toml", base_dir=folder)
    with pytest.raises(UserInputError, match="badrho.toml: compensator\\[2\\].params: "
                                             "compensator 'Modified RBFNN'"):
        run_study(study, tmp_path, progress=False)


@pytest.mark.skipif(not CHROMIUM.exists(), reason=SKIP_REASON)
def test_html_report_renders_in_headless_chromium(ran, tmp_path):
    check_report_renders(ran / "report.html", tmp_path, min_figures=3)


def test_study_on_exported_recordings_gives_the_datasets_paper_tables(tmp_path):
    """The short study (deterministic compensators: MLR and the traditional RBFNN) on its
    simulated datasets, and on the same runs exported as recordings (CSV and Parquet): Table 1
    (but the wall times), the before check, the ranking by σ and the fitted models agree; the
    truth (the oracle row, std(ŷ − b)) is absent from the recordings' and the report says why."""
    from rlgsim.lab.cli import main
    text = STUDY[:STUDY.index('[[compensator]]\nname = "Modified RBFNN"')] + \
        STUDY[STUDY.index("[[environment]]"):]
    text = text.replace('"Modified RBFNN" = 6.922e-4', '').replace(
        '"Modified RBFNN" = 9.82', '').replace('"Modified RBFNN" = 82.6', '').replace(",  }", " }")
    (tmp_path / "const.toml").write_text(CONST)
    (tmp_path / "cycle.toml").write_text(CYCLE)
    (tmp_path / "study.toml").write_text(text)
    sim = tmp_path / "sim"
    run_study(load_study(str(tmp_path / "study.toml")), sim, progress=False)
    for sc, a, b in (("const", 11, 12), ("cycle", 21, 22)):
        for seed, role, fmt in ((a, "train", "csv"), (b, "test", "parquet")):
            assert main(["export", str(sim / "data" / f"{sc}-seed{seed}.h5"), "--format", fmt,
                         "-o", str(tmp_path / f"{sc}{seed}.{fmt}"), "-q"]) == 0
            text = text.replace(f'{role} = [{{ scenario = "{sc}.toml", seed = {seed}, ',
                                f'{role} = [{{ scenario = "{sc}{seed}.{fmt}", ')
    assert text.count(".csv") == 2 and text.count(".parquet") == 2
    (tmp_path / "rec.toml").write_text(text)
    rec = tmp_path / "rec"
    assert main(["study", str(tmp_path / "rec.toml"), "-o", str(rec), "--quiet"]) == 0
    for name in ("table1.csv", "before_check.csv", "ranking_checks.csv", "fitted_models.csv"):
        a, b = _csv(sim / name), _csv(rec / name)
        assert len(a) == len(b) and a and list(a[0]) == list(b[0]), name
        for ra, rb in zip(a, b):
            if ra.get("quantity") == "running time (s)":
                continue                                    # wall time
            for k in ra:
                if "fit time" in k:
                    continue
                if (ra.get("method") == ORACLE_NAME and k.endswith(" ours")) \
                        or "std(ŷ − b)" in k or k == "by the truth":   # no truth in a recording
                    assert rb[k] in ("", "—"), (name, k, rb[k])
                    continue
                try:
                    va = float(ra[k])
                except ValueError:
                    assert ra[k] == rb[k], (name, k)
                    continue
                assert float(rb[k]) == pytest.approx(va, rel=1e-9), (name, k)
    assert not (rec / "truth_scores.csv").exists() and not (rec / "noise_budget.csv").exists()
    md = (rec / "report.md").read_text()
    assert "Recorded runs (docs/recordings.md): const11.csv, const12.parquet" in md
    assert "Absent for 20 °C, 5 °C/min: the test runs are recordings" in md
    assert "recording cycle22.parquet (no truth)" in md
    assert "Paper: RBFNN > MLR. Ours: holds by bias stability in" in md
    assert "no truth (recordings)" in md


ORACLE_NAME = "truth: temperature law"
