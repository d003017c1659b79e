"""The three-gyro IMU of the single-gyro studies (src/rlgsim/lab/studies/imu_axes.py) and
``rlgsim navigate --models`` with exported compensators (docs/navigation.md).

A two-run study of the paper-001 gyro (1.5 h at 10 Hz, a ramp) runs once per module, inside a
Monte Carlo chamber variation, so the drawn units' sharing of the study unit's chamber is seen.
The drawn units' gyro errors are checked against the study's own window builder (another code
path), their heading after alignment against the gyrocompassing bound ε_E/(Ω cos L) of the East
unit's bias, and the study's [navigation] table against bad input.
"""

from __future__ import annotations

import math
import pathlib

import h5py
import numpy as np
import pandas as pd
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import parse_study, recipe_module, study_unit

SCENARIO = """
name = "imu_ramp"
device = "trplg_001"
seed = {seed}
device_seed = 1001
duration_h = 1.5
[acquisition]
sample_rate_hz = 10
thermal_step_s = 1
[power]
on_at_s = 0
[chamber]
start_c = 20.0
[[chamber.segments]]
type = "hold"
duration_h = 0.25
[[chamber.segments]]
type = "ramp"
to_c = 40.0
rate_c_per_min = 0.5
[[chamber.segments]]
type = "hold"
duration_h = 2
"""

STUDY = """
[study]
name = "imu_axes"
recipe = "bias_compensation"
device_seed = 1001

[data]
train = [{{ scenario = "train.toml" }}]
test = [{{ scenario = "test.toml" }}]
window_s = 100
gyro = "z"

[features]
temperature = "g.A"
uhfo = true

[[compensator]]
name = "LS T"
kind = "polynomial"
inputs = ["T"]
params = {{ degree = 2 }}

[[compensator]]
name = "LS U"
kind = "polynomial"
inputs = ["U"]
params = {{ degree = 1 }}
{navigation}
"""


def _study(folder: pathlib.Path, navigation: str = ""):
    (folder / "train.toml").write_text(SCENARIO.format(seed=11))
    (folder / "test.toml").write_text(SCENARIO.format(seed=12))
    path = folder / "imu.toml"
    path.write_text(STUDY.format(navigation=navigation))
    return parse_study(path.read_text(), str(path), base_dir=folder)


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    """The study's run and navigation (unit 0) inside a chamber variation of 2 K."""
    from rlgsim.sim.run.unit_variations import ChamberVariation, varied
    folder = tmp_path_factory.mktemp("imu")
    study = _study(folder, '[navigation]\ncompensators = ["LS U"]\n')
    recipe = recipe_module(study)
    config = recipe.check(study)
    with varied(ChamberVariation(offset_c=2.0)):
        result = recipe.run(study, config, folder / "out", unit=0, progress=False)
        ds, intro = recipe.navigation(study, config, result)
    return folder / "out" / "data", ds, intro, result


def test_drawn_units_share_the_chamber_not_the_device(ran):
    data, ds, intro, _ = ran
    test = [data / "test.h5", data / "test-unit1048576.h5", data / "test-unit2097152.h5"]
    assert all(p.is_file() for p in test) and (data / "train-unit2097152.h5").is_file()
    files = [h5py.File(p, "r") for p in test]
    try:
        chambers = [f["thermal/chamber_setpoint"][...] for f in files]
        # the study unit's varied programme (start 20 °C + its offset) for all three
        assert abs(chambers[0][0] - 20.0) > 1e-3
        for c in chambers[1:]:
            np.testing.assert_array_equal(c, chambers[0])
        laws = [f["truth/gyro_bias"][...] - f["truth/gyro_bias_random"][...] for f in files]
        assert not np.allclose(laws[0], laws[1]) and not np.allclose(laws[1], laws[2])
        assert [int(f.attrs["unit"]) for f in files] == [0, 1 << 20, 2 << 20]
    finally:
        for f in files:
            f.close()
    assert "IMU of three such gyros" in intro and "Ideal accelerometers" in intro
    assert list(ds["variant"].values) == ["raw", "LS U", "oracle (gyros)", "truth"]


def test_each_axis_carries_its_units_gyro_error(ran):
    """Over every 100-s window, the IMU's rate error on each unit's axis equals that unit's
    measured bias from the study's window builder (pulses / (k0·W) − Earth projection)."""
    from rlgsim.lab.navigation_source import gyro_units_source
    from rlgsim.lab.studies.runs import read_run
    data, _, _, result = ran
    from rlgsim.lab.studies.bias_compensation import check
    study = _study(data.parent.parent)
    config = check(study)
    spec = config.test[0]
    units = [(data / "test.h5", "z", 1), (data / "test-unit1048576.h5", "z", 0),
             (data / "test-unit2097152.h5", "z", 2)]
    src = gyro_units_source(units)
    try:
        n = 10 * 1000                                   # 10 windows at 10 Hz
        dth, dv = src.read(0, n)
        exact, dv_true = src.truth(0, n)
        np.testing.assert_array_equal(dv, dv_true)      # ideal accelerometers
        for path, _, mount in units:
            rs = read_run(path, config, spec.label, spec.ctx)
            err = (dth[:, mount] - exact[:, mount]).reshape(10, 1000).sum(axis=1) / 100.0
            deg_h = err * 180 / math.pi * 3600
            np.testing.assert_allclose(deg_h, rs.y[:10], rtol=0, atol=1e-9)
    finally:
        src.close()


def test_heading_after_alignment_follows_the_east_units_bias(ran):
    """Gyrocompassing turns the heading by ε_E/(Ω cos L), ε_E the East (x) unit's gyro error
    over the alignment. Between raw and the gyro oracle only the temperature law differs (the
    same noise, the same random bias), so their heading difference is the bound's difference
    ε_E,law/(Ω cos L); what is left is the law's change within the 600 s and the filter's
    weighting of it (a few per cent of a law that moves 0.3 K/min)."""
    _, ds, _, _ = ran
    psi = ds["heading_error_align_arcmin"]
    bound = ds["heading_bound_arcmin"]
    d_psi = float(psi.sel(variant="raw") - psi.sel(variant="oracle (gyros)"))
    d_bound = float(bound.sel(variant="raw") - bound.sel(variant="oracle (gyros)"))
    assert abs(d_bound) > 0.1
    assert d_psi == pytest.approx(d_bound, rel=0.05)


def test_monte_carlo_units_navigate_their_own_imu(ran, tmp_path):
    folder = tmp_path / "mc"
    folder.mkdir()
    study = _study(folder, '[navigation]\ncompensators = ["LS T"]\n')
    payload = {"text": study.text, "source": study.source, "name": study.name,
               "base_dir": str(folder)}
    a, b = study_unit(payload, 0), study_unit(payload, 1)
    nav_a = {(c, m): v for c, m, v in a["rows"] if m.startswith("nav_")}
    nav_b = {(c, m): v for c, m, v in b["rows"] if m.startswith("nav_")}
    assert nav_a.keys() == nav_b.keys() and {c for c, _ in nav_a} == {
        "raw", "LS T", "oracle (gyros)", "truth"}
    assert nav_a[("raw", "nav_error_end_m")] != nav_b[("raw", "nav_error_end_m")]


@pytest.mark.parametrize("table, needle", [
    ('[navigation]\ncompensators = ["LS X"]\n', "navigation.compensators: entry 1 'LS X'"),
    ('[navigation]\ncompensators = "LS T"\n', "navigation.compensators: expected an array"),
    ('[navigation]\nretune = 1\n', "navigation.retune: expected true or false"),
    ('[navigation]\nunits = 3\n', "navigation"),
])
def test_bad_navigation_table_is_one_line(tmp_path, table, needle):
    with pytest.raises(UserInputError) as e:
        _study(tmp_path, table)
    assert needle in str(e.value) and "\n" not in str(e.value)


# ------------------------------------------------------------- rlgsim navigate --models
@pytest.fixture(scope="module")
def imu_dataset(tmp_path_factory):
    from rlgsim.lab.api import load_scenario, with_changes
    from rlgsim.sim.run.simulate import simulate
    sc = with_changes(load_scenario("paper000_short"), duration_h=1.0)
    return simulate(sc, tmp_path_factory.mktemp("navmodels") / "p000.h5", progress=False)


def _export_law_models(dataset: pathlib.Path, folder: pathlib.Path) -> None:
    """Per gyro axis, a linear model of the true temperature law against the gyro's first
    probe, fitted on the run's 100-s windows and written by the study export
    (``rlgsim study --export-models``: rlgsim.lab.study_models.write_models)."""
    from rlgsim.estimators.polynomial import PolynomialRegressor
    from rlgsim.lab.api import window_table
    from rlgsim.lab.study_models import FittedModel, write_models
    models = []
    for a in "xyz":
        df = window_table(dataset, 100.0, gyro=a)
        probe = next(c for c in df.columns if c.startswith("probe_"))[len("probe_"):-len("_c")]
        X = df[[f"probe_{probe}_c"]].to_numpy()
        y = (df["true_bias_deg_per_h"] - df["true_random_deg_per_h"]).to_numpy()
        models.append(FittedModel(f"law_{a}", "polynomial",
                                  PolynomialRegressor(degree=1).fit(X, y), X, (probe,)))
    records = write_models(models, folder)
    assert all(r["JSON"] != "—" for r in records)


def test_navigate_models_folder_corrects_toward_truth(imu_dataset, tmp_path):
    from rlgsim.lab.cli import main
    folder = tmp_path / "models"
    _export_law_models(imu_dataset, folder)
    assert sorted(p.name for p in folder.glob("*.json")) == ["law_x.json", "law_y.json",
                                                             "law_z.json"]
    out = tmp_path / "nav"
    assert main(["navigate", str(imu_dataset), "--models", str(folder), "--span-h", "0.4",
                 "-o", str(out), "-q"]) == 0
    s = pd.read_csv(out / "summary.csv").set_index("variant")
    assert list(s.index) == ["raw", "law", "oracle (gyros)", "oracle", "truth"]
    gyro = s["residual_gyro_error_deg_h"]
    # the model learnt the true law: it leaves far less gyro error than raw, about the oracle's
    assert abs(gyro["law"] - gyro["oracle (gyros)"]) < 0.2 * (gyro["raw"] - gyro["oracle (gyros)"])
    err = s["error_end_m"]
    assert abs(err["law"] - err["oracle (gyros)"]) < abs(err["raw"] - err["oracle (gyros)"])
    # FILE.json without an axis suffix: one model for all three gyros, a variant of its own
    common = tmp_path / "common.json"
    common.write_text((folder / "law_y.json").read_text())
    assert main(["navigate", str(imu_dataset), "--models", str(common), "--span-h", "0.4",
                 "-o", str(tmp_path / "one"), "-q"]) == 0
    assert "common" in set(pd.read_csv(tmp_path / "one" / "summary.csv")["variant"])


@pytest.mark.parametrize("text, needle", [
    ("{", "not valid JSON"),
    ('{"model": 3}', ""),
    ("", "not valid JSON"),
])
def test_bad_model_file_is_one_line_exit_2(imu_dataset, tmp_path, capsys, text, needle):
    from rlgsim.lab.cli import main
    bad = tmp_path / "bad_x.json"
    bad.write_text(text)
    assert main(["navigate", str(imu_dataset), "--models", str(bad), "-o",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err and needle in err
    assert not (tmp_path / "o").exists()


def test_missing_models_folder_is_one_line_exit_2(imu_dataset, tmp_path, capsys):
    from rlgsim.lab.cli import main
    empty = tmp_path / "none"
    empty.mkdir()
    for arg in (empty, tmp_path / "absent.json"):
        assert main(["navigate", str(imu_dataset), "--models", str(arg)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and str(arg) in err


def test_retune_false_refits_at_the_tuned_point(tmp_path):
    """``retune = false``: a drawn unit's PSO-SVR is scikit-learn's SVR at the study unit's
    tuned (C, gamma) fitted on the drawn unit's windows (the reference built here from
    sklearn alone), and the study unit's own model is left as it was."""
    import dataclasses

    from sklearn.compose import TransformedTargetRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVR

    from rlgsim.estimators.columns import Columns
    from rlgsim.lab.studies.bias_compensation import check
    from rlgsim.lab.studies.fitting import fit
    from rlgsim.lab.studies.imu_axes import axis_predictions
    from rlgsim.lab.studies.runs import RunSeries
    spec = dataclasses.replace(check(_study(tmp_path)).compensators[0], kind="pso_svr",
                               params={"n_agents": 4, "max_iter": 2})
    rng = np.random.default_rng(5)

    def series(shift: float) -> RunSeries:
        t = np.linspace(-20.0, 60.0, 120)
        y = 0.01 * np.tanh((t - shift) / 15.0) + 1e-4 * rng.standard_normal(t.size)
        return RunSeries("r", pathlib.Path("r.h5"), 1, 1, np.arange(1, 121) * 100.0, y, y, 0 * y,
                         Columns({"T": t, "dT/dt": 0 * t, "U": 0 * t}), 0.0, {})
    own, drawn = series(10.0), series(25.0)
    f0 = fit(spec, own.X, own.y, 7)
    before = f0.model.predict(np.asarray(own.X.select(["T"])))
    pred = axis_predictions([spec], {spec.name: f0}, [drawn], drawn, 7, retune=False)
    C, gamma = f0.model.best_params_["C"], f0.model.best_params_["gamma"]
    ref = TransformedTargetRegressor(
        regressor=make_pipeline(StandardScaler(), SVR(kernel="rbf", C=C, gamma=gamma,
                                                      epsilon=0.1)),
        transformer=StandardScaler()).fit(drawn.X["T"][:, None], drawn.y)
    np.testing.assert_allclose(pred[spec.name], ref.predict(drawn.X["T"][:, None]),
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(f0.model.predict(np.asarray(own.X.select(["T"]))), before)
