"""Studies end to end: the demo study's report, truth scores recomputed from the dataset, bad
study files, the CLI, and the HTML report rendered by headless Chromium."""

from __future__ import annotations

import contextlib
import csv
import io
import math
import pathlib
import shutil

import h5py
import numpy as np
import pytest

from html_render import CHROMIUM, SKIP_REASON, check_report_renders
from rlgsim.lab.cli.main import main
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import list_studies, load_study, parse_study, run_study

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEG_PER_H = 180.0 / math.pi * 3600.0


@pytest.fixture(scope="module")
def demo_command(tmp_path_factory) -> tuple[pathlib.Path, str]:
    """``rlgsim demo`` run once in a fresh folder, through the command line's own entry point
    (in this process: the demo study is the suite's costliest shared set-up, so every demo test
    reads this one run; ``python -m rlgsim`` as a process is test_namespace.py's and
    test_kill.py's). Returns the report folder and what the command printed."""
    cwd = tmp_path_factory.mktemp("demo")
    printed = io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(printed):
        assert main(["demo", "--quiet"]) == 0
    return cwd / "rlgsim-demo", printed.getvalue()


@pytest.fixture(scope="module")
def demo(demo_command) -> pathlib.Path:
    """The demo study's report folder (``rlgsim demo``'s ./rlgsim-demo/)."""
    return demo_command[0]


def test_demo_runs_end_to_end(demo_command):
    out, printed = demo_command
    assert (out / "report.md").is_file() and (out / "report.html").is_file()
    assert "rlgsim-demo/report.md" in printed and "rlgsim-demo/report.html" in printed
    (train,) = (out / "data").glob("demo_cycle-seed7001.h5")
    with h5py.File(train) as f:
        assert f.attrs["scenario_name"] == "demo_cycle"
        assert f["thermal/time"].shape[0] == 8 * 3600


def _scores(folder: pathlib.Path) -> dict[str, dict[str, float]]:
    (path,) = folder.glob("scores_*.csv")
    with open(path, newline="") as fh:
        return {row["compensator"]: {k: float(v) for k, v in row.items() if k != "compensator"}
                for row in csv.DictReader(fh)}


def test_demo_writes_report_tables_and_figures(demo):
    md = (demo / "report.md").read_text()
    html = (demo / "report.html").read_text()
    for heading in ("Correlation of the bias", "Paper-style scores", "Truth-based scores",
                    "Rankings", "Regression equations", "Study file"):
        assert heading in md
    pngs = sorted(p.name for p in demo.glob("*.png"))
    assert {"bias_over_time.png", "bias_vs_temperature.png", "allan_deviation.png"} <= set(pngs)
    for name in pngs:
        assert f"({name})" in md
        assert (demo / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert html.count("src='data:image/png;base64,") == len(pngs)
    assert len(list(demo.glob("*.csv"))) >= 5
    scores = _scores(demo)
    assert {"raw", "LS cubic T", "Stepwise Model 2", "LSSVM T, dT/dt, U",
            "truth: temperature law"} <= set(scores)
    # every compensator improves on the raw bias and none beats the oracle's floor by much
    floor = scores["truth: temperature law"]["stability_after"]
    for name, s in scores.items():
        if name not in ("raw", "truth: temperature law"):
            assert s["stability_after"] < scores["raw"]["stability_after"]
            assert s["improvement_pct"] == pytest.approx(
                100 * (s["stability_before"] - s["stability_after"]) / s["stability_before"])
            assert s["stability_after"] > 0.8 * floor


def _window_means(x: np.ndarray, m: int) -> np.ndarray:
    n = x.shape[0] // m
    return x[: n * m].reshape(n, m).mean(axis=1)


def _series(path: pathlib.Path):
    """Independent re-reading of a demo dataset: measured bias y, probe T, true bias b and its
    random part r, as 100 s window means in °/h and °C."""
    with h5py.File(path, "r") as f:
        rate = float(f.attrs["sample_rate_hz"])
        step = float(f.attrs["thermal_step_s"])
        names = [n.decode() for n in f["truth/coefficient"][:]]
        k0 = float(f["truth/coefficient_value"][names.index("gyro.k0[z]")])
        lat = math.radians(float(f.attrs["latitude_deg"]))
        pulses = f["imu/gyro_pulses"][:, 0].astype(np.int64)
        probes = [p.decode() for p in f["probes/probe"][:]]
        T = f["probes/temperature"][:, probes.index("g.A")]
        b = f["truth/gyro_bias"][:, 0] * DEG_PER_H
        r = f["truth/gyro_bias_random"][:, 0] * DEG_PER_H
    ms, mt = int(round(100 * rate)), int(round(100 / step))
    n = pulses.shape[0] // ms
    y = pulses[: n * ms].reshape(n, ms).sum(axis=1) / (k0 * 100.0) * DEG_PER_H \
        - 7.292115e-5 * math.sin(lat) * DEG_PER_H          # Earth rate on an up gyro
    return y, _window_means(T, mt), _window_means(b, mt), _window_means(r, mt)


def test_truth_scores_match_an_independent_recomputation(demo):
    y_tr, T_tr, _, _ = _series(demo / "data" / "demo_cycle-seed7001.h5")
    y_te, T_te, b_te, r_te = _series(demo / "data" / "demo_cycle-seed7002.h5")
    scores = _scores(demo)
    # the oracle (true temperature law b − r) misses exactly the random part
    oracle = scores["truth: temperature law"]
    assert oracle["rmse_true"] == pytest.approx(np.sqrt(np.mean(r_te**2)), rel=1e-6)
    assert oracle["law_resid_std"] == pytest.approx(0.0, abs=1e-12)
    # LS cubic in T, refitted here with numpy.polyfit on the independently read windows
    coef = np.polyfit(T_tr, y_tr, 3)
    pred = np.polyval(coef, T_te)
    ls = scores["LS cubic T"]
    assert ls["rmse_true"] == pytest.approx(np.sqrt(np.mean((pred - b_te) ** 2)), rel=1e-6)
    assert ls["mae_true"] == pytest.approx(np.mean(np.abs(pred - b_te)), rel=1e-6)
    assert ls["resid_std_true"] == pytest.approx(np.std(pred - b_te, ddof=1), rel=1e-6)
    assert ls["stability_before"] == pytest.approx(np.std(y_te, ddof=1), rel=1e-6)
    assert ls["stability_after"] == pytest.approx(np.std(y_te - pred, ddof=1), rel=1e-6)
    ss_tot = np.sum((b_te - b_te.mean()) ** 2)
    assert ls["r2_true"] == pytest.approx(1 - np.sum((b_te - pred) ** 2) / ss_tot, rel=1e-6)


def test_rerun_reuses_matching_datasets(demo, tmp_path):
    shutil.copytree(demo / "data", tmp_path / "data")
    before = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "data").glob("*.h5")}
    run_study(load_study("demo"), tmp_path, progress=False)
    after = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "data").glob("*.h5")}
    assert before == after
    assert "(reused)" in (tmp_path / "report.md").read_text()
    assert _scores(tmp_path) == _scores(demo)


GOOD = (ROOT / "scenarios" / "studies" / "demo.toml").read_text()


@pytest.mark.parametrize("old, new, expected", [
    ("window_s = 100", "window_secs = 100", "data.window_secs: unknown key"),
    ('kind = "lssvm"', 'kind = "svm_magic"', "value 'svm_magic' not allowed"),
    ('test = [{ scenario = "demo_cycle"', 'test = [{ scenario = "no_such_cycle"',
     "unknown scenario 'no_such_cycle'"),
    ("params = { degree = 3 }", "params = { degre = 3 }", "params.degre: unknown key"),
    ('inputs = ["T"]', 'inputs = ["Tx"]', "unknown input 'Tx'"),
    ('baseline = "raw"', 'baseline = "nobody"', "value 'nobody' not allowed"),
    ("cluster_s = 100", "cluster_s = 150", "whole multiple"),
])
def test_bad_study_files_are_user_errors(old, new, expected, tmp_path):
    assert old in GOOD
    path = tmp_path / "bad.toml"
    path.write_text(GOOD.replace(old, new, 1))
    with pytest.raises(UserInputError, match="bad.toml") as err:
        load_study(str(path))
    assert expected in str(err.value)


def test_bad_parameter_value_is_a_user_error_at_fit_time(tmp_path):
    text = GOOD.replace("params = { degree = 3 }", "params = { degree = -2 }", 1)
    study = parse_study(text, "neg.toml", base_dir=ROOT / "scenarios" / "studies")
    with pytest.raises(UserInputError, match="neg.toml.*LS cubic T"):
        run_study(study, tmp_path, progress=False)


def test_cli_study_list_and_unknown(capsys):
    """``rlgsim study --list``; an unknown study is one line. (``rlgsim study PATH -o``
    runs: test_fuzz_datasets, test_kill, test_recordings; ``rlgsim demo``: the ``demo``
    fixture.)"""
    assert main(["study", "--list"]) == 0
    out = capsys.readouterr().out
    names = [n for n, _ in list_studies()]
    assert "demo" in names and "paper001" in names
    for name in names:
        assert name in out
    assert main(["study", "no_such_study"]) == 2
    assert "unknown study 'no_such_study'" in capsys.readouterr().err


@pytest.mark.skipif(not CHROMIUM.exists(), reason=SKIP_REASON)
def test_html_report_renders_in_headless_chromium(demo, tmp_path):
    check_report_renders(demo / "report.html", tmp_path, min_figures=3)


@pytest.mark.parametrize("name", ["demo", "paper001"])
def test_shipped_bias_compensation_studies_validate(name):
    study = load_study(name)
    assert study.recipe == "bias_compensation" and study.paper == "001"


def test_study_unit_draws_another_device_without_a_report():
    from rlgsim.lab.study import study_unit
    study = load_study("demo")
    payload = {"text": study.text, "source": study.source, "name": study.name,
               "base_dir": str(study.base_dir) if study.base_dir else None}
    u1, u2 = study_unit(payload, 1), study_unit(payload, 2)
    metrics = {(c, m) for c, m, _ in u1["rows"]}
    assert ("LS cubic T", "stability_after") in metrics
    assert ("truth: temperature law", "rmse_true") in metrics
    assert ("LS cubic T", "nav_radial_rate_nmi_per_h") in metrics      # the unit navigates
    assert ("truth", "nav_error_end_m") in metrics
    assert all(math.isfinite(v) for _, _, v in u1["rows"])
    assert u1["params"].keys() == u2["params"].keys()
    assert u1["params"]["gyro.bias.c1[z]"] != u2["params"]["gyro.bias.c1[z]"]
    assert study_unit(payload, 1) == u1           # a unit's result depends on (payload, unit) only


@pytest.mark.parametrize("old, new, expected", [
    ('gyro = "z"', 'gyro = "x"',
     "data.gyro: value 'x' not allowed; device 'trplg_001' has gyro axes z"),
    ('temperature = "g.A"', 'temperature = "g.Z"',
     "features.temperature: unknown probe 'g.Z'; device 'trplg_001' has g.A, g.B"),
])
def test_names_the_device_lacks_are_found_before_anything_is_simulated(old, new, expected,
                                                                       tmp_path):
    with pytest.raises(UserInputError, match="early.toml") as err:
        parse_study(GOOD.replace(old, new, 1), "early.toml",
                    base_dir=ROOT / "scenarios" / "studies")
    assert expected in str(err.value) and "\n" not in str(err.value)
    assert not list(tmp_path.iterdir())


def test_a_window_that_does_not_fit_the_data_is_a_user_error_before_simulating(tmp_path):
    text = GOOD.replace("window_s = 100", "window_s = 100.05", 1).replace(
        "cluster_s = 100", "cluster_s = 100.05", 1)
    with pytest.raises(UserInputError, match="early.toml") as err:
        parse_study(text, "early.toml", base_dir=ROOT / "scenarios" / "studies")
    assert "data.window_s: a 100.05 s window at 10.0 Hz is 1000.5 samples" in str(err.value)
    assert "scenario 'demo_cycle'" in str(err.value)


def test_report_holds_the_exact_scenario_and_preset_texts(demo):
    from rlgsim.sim.run.scenario import load_scenario
    md = (demo / "report.md").read_text()
    sc = load_scenario("demo_cycle")
    for kind, text in (("scenario demo_cycle", sc.text),
                       ("device preset trplg_001", sc.device.text),
                       (f"thermal preset {sc.device.thermal.name}", sc.device.thermal.text)):
        assert md.count(f"**{kind} (") == 1                   # train and test: shown once
        assert text.rstrip("\n") in md


def test_several_test_runs_get_their_own_scores_and_figures(tmp_path):
    text = GOOD.replace('test = [{ scenario = "demo_cycle", seed = 7002 }]',
                        'test = [{ scenario = "demo_cycle", seed = 7002 }, '
                        '{ scenario = "demo_cycle", seed = 7003 }]')
    assert text != GOOD
    study = parse_study(text, "two.toml", base_dir=ROOT / "scenarios" / "studies")
    run_study(study, tmp_path, progress=False)
    for label in ("demo_cycle_seed7002", "demo_cycle_seed7003"):
        assert (tmp_path / f"scores_{label}.csv").is_file()
        for fig in ("bias_over_time", "bias_vs_temperature", "allan_deviation"):
            assert (tmp_path / f"{fig}_{label}.png").stat().st_size > 10_000
    md = (tmp_path / "report.md").read_text()
    assert "Test run demo_cycle-seed7003. Top:" in md


def test_an_edited_device_or_thermal_preset_is_simulated_again(tmp_path):
    """The one dataset fingerprint (every recipe, paper 000's included): a dataset is reused
    only while the scenario, device preset and thermal preset texts are those it was made from."""
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.lab.studies.runs import simulated_dataset

    shipped = ROOT / "scenarios"
    device = (shipped / "devices" / "trplg_001.toml").read_text()
    assert 'thermal_preset = "trplg_001_cabinet"' in device
    (tmp_path / "dev.toml").write_text(device.replace('thermal_preset = "trplg_001_cabinet"',
                                                      'thermal_preset = "therm.toml"'))
    (tmp_path / "therm.toml").write_text(
        (shipped / "thermal" / "trplg_001_cabinet.toml").read_text())
    (tmp_path / "run.toml").write_text(
        'name = "run"\ndevice = "dev.toml"\nseed = 5\n[acquisition]\nsample_rate_hz = 10\n'
        '[power]\non_at_s = 0\n[chamber]\nstart_c = 25.0\n[[chamber.segments]]\n'
        'type = "hold"\nduration_h = 0.1\n')
    path = tmp_path / "data" / "run.h5"

    def reused() -> bool:
        return simulated_dataset(load_scenario(str(tmp_path / "run.toml")), path,
                                 progress=False)[1]

    assert not reused() and reused()
    for preset in ("dev.toml", "therm.toml", "run.toml"):
        f = tmp_path / preset
        f.write_text(f.read_text() + "\n# edited: same numbers, another text\n")
        assert not reused(), preset
        assert reused(), preset


def test_a_recipe_without_a_report_hook_gets_its_score_rows(tmp_path, monkeypatch):
    import types

    from rlgsim.lab import study as runner
    from rlgsim.lab.study import Study, StudyResult

    def run(study, config, workdir, *, unit, progress):
        return StudyResult(rows=[("model", "rmse_true", 0.25)])

    recipe = types.SimpleNamespace(check=lambda study: None, run=run)
    monkeypatch.setattr(runner, "recipe_module", lambda study: recipe)
    study = Study(name="bare", description="no hook", paper="", recipe="bare",
                  source="bare.toml", text="[study]\n", base_dir=None)
    md = run_study(study, tmp_path, progress=False).read_text()
    assert "Study bare" in md and "Study file" in md
    assert (tmp_path / "scores.csv").read_text().splitlines()[1:] == ["model,rmse_true,0.25"]


def test_demo_navigation_section(demo):
    """The gyro navigates in an IMU of three such gyros (docs/navigation.md): raw, every
    compensator (fitted per unit), the gyro oracle and the truth floor, with a reason per
    ranking; the two drawn units' runs sit beside the study's datasets."""
    import csv
    with open(demo / "navigation.csv", newline="") as fh:
        rows = {r["variant"]: r for r in csv.DictReader(fh)}
    assert list(rows) == ["raw", "LS cubic T", "LS cubic U", "Stepwise Model 2",
                          "LSSVM T, dT/dt, U", "oracle (gyros)", "truth"]
    rate = {k: float(r["radial rate [nmi/h]"]) for k, r in rows.items()}
    assert rate["truth"] < 1e-6 < rate["oracle (gyros)"]
    # the gyro oracle removes the temperature law the compensators estimate: less residual
    # gyro error than the raw gyro, and than every compensator (its rest is the random part)
    resid = {k: float(r["residual gyro error [°/h]"]) for k, r in rows.items()}
    assert all(resid["oracle (gyros)"] <= resid[k] for k in resid if k != "truth")
    md = (demo / "report.md").read_text()
    assert md.count("ranks before") == len(rows) - 1 and "(navigation.png)" in md
    assert "IMU of three such gyros" in md
    assert len(list((demo / "data").glob("*-unit1048576.h5"))) == 2      # train and test
