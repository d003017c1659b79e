"""``rlgsim study --export-models`` / ``[study] export_models = true``: every fitted compensator
of a study as models/<name>.json, .c and .h in the report folder, listed in the report."""

from __future__ import annotations

import shutil
import subprocess
import warnings

import numpy as np
import pytest

from rlgsim.estimators.model_export import OutOfTrainingRangeWarning, load_json
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.main import main
from rlgsim.sim.presets import load
from rlgsim.lab.study import parse_study


@pytest.fixture(scope="module")
def demo_export(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo-export")
    assert main(["study", "demo", "-o", str(out), "--quiet", "--export-models"]) == 0
    return out


def _demo_text(extra: str) -> str:
    return load("demo", "study").text.replace('device_seed = 1001\n',
                                               f'device_seed = 1001\n{extra}\n', 1)


def test_every_compensator_is_exported_and_listed(demo_export):
    study = parse_study(_demo_text(""), "demo.toml")
    names = [c["name"] for c in study.tables["compensator"]]
    models = demo_export / "models"
    jsons = sorted(models.glob("*.json"))
    assert len(jsons) == len(names)
    assert {load_json(p).name_ for p in jsons} == set(names)
    for p in jsons:
        assert p.with_suffix(".c").is_file() and p.with_suffix(".h").is_file()
    md = (demo_export / "report.md").read_text()
    assert "## Exported compensators" in md and "models/ls_cubic_t.json" in md
    assert (demo_export / "exported_models.csv").is_file()


def test_exported_model_has_study_units_and_predicts_inside_its_range(demo_export):
    m = load_json(demo_export / "models" / "stepwise_model_2.json")
    assert m.input_names_ == ("T", "dT/dt", "U")
    assert m.input_units_ == ("°C", "K/s", "V")
    assert (m.target_, m.target_unit_) == ("bias", "°/h")
    inside = np.column_stack([np.linspace(lo, hi, 7) for lo, hi in
                              zip(m.train_min_, m.train_max_)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", OutOfTrainingRangeWarning)
        y = m.predict(inside)
    assert np.all(np.isfinite(y)) and np.all(np.abs(y) < 1.0)      # °/h: a gyro bias
    with pytest.warns(OutOfTrainingRangeWarning, match="T "):
        m.predict(inside + np.array([50.0, 0.0, 0.0]))


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")
def test_exported_c_compiles_as_written(demo_export, tmp_path):
    for c in sorted((demo_export / "models").glob("*.c")):
        res = subprocess.run(["cc", "-std=c99", "-Wall", "-Werror", "-c", str(c), "-o",
                              str(tmp_path / (c.stem + ".o"))], capture_output=True, text=True)
        assert res.returncode == 0, res.stderr


def test_study_file_key(tmp_path):
    assert parse_study(_demo_text("export_models = true"), "demo.toml").export_models
    assert not parse_study(_demo_text(""), "demo.toml").export_models
    with pytest.raises(UserInputError, match="demo.toml: study.export_models"):
        parse_study(_demo_text('export_models = "yes"'), "demo.toml")


def _fitted(name: str, kind: str, inputs, seed: int = 0):
    """A ``Fitted``-like record of a small polynomial fit (spec, model, X_train)."""
    from types import SimpleNamespace

    from rlgsim.estimators.columns import Columns
    from rlgsim.estimators.polynomial import PolynomialRegressor
    rng = np.random.default_rng(seed)
    X = Columns({n: rng.uniform(-1, 1, 30) for n in inputs})
    y = X.values.sum(axis=1) + rng.normal(0, 0.01, 30)
    return SimpleNamespace(spec=SimpleNamespace(name=name, kind=kind, inputs=tuple(inputs)),
                           model=PolynomialRegressor(degree=1).fit(X, y), X_train=X)


def test_recipe_hooks_hand_over_every_fitted_model(tmp_path):
    from types import SimpleNamespace

    from rlgsim.lab.studies import environments, gradient_selection, paper000_system
    from rlgsim.lab.study_models import write_models
    f = [_fitted("LS (T)", "polynomial", ["T"]), _fitted("grad", "polynomial", ["A-B", "C"])]
    got = gradient_selection.fitted_models(None, SimpleNamespace(details=SimpleNamespace(
        fitted=f)))
    assert [m.name for m in got] == ["LS (T)", "grad"] and got[1].inputs == ("A-B", "C")
    envs = SimpleNamespace(details=SimpleNamespace(results=[
        SimpleNamespace(env=SimpleNamespace(name=e), fitted=f[:1]) for e in ("-40 C", "1 C/min")]))
    assert [m.name for m in environments.fitted_models(None, envs)] == \
        ["-40 C LS (T)", "1 C/min LS (T)"]
    lsm = f[0].model
    p0 = SimpleNamespace(details=SimpleNamespace(
        fitted={"gyro_bias_x": (lsm, lsm, 0.0)}, xs={"gyro_bias_x": f[0].X_train["T"]},
        units={"gyro_bias_x": "°/h"}))
    got = paper000_system.fitted_models(None, p0)
    assert [(m.name, m.kind, m.target_unit) for m in got] == [
        ("HHO-RVR gyro_bias_x", "hho_rvr", "°/h"), ("cubic LSM gyro_bias_x", "polynomial", "°/h")]
    records = write_models(got[1:], tmp_path)
    loaded = load_json(tmp_path / records[0]["JSON"].split("/")[-1])
    assert loaded.input_names_ == ("T",) and loaded.input_units_ == ("°C",)
    assert loaded.target_ == "gyro_bias_x"


def test_report_notes_only_where_they_apply(demo_export):
    """The LS-SVM note under the LSSVM table only; no IR-LSSVM note without IR-LSSVM."""
    md = (demo_export / "report.md").read_text()

    def note_after(title: str) -> str:
        rest = md[md.index(f"**{title}**"):]
        return next(line for line in rest.splitlines() if line.startswith("*paper:"))

    assert "LS-SVM regularisation" not in note_after("Least squares (paper 001 Table 2)")
    assert "LS-SVM regularisation" in note_after("LSSVM (paper 001 §4.3)")
    assert "IR-LSSVM: (c, σ²)" not in md


def test_device_coefficients_carry_the_presets_units(demo_export):
    import csv
    with open(demo_export / "device_coefficients.csv", encoding="utf-8") as fh:
        rows = {r["coefficient"]: r for r in csv.DictReader(fh)}
    arw = rows["noise.gyro_arw[z]"]
    assert arw["unit"] == "°/√h"                       # the preset key gyro_arw_deg_per_sqrt_h
    assert 0.0005 < float(arw["value"]) < 0.0011       # trplg_001: 0.0008 ± 10 % (1σ)
    assert rows["gyro.bias.c1[z]"]["unit"] == "°/h/K"
    assert all(r["unit"] for r in rows.values())
    assert "rad/s" not in (demo_export / "report.md").read_text()


def test_allan_figure_starts_at_the_sample_rate(demo_export):
    import pathlib

    from rlgsim.estimators.metrics import allan_deviation
    from rlgsim.lab.studies.sample_rate import sample_rate_series
    md = (demo_export / "report.md").read_text()
    assert "from the sample rate (10 Hz" in md                 # demo_cycle: 10 Hz IMU
    rs = type("RS", (), {})()                                  # a RunSeries-like stand-in
    data = sorted(pathlib.Path(demo_export / "data").glob("demo_cycle*7002*.h5"))[0]
    from rlgsim.ground.dataset_format import open_dataset
    with open_dataset(data) as ds:
        rs.coefficients = ds.coefficients()
    rs.path, rs.time_s = data, np.arange(1, 51) * 100.0        # the first 50 windows
    rate, y, m = sample_rate_series(rs, "z", 100.0)
    assert (rate, m, y.size) == (10.0, 1000, 50_000)
    ad = allan_deviation(y, rate, "octave")
    assert ad.tau_s[0] == pytest.approx(0.1)
    rs.path = demo_export / "report.md"                        # not a dataset: window series
    assert sample_rate_series(rs, "z", 100.0) is None
