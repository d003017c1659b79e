"""The paper-000 study recipe (src/rlgsim/lab/studies/paper000_system.py) on a shortened campaign.

One module-scoped run of the recipe on ``scenarios/paper000_short.toml`` (8 calibration windows
over −5 → 65 °C) with a tiny HHO budget; the tests check its report, recompute its truth-based
scores independently from the calibration table it wrote, check the physics of the
system-level compensation and the validation of the study tables.
"""

from __future__ import annotations

import csv
import pathlib

import numpy as np
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.study import parse_study, recipe_module

PARAMS = [f"gyro_bias_{a}" for a in "xyz"] + [f"gyro_sf_{a}" for a in "xyz"] + \
         [f"accel_bias_{a}" for a in "xyz"] + [f"accel_sf_pos_{a}" for a in "xyz"] + \
         [f"accel_sf_neg_{a}" for a in "xyz"]

SHORT = """
[study]
name = "paper000_test"
recipe = "paper000_system"
paper = "000"

[campaign]
scenario = "paper000_short"
workers = 2

[models.hho_rvr]
hawks = 4
iterations = 5
folds = 3

[system]
desired_temperature_c = 50.0
"""


def _read_csv(path: pathlib.Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper000")
    study = parse_study(SHORT, "paper000_test.toml")
    recipe = recipe_module(study)
    cfg = recipe.check(study)
    result = recipe.run(study, cfg, out, unit=0, progress=False)
    recipe.report(study, cfg, result).write(out)
    scores = {(c, m): v for c, m, v in result.rows}
    return out, result, scores, study, cfg


def test_end_to_end_writes_the_report_and_all_scores(run):
    out, result, scores, _, _ = run
    text = (out / "report.md").read_text()
    for needle in ("Table 2", "Table 3", "Verdict", "35.27", "30.34",
                   "parameters_vs_temperature.png", "compensation_residuals.png"):
        assert needle in text
    for name in ("parameters_vs_temperature.png", "compensation_residuals.png", "report.html",
                 "table2_ours.csv", "table3_ours.csv", "calibration_raw.csv",
                 "model_predictions.csv"):
        assert (out / name).stat().st_size > 0
    for p in PARAMS:
        for c in ("hho_rvr", "lsm"):
            for m in ("rmse", "mae", "r2", "truth_rmse", "truth_mae", "truth_r2",
                      "residual_variance"):
                assert np.isfinite(scores[(c, f"{p}.{m}")]), (c, p, m)
        assert np.isfinite(scores[("raw", f"{p}.residual_variance")])
    for m in ("rmse", "mae", "r2", "residual_variance"):
        assert np.isfinite(scores[("hho_rvr", f"avg_improvement_{m}_pct")])
    # the drawn device coefficients come with the scores
    assert any(k.startswith("accel.bias.c1[") for k in result.params)


def test_table3_reports_the_share_of_compensated_samples_outside_the_training_range(run):
    """Issue 27: the compensation evaluates each model at every probe sample of the windows;
    the share beyond the training temperatures (window means) and the largest excess in % of
    their span, recomputed here from the calibration table and the dataset's probe log."""
    import h5py
    out, result, _, _, _ = run
    rows = {r["parameter"]: r for r in _read_csv(out / "table3_ours.csv")}
    cal = _read_csv(out / "calibration_raw.csv")
    ok = [r for r in cal if r["status"] == "ok"]
    with h5py.File(result.details.data_path, "r") as f:
        g = f["probes"]
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in g["probe"][()]]
        t, temps = g["time"][()], g["temperature"][()]
    inside = np.zeros(t.shape, bool)
    for r in ok:
        inside |= (t > float(r["t0_s"])) & (t <= float(r["t1_s"]))
    for p in PARAMS:
        probe = f"g{p[-1]}.A" if p.startswith("gyro") else f"a{p[-1]}"
        xs = np.array([float(r[f"temp_{probe}_c"]) for r in ok])
        grid = temps[inside, names.index(probe)].astype(float)
        lo, hi = xs.min(), xs.max()
        beyond = np.maximum(np.maximum(lo - grid, grid - hi), 0.0)
        assert float(rows[p]["outside_range_pct"]) == pytest.approx(
            100 * np.mean(beyond > 0), abs=1e-9)
        assert float(rows[p]["outside_excess_pct"]) == pytest.approx(
            100 * beyond.max() / (hi - lo), rel=1e-9, abs=1e-9)
        # the first window starts below its own mean: the ends extrapolate a little
        assert 0 < float(rows[p]["outside_range_pct"]) < 50
    assert "Inputs outside the training range" in (out / "report.md").read_text()


def test_truth_scores_match_an_independent_recomputation(run):
    """RMSE/MAE/R² against the truth, recomputed with numpy from the calibration table the
    recipe wrote (estimate, truth and probe mean per window) and, for the LSM, a numpy.polyfit
    of the same rows."""
    out, _, scores, _, _ = run
    table = [r for r in _read_csv(out / "calibration_raw.csv") if r["status"] == "ok"]
    preds = _read_csv(out / "model_predictions.csv")
    assert len(table) == 8
    for p in PARAMS:
        probe = f"g{p[-1]}.A" if p.startswith("gyro") else f"a{p[-1]}"
        T = np.array([float(r[f"temp_{probe}_c"]) for r in table])
        est = np.array([float(r[p]) for r in table])
        truth = np.array([float(r[f"{p}_true"]) for r in table])
        mine = [r for r in preds if r["parameter"] == p]
        np.testing.assert_allclose([float(r["temperature_c"]) for r in mine], T)
        np.testing.assert_allclose([float(r["estimate"]) for r in mine], est)
        np.testing.assert_allclose([float(r["truth"]) for r in mine], truth)
        lsm = np.polyval(np.polyfit(T, est, 3), T)
        rvr = np.array([float(r["hho_rvr"]) for r in mine])
        np.testing.assert_allclose([float(r["lsm"]) for r in mine], lsm,
                                   rtol=1e-6, atol=1e-9 * np.max(np.abs(est)))
        for c, pred in (("lsm", lsm), ("hho_rvr", rvr)):
            e = pred - truth
            rmse = np.sqrt(np.mean(e ** 2))
            r2 = 1 - np.sum(e ** 2) / np.sum((truth - truth.mean()) ** 2)
            assert scores[(c, f"{p}.truth_rmse")] == pytest.approx(rmse, rel=1e-6)
            assert scores[(c, f"{p}.truth_mae")] == pytest.approx(np.mean(np.abs(e)), rel=1e-6)
            assert scores[(c, f"{p}.truth_r2")] == pytest.approx(r2, rel=1e-6, abs=1e-9)
            # in-sample (Table 2) scores against the estimates
            assert scores[(c, f"{p}.rmse")] == pytest.approx(
                np.sqrt(np.mean((pred - est) ** 2)), rel=1e-6)


def test_shapes_reading_agrees_with_table2_and_the_truth(run):
    """The reading of the paper's summary numbers (shapes_reading.csv): its in-sample columns
    are Table 2's, its cubic share is 1 − R²_LSM, its σ_e and n are recomputed here with numpy
    from model_predictions.csv, and every class follows from its own columns."""
    from rlgsim.lab.studies.paper000_reading import classify
    out, _, _, _, _ = run
    reading = {r["parameter"]: r for r in _read_csv(out / "shapes_reading.csv")}
    table2 = {r["parameter"]: r for r in _read_csv(out / "table2_ours.csv")}
    preds = _read_csv(out / "model_predictions.csv")
    assert set(reading) == set(PARAMS)
    for p in PARAMS:
        r, t2 = reading[p], table2[p]
        assert float(r["RMSE impr %"]) == pytest.approx(float(t2["RMSE impr %"]), rel=1e-9)
        assert float(r["R² impr %"]) == pytest.approx(float(t2["R² impr %"]), rel=1e-6)
        assert float(r["R² LSM"]) == pytest.approx(float(t2["R² LSM"]), rel=1e-9)
        assert float(r["cubic share %"]) == pytest.approx(100 * (1 - float(t2["R² LSM"])),
                                                          rel=1e-6)
        mine = [q for q in preds if q["parameter"] == p]
        T, est, truth = (np.array([float(q[c]) for q in mine])
                         for c in ("temperature_c", "estimate", "truth"))
        cubic = np.polyval(np.polyfit(T, truth, 3), T)
        assert float(r["σ_e"]) == pytest.approx(np.std(est - truth, ddof=1), rel=1e-6)
        assert float(r["n beyond cubic"]) == pytest.approx(np.std(truth - cubic, ddof=1),
                                                           rel=1e-4, abs=1e-12)
        assert r["class"] == classify(float(r["cubic share %"]) / 100, float(r["n/σ_e"]))
    classes = _read_csv(out / "shapes_classes.csv")
    assert sum(int(c["count"]) for c in classes) == len(PARAMS)
    assert "Reading the paper's summary numbers" in (out / "report.md").read_text()
    paper = _read_csv(out / "paper_reading.csv")
    assert [r["paper"] for r in paper][:4] == ["35.27", "80.12", "9.15", "2.29"]
    counts = paper[4]["ours"].split(" (")[0].split(" / ")
    assert counts == [str(sum(r["class"] == c for r in reading.values())) for c in "abc"]


def test_system_compensation_removes_a_strong_temperature_slope(run):
    """accelerometer x bias: ~20 µg/K (rlg_imu_000) over a 70 K ramp, so its raw estimates
    spread over ~1400 µg. The drift is a deterministic, repeatable function of the sensor's
    temperature, which its probe tracks; converting the pulses to 50 °C with the fitted model
    (paper 000 eq. 29) removes it, and the re-calibrated bias is then constant up to the
    calibration noise (~2 µg 1σ), the in-window drift of the fast test ramp and the probe's lag
    — far less than the raw spread. The scale factors (~20 ppm/K) behave the same way."""
    _, _, scores, _, _ = run
    for p in ("accel_bias_x", "accel_sf_pos_y", "accel_sf_neg_z"):
        raw = scores[("raw", f"{p}.residual_variance")]
        for c in ("lsm", "hho_rvr"):
            assert scores[(c, f"{p}.residual_variance")] < raw / 100, (p, c)
    raw = np.sqrt(scores[("raw", "accel_bias_x.residual_variance")])
    assert raw > 200.0           # the slope is really there (µg)


def test_compensated_gyro_pulses_follow_eq_26_with_cumulative_rounding(run):
    """Paper 000 eq. (26) recomputed independently: the LSM models refitted with numpy.polyfit
    on the calibration table, the probe log interpolated to the sample times, and
    N' = K(T_d)/K(T)·N + K(T_d)(D(T_d) − D(T))Δt summed; the compensated dataset's int32 pulses
    must track that running sum within half a pulse (cumulative rounding never loses one)."""
    import h5py
    out, _, _, _, cfg = run
    table = [r for r in _read_csv(out / "calibration_raw.csv") if r["status"] == "ok"]
    data = out / "data"
    arcsec = np.pi / 180 / 3600
    deg_per_h = np.pi / 180 / 3600
    n = 400_000
    with h5py.File(data / "paper000_short_u0.h5") as fr, \
            h5py.File(data / "paper000_short_u0_compensated_lsm.h5") as fc:
        assert set(fc) == set(fr)
        # the copy's variables stay attached to the copy's own dimension scales (an object copy
        # would leave references into the source file, which h5py's .dims cannot follow)
        scales = {}
        for f in (fr, fc):
            scales[f] = {}
            f.visititems(lambda name, obj, f=f: scales[f].__setitem__(
                name, [[sc.name for sc in dim.values()] for dim in obj.dims])
                if isinstance(obj, h5py.Dataset) else None)
        assert scales[fc] == scales[fr] and scales[fc]["imu/gyro_pulses"][0]
        raw = fr["imu/gyro_pulses"][:n].astype(float)
        comp = fc["imu/gyro_pulses"][:n]
        assert comp.dtype == np.int32
        rate = float(fr["imu"].attrs["sample_rate_hz"])
        names = [p.decode() if isinstance(p, bytes) else p for p in fr["probes/probe"][:]]
        ptime = fr["probes/time"][:]
        t = (np.arange(n) + 0.5) / rate
        for i, a in enumerate("xyz"):
            probe = f"g{a}.A"
            T_rows = np.array([float(r[f"temp_{probe}_c"]) for r in table])
            cs = np.polyfit(T_rows, [float(r[f"gyro_sf_{a}"]) for r in table], 3)
            cb = np.polyfit(T_rows, [float(r[f"gyro_bias_{a}"]) for r in table], 3)
            T = np.interp(t, ptime, fr["probes/temperature"][:, names.index(probe)])
            s, b = np.polyval(cs, T), np.polyval(cb, T)
            s_d, b_d = np.polyval(cs, cfg.desired_c), np.polyval(cb, cfg.desired_c)
            k_d = 2.14 / arcsec * (1 + 1e-6 * s_d)
            want = np.cumsum((1 + 1e-6 * s_d) / (1 + 1e-6 * s) * raw[:, i]
                             + k_d * (b_d - b) * deg_per_h / rate)
            got = np.cumsum(comp[:, i].astype(float))
            assert np.max(np.abs(got - want)) < 0.5 + 1e-3, a
            # and the correction is real: ~0.03 °/h over the first hour at −5 °C
            assert abs(want[-1] - raw[:, i].sum()) > 20


@pytest.mark.parametrize("two_sided", [False, True])
def test_compiled_pulse_conversion_equals_the_numpy_formulation_bit_for_bit(two_sided):
    """The compiled pass (paper000_kernel.convert_block) against the numpy formulation
    (_Transform.numpy_block) on the same blocks: identical int32 pulses and carries, block
    after block, with samples before, on and after the probe grid's points and pulses of
    both signs (the accelerometer's K+/K−); a non-finite model value takes the numpy path."""
    from rlgsim.lab.studies.paper000_compensation import _Transform
    rng = np.random.default_rng(7)
    dt, m = 0.01, 400
    ptime = 1.0 + np.arange(m) * 0.25 + rng.uniform(0, 0.1, m)   # starts after sample 0
    ptime[50] = (int(ptime[50] / dt) + 0.5) * dt                  # a sample middle on a point
    grid = [[rng.normal(0, 50, m)] + ([rng.normal(0, 50, m)] if two_sided else [])
            for _ in range(3)]
    args = (ptime, dt, grid, [[3.0, -2.0][:len(g)] for g in grid],
            [rng.normal(0, 1e3, m) for _ in range(3)], [5.0, -7.0, 0.5],
            np.array([1e5, 2e5, 3e5]))
    compiled, reference = _Transform(*args), _Transform(*args)
    assert compiled.compiled
    for k0, n in ((0, 3000), (3000, 5000), (8000, 4000)):          # the last runs past the grid
        pulses = rng.integers(-300, 400, (n, 3)).astype(np.int32)
        got, want = compiled(k0, pulses), reference.numpy_block(k0, pulses)
        assert got.dtype == np.int32 and np.array_equal(got, want)
        assert np.array_equal(compiled.cum, reference.cum)
        assert np.array_equal(compiled.last, reference.last)
    grid[1][0][7] = np.nan
    assert not _Transform(*args).compiled


def test_existing_dataset_is_reused_and_a_changed_one_is_not(run):
    import dataclasses

    from rlgsim.lab.studies.runs import dataset_matches
    from rlgsim.lab.study import scenario_for
    out, _, _, study, _ = run
    path = out / "data" / "paper000_short_u0.h5"
    scenario = scenario_for(study, "paper000_short")
    assert dataset_matches(path, scenario)
    assert not dataset_matches(path, dataclasses.replace(scenario, seed=scenario.seed + 1))
    assert not dataset_matches(path, dataclasses.replace(scenario, unit=1))
    assert not dataset_matches(path, dataclasses.replace(scenario, device_seed=7))
    # the one fingerprint of every recipe: an edited device or thermal preset is not reused
    device = scenario.device
    edited = dataclasses.replace(device, text=device.text + "\n# edited\n")
    assert not dataset_matches(path, dataclasses.replace(scenario, device=edited))
    thermal = dataclasses.replace(device.thermal, text=device.thermal.text + "\n# edited\n")
    assert not dataset_matches(
        path, dataclasses.replace(scenario, device=dataclasses.replace(device, thermal=thermal)))


BAD = [
    ("[campaign]\nscenaro = 'paper000_short'\n", "scenaro"),
    ("[campaign]\nscenario = ''\n", "campaign.scenario"),
    ("[campaign]\ntemperature = ''\n", "campaign.temperature"),
    ("[campaign]\nworkers = -1\n", "campaign.workers"),
    ("[models.hho_rvr]\nhawks = 1\n", "models.hho_rvr.hawks"),
    ("[models.hho_rvr]\niterations = 'many'\n", "models.hho_rvr.iterations"),
    ("[models.hho_rvr]\nfolds = 1\n", "models.hho_rvr.folds"),
    ("[models.hho_rvr]\nshuffle = 'yes'\n", "models.hho_rvr.shuffle"),
    ("[models.svr]\nC = 1\n", "svr"),
    ("[models.lsm]\ndegree = 0\n", "models.lsm.degree"),
    ("[system]\ndesired_temperature_c = 'hot'\n", "system.desired_temperature_c"),
    ("[system]\ndesired_temperature_c = 5000.0\n", "system.desired_temperature_c"),
    ("[sytem]\ndesired_temperature_c = 50.0\n", "sytem"),
]


@pytest.mark.parametrize("extra, key", BAD)
def test_bad_study_tables_raise_user_input_error(extra, key):
    text = "[study]\nrecipe = 'paper000_system'\n" + extra
    with pytest.raises(UserInputError) as exc:
        parse_study(text, "bad.toml")
    msg = str(exc.value)
    assert "bad.toml" in msg and key in msg


def test_defaults_are_the_papers():
    study = parse_study("[study]\nrecipe = 'paper000_system'\n", "d.toml")
    cfg = recipe_module(study).check(study)
    assert (cfg.hawks, cfg.iterations, cfg.folds, cfg.shuffle) == (30, 500, 5, True)
    assert (cfg.degree, cfg.desired_c, cfg.scenario) == (3, 50.0, "paper000_campaign")


def test_shipped_study_parses():
    from rlgsim.lab.study import load_study
    study = load_study("paper000")
    cfg = recipe_module(study).check(study)
    assert cfg.scenario == "paper000_campaign" and cfg.hawks == 30


def test_one_worker_gives_the_same_results(run, tmp_path):
    """workers = 1 runs the fits and the compensations in sequence in this process; workers = 2
    overlaps them in a pool (the LSM-compensated dataset written while HHO-RVR fits): the
    scores are the same numbers."""
    import shutil
    out, result, _, _, _ = run
    (tmp_path / "data").mkdir()
    for h5 in (out / "data").glob("paper000_short_u0.h5"):
        shutil.copy(h5, tmp_path / "data" / h5.name)            # reused, not simulated again
    study = parse_study(SHORT.replace("workers = 2", "workers = 1"), "paper000_test.toml")
    recipe = recipe_module(study)
    one = recipe.run(study, recipe.check(study), tmp_path, unit=0, progress=False)
    assert one.details.reused
    assert one.rows == result.rows


def test_navigation_section(run):
    """The report's navigation table: raw, both compensated runs, the oracles and the truth
    floor, with a reason per ranking (docs/navigation.md)."""
    out = run[0]
    rows = _read_csv(out / "navigation.csv")
    assert [r["variant"] for r in rows] == ["raw", "HHO-RVR (to 50 °C)", "LSM (to 50 °C)",
                                             "oracle (gyros)", "oracle", "truth"]
    floor = rows[-1]
    assert float(floor["error at end [m]"]) < 0.05
    assert all(float(r["radial rate [nmi/h]"]) > 100 * float(floor["radial rate [nmi/h]"])
               for r in rows[:-1])
    text = (out / "report.md").read_text(encoding="utf-8")
    assert text.count("ranks before") == len(rows) - 1
    assert (out / "navigation.png").stat().st_size > 10000
