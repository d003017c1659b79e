"""Scale factor and its temperature law from turntable rate segments (rlgsim identify, issue 17
§3): units with a known scale-factor law simulated on a turntable programme of ± rate segments
during a chamber programme, identified back; the refusals; the segment noise covariance against
its equal-window special case and direct numerical integration."""

import pathlib
import tomllib

import h5py
import numpy as np
import pytest

import identify_truth as IT
from rlgsim.estimators.identify.segment_noise import (gauss_markov_segment_covariance,
                                                       segment_mean_covariance)
from rlgsim.estimators.identify.window_noise import window_mean_covariance
from rlgsim.lab.identify import identify
from rlgsim.lab.identify.preset_text import dumps

BIAS = {"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 3e-4,
        "langmuir_deg_per_h_per_ma": 0.0}
SF = {"node": "A", "t_ref_c": 20.0, "value_ppm": 3.0, "c1_ppm_per_k": 0.1,
      "c2_ppm_per_k2": -0.002}
QUIET = {"gyro_arw_deg_per_sqrt_h": 0.0, "gyro_bias_instability_deg_per_h": 0.0}
#: 20 → 45 → 0 → 20 °C, 2.2 h: the rate segments see four soaks and three ramps
PROGRAMME = [{"type": "hold", "duration_min": 15},
             {"type": "ramp", "to_c": 45.0, "rate_c_per_min": 2.0},
             {"type": "hold", "duration_min": 30},
             {"type": "ramp", "to_c": 0.0, "rate_c_per_min": 2.0},
             {"type": "hold", "duration_min": 30},
             {"type": "ramp", "to_c": 20.0, "rate_c_per_min": 2.0},
             {"type": "hold", "duration_min": 10}]


def _spin(rate: float, seconds: float = 72.0) -> list[dict]:
    """Rotations about the inner axis (body z, the gyro's input axis) at + then − rate."""
    return [{"type": "continuous", "axis": "inner", "rate_deg_s": rate, "duration_s": seconds},
            {"type": "continuous", "axis": "inner", "rate_deg_s": -rate, "duration_s": seconds}]


#: every 10 min: 456 s at rest, 72 s at +50 °/s, 72 s at −50 °/s (ten turns each way)
EVERY_10_MIN = {"program": "custom", "continuous": True,
                "motions": [{"type": "hold", "duration_s": 456.0}, *_spin(50.0)]}


def _unit(folder: pathlib.Path, *, noise: dict | None, turntable: dict | None, seed: int = 1,
          sample_rate_hz: float = 2.0, programme=PROGRAMME, name: str = "run",
          sf: dict | None = None) -> pathlib.Path:
    """Simulate one unit (thermal template rlg_single, device trplg_001 with the bias law BIAS
    and the scale-factor law SF; the value drawn around SF's by the template's 5 ppm
    tolerance) on ``programme`` with the ``turntable`` table; the dataset's path."""
    th = IT.thermal_truth(folder, {"rlg_block.power": 1.08}, probe_noise=noise is not None,
                          name=f"{name}_thermal.toml")
    dev = IT.device_truth(folder, th, bias=BIAS, noise=noise, keep_uhfo=False,
                          scale_factor=100.0, name=f"{name}_device.toml")
    d = tomllib.loads(dev.read_text())
    d["gyro"]["scale_factor"] = dict(SF if sf is None else sf)
    dev.write_text(dumps(d))
    sc = IT.scenario(folder, dev, programme=programme, sample_rate_hz=sample_rate_hz,
                     seed=seed, device_seed=seed, name=name)
    s = tomllib.loads(sc.read_text())
    if turntable is not None:
        s["turntable"] = turntable
    sc.write_text(dumps(s))
    return IT.simulate(sc, folder / f"{name}.h5")


def _truth(path: pathlib.Path) -> dict[str, float]:
    with h5py.File(path, "r") as h:
        names = [n.decode() if isinstance(n, bytes) else str(n)
                 for n in h["truth/coefficient"][()]]
        return dict(zip(names, map(float, h["truth/coefficient_value"][()])))


def _fit_only(rec: pathlib.Path):
    """The identification's fits (thermal, laws, scale factor) without writing the twin."""
    from rlgsim.lab.identify.law_fit import fit_laws
    from rlgsim.lab.identify.recording_data import read_recording
    from rlgsim.lab.identify.scale_factor_fit import fit_scale_factor
    from rlgsim.lab.identify.thermal_fit import fit_thermal
    from rlgsim.lab.identify.twin import load_templates
    from threadpoolctl import threadpool_limits
    _, dev, _, th = load_templates(str(rec), None, None)
    d = read_recording(rec)
    with threadpool_limits(limits=1, user_api="blas"):      # as identify() runs them
        thermal = fit_thermal(th, d.air_c, d.power, d.step_s, d.probe_names, d.probes_c,
                              source=str(rec))
        names = thermal.network.node_names
        laws = fit_laws(d, thermal.nodes_c, names, dev)
        return fit_scale_factor(d, thermal.nodes_c, names, dev, laws)


@pytest.fixture(scope="module")
def noise_free(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sf_noise_free")
    rec = _unit(folder, noise=QUIET, turntable=EVERY_10_MIN)
    return folder, rec, identify(rec, folder / "twin")


def test_noise_free_scale_factor_law_is_recovered(noise_free):
    folder, rec, r = noise_free
    truth = _truth(rec)
    sf = r.scale_factor
    assert sf is not None and sf.identified
    assert set(sf.law.terms) == {"c1", "c2"}
    assert len(sf.levels_c) >= 3
    v = {k: x for k, (x, _) in sf.values.items()}
    assert v["value_ppm"] == pytest.approx(truth["gyro.scale_factor.value[z]"], abs=0.002)
    assert v["c1_ppm_per_k"] == pytest.approx(0.1, rel=2e-3)
    assert v["c2_ppm_per_k2"] == pytest.approx(-0.002, rel=3e-3)
    # the bias law comes from the stationary windows only, unpolluted by the 50 °/s segments
    # (5 ppm of 50 °/s is 0.9 °/h, 3000 times the law's c1 per kelvin)
    assert r.data.moving_windows > 0
    assert r.laws.bias.value("c1") == pytest.approx(3e-4, rel=2e-3)
    # the twin: loadable, the law written with its standard errors and the summary line
    text = r.device_path.read_text()
    dev = tomllib.loads(text)
    law = dev["gyro"]["scale_factor"]
    assert law["c1_ppm_per_k"] == pytest.approx(v["c1_ppm_per_k"], rel=1e-8)
    assert law["node"] == "A" and law["t_ref_c"] == 20.0
    line = next(x for x in text.splitlines() if x.startswith("c2_ppm_per_k2"))
    assert "standard error" in line
    assert "# scale factor: identified from" in text
    from rlgsim.sim.run.scenario import load_scenario
    sc = load_scenario(str(r.scenario_path))
    assert sc.device.parts["gyro"].scale_factor.nominal["c1"][0] == pytest.approx(v["c1_ppm_per_k"])
    assert "## Scale factor" in (folder / "twin" / "report.md").read_text()


def test_noise_free_knee_at_the_template_centre_is_recovered(tmp_path):
    """A knee in the template's law is a candidate at the template's centre and width."""
    sf_law = {"node": "A", "t_ref_c": 20.0, "value_ppm": 3.0, "c1_ppm_per_k": 0.1,
              "knee_ppm": 0.5, "knee_c": 30.0, "knee_width_k": 5.0}
    rec = _unit(tmp_path, noise=QUIET, turntable=EVERY_10_MIN, name="knee", sf=sf_law)
    truth = _truth(rec)
    sf = _fit_only(rec)
    assert sf.candidates == ("c1", "c2", "knee")
    assert set(sf.law.terms) == {"c1", "knee"}
    assert sf.values["value_ppm"][0] == pytest.approx(truth["gyro.scale_factor.value[z]"],
                                                      abs=0.005)
    assert sf.values["c1_ppm_per_k"][0] == pytest.approx(0.1, rel=3e-3)
    assert sf.values["knee_ppm"][0] == pytest.approx(0.5, rel=5e-3)


def test_a_recording_gives_the_same_scale_factor_and_needs_its_angle_columns(noise_free,
                                                                             tmp_path):
    """The exported recording carries the table angles at the temperature rate (1 s): the rate
    segments come from them and the law is the dataset's; without the angle columns the
    motion cannot be used and the line names the columns."""
    from rlgsim.ground.recording_export import export
    folder, rec, r = noise_free
    csv = export(rec, "csv", out=tmp_path / "run.csv").table
    dev = folder / "run_device.toml"
    th = folder / "run_thermal.toml"
    rr = identify(csv, tmp_path / "twin", device_template=str(dev), thermal_template=str(th))
    for key, (v, se) in r.scale_factor.values.items():
        assert rr.scale_factor.values[key][0] == pytest.approx(v, rel=1e-6, abs=1e-6 * se)
    side = tmp_path / "run.toml"
    s = tomllib.loads(side.read_text())
    s["recording"]["ignore_columns"] = ["outer_angle_deg", "inner_angle_deg"]
    side.write_text(dumps(s))
    r2 = identify(csv, tmp_path / "twin2", device_template=str(dev), thermal_template=str(th))
    assert r2.scale_factor is None
    head = [x for x in r2.device_path.read_text().splitlines() if x.startswith("# scale factor")]
    assert len(head) == 1 and "outer_angle_deg, inner_angle_deg" in head[0]
    assert "kept from the template" in head[0]


def test_standard_errors_cover_the_truth_on_noisy_units(tmp_path):
    """Ten units (value drawn by the 5 ppm tolerance) with trplg_001's noise (ARW
    0.0008 °/√h, flicker 0.002 °/h, 2 Hz) and probe noise, identified end to end: the z-scores
    of value, c1 and c2 against the drawn truth. 30 z-scores (three per unit, correlated within
    a unit): |z| < 2 in at least 80 % (nominal 95 %; 80 % is 3.8 binomial standard errors below
    it at n = 30 — an SE half the true one gives ≈ 68 %) and |z| < 1 in 40-95 % (nominal 68 %;
    SEs twice the true ones give ≈ 95 %+). Seeds are fixed: the figures are deterministic."""
    z = []
    for seed in range(1, 11):
        rec = _unit(tmp_path, noise=None, turntable=EVERY_10_MIN, seed=seed, name=f"u{seed}")
        truth = _truth(rec)
        sf = _fit_only(rec)
        assert set(sf.law.terms) == {"c1", "c2"}
        for key, c in (("value_ppm", "value"), ("c1_ppm_per_k", "c1"), ("c2_ppm_per_k2", "c2")):
            v, se = sf.values[key]
            z.append((v - truth[f"gyro.scale_factor.{c}[z]"]) / se)
    z = np.abs(np.array(z))
    assert np.mean(z < 2) >= 0.8, z
    assert 0.4 <= np.mean(z < 1) <= 0.95, z


def test_refusals_static_one_temperature_and_too_slow(tmp_path):
    # a static table: the template's scale factor, the static line
    rec = _unit(tmp_path, noise=QUIET, turntable=None, name="static")
    r = identify(rec, tmp_path / "t_static")
    assert r.scale_factor is None
    assert "the recording has no turntable motion" in r.device_path.read_text()
    # rate segments in the first soak only: the constant is identified, c1/c2 are not
    first = {"program": "custom",
             "motions": [{"type": "repeat", "count": 3, "motions": _spin(50.0)},
                         {"type": "hold"}]}
    rec = _unit(tmp_path, noise=QUIET, turntable=first, name="one_t")
    truth = _truth(rec)
    r = identify(rec, tmp_path / "t_one")
    sf = r.scale_factor
    assert len(sf.levels_c) == 1 and sf.identified
    assert set(sf.kept) == {"c1", "c2"}
    for t in ("c1", "c2"):
        line = next(x for x in sf.lines if x.startswith(f"scale factor {t}:"))
        assert "kept from the template" in line and "1 temperature level" in line
    assert sf.values["value_ppm"][0] == pytest.approx(truth["gyro.scale_factor.value[z]"],
                                                      abs=0.01)
    law = tomllib.loads(r.device_path.read_text())["gyro"]["scale_factor"]
    assert law["c1_ppm_per_k"] == 0.1 and law["c2_ppm_per_k2"] == -0.002   # the template's
    # 0.02 °/s (72 °/h) with a navigation gyro's noise: each segment resolves the scale
    # factor to tens of ppm, no better than the template's 5 ppm spread
    slow = {"program": "custom", "continuous": True,
            "motions": [{"type": "hold", "duration_s": 1800.0},
                        *_spin(0.02, 600.0)]}
    rec = _unit(tmp_path, noise=None, turntable=slow, name="slow")
    r = identify(rec, tmp_path / "t_slow")
    sf = r.scale_factor
    assert not sf.identified and set(sf.kept) == {"value"}
    assert "resolve K − K₀ only to" in sf.lines[0] and "total turned angle" in sf.lines[0]
    tmpl = tomllib.loads((tmp_path / "slow_device.toml").read_text())["gyro"]["scale_factor"]
    assert tomllib.loads(r.device_path.read_text())["gyro"]["scale_factor"] == tmpl


def test_segment_covariance_matches_equal_windows_and_numerical_integration():
    s = np.array([0.0, 100.0, 300.0, 700.0, 900.0])
    kw = dict(n=0.05, b=0.002, k=1e-4, tau_min_s=2.0, tau_max_s=1e5, per_decade=3)
    a = segment_mean_covariance(s, np.full(5, 100.0), **kw)
    b = window_mean_covariance(s, 100.0, **kw)
    assert np.allclose(a, b, rtol=1e-6, atol=0)      # window_noise: var(1 − x/3) below x = 1e-3
    # unequal segments, one Gauss–Markov process: ∫∫ var e^{−|t−t'|/τ} dt dt' / (T_i T_j)
    from scipy.integrate import dblquad
    st, ln, tau, var = np.array([0.0, 150.0]), np.array([40.0, 90.0]), 60.0, 2.0
    cov = gauss_markov_segment_covariance(st, ln, var, tau)
    for i in range(2):
        for j in range(2):
            num, _ = dblquad(lambda t2, t1: var * np.exp(-abs(t1 - t2) / tau), st[i],
                             st[i] + ln[i], st[j], st[j] + ln[j], epsabs=0, epsrel=1e-8)
            assert cov[i, j] == pytest.approx(num / (ln[i] * ln[j]), rel=1e-6), (i, j)
    with pytest.raises(ValueError):
        segment_mean_covariance(np.array([0.0, 50.0]), np.array([100.0, 10.0]))


def test_a_recording_at_rest_away_from_zero_gets_the_earth_rate_of_its_attitude(tmp_path):
    """A table standing at outer = 90° (gyro z pointing South): the recording's bias windows
    take the Earth rate through the logged attitude, as the dataset's truth does (window_table
    alone assumes the table at zero: 20.9 °/h off at 34° latitude)."""
    from rlgsim.api import window_table
    from rlgsim.ground.recording_export import export
    from rlgsim.lab.identify.recording_data import read_recording
    rec = _unit(tmp_path, noise=QUIET, turntable={"program": "static", "outer_deg": 90.0},
                name="r90")
    d0 = read_recording(rec)
    csv = export(rec, "csv", out=tmp_path / "r90_rec.csv").table
    d1 = read_recording(csv)
    assert d1.motion is None and not d1.has_motion
    b0 = d0.windows["bias_deg_per_h"].to_numpy()
    b1 = d1.windows["bias_deg_per_h"].to_numpy()
    assert np.max(np.abs(b1 - b0)) < 1e-9
    assert np.min(np.abs(window_table(csv)["bias_deg_per_h"].to_numpy() - b1)) > 10.0


def test_multi_position_programme_finds_no_false_read_out_spikes(tmp_path):
    """calibration19 (90° turns about every axis at 20 °/s, 10 Hz, noisy, no anomalies): the
    spike search sees the rate less the table's input, so the Earth rate swinging through a
    turning gyro and the rate steps are not spikes (two false ones before); the scale factor
    comes from the turns about the gyro's own axis."""
    rec = _unit(tmp_path, noise=None, turntable={"program": "calibration19",
                                                   "rate_deg_s": 20.0},
                name="c19", sample_rate_hz=10.0)
    truth = _truth(rec)
    r = identify(rec, tmp_path / "twin")
    assert r.laws.spikes.sizes == ()
    sf = r.scale_factor
    assert sf.identified and set(np.round(np.abs(sf.segments["rate_deg_s"]), 6)) == {20.0}
    v, se = sf.values["value_ppm"]
    assert abs(v - truth["gyro.scale_factor.value[z]"]) < 4 * se


def test_logged_angles_with_jitter_keep_their_constant_rate_segments():
    """Angles logged at 1 Hz with 1e-4° resolution and time-stamp jitter: each ±10 °/s rotation
    and each rest is one segment (exact rates, as a simulated dataset gives, must not be needed)
    and the segment's rate is the table's mean rate over it."""
    from rlgsim.lab.identify.table_motion import _from_knots
    rng = np.random.default_rng(5)
    t_k = np.arange(0.0, 400.0 + 1.0, 1.0)
    rate = np.where(t_k < 100, 0.0, np.where(t_k < 200, 10.0, np.where(t_k < 300, 0.0, -10.0)))
    angle = np.concatenate(([0.0], np.cumsum(rate[:-1] * np.diff(t_k))))
    angle = np.round(angle + rng.normal(0.0, 2e-5, angle.size) * (rate != 0), 4)
    # the inner axis turns the z gyro (the outer axis lies in the body's x-y plane)
    tm = _from_knots(t_k, np.zeros_like(angle), angle, 4000, 10.0, np.array([0.0, 0.0, 1.0]),
                     45.0, "test")
    assert len(tm.segments) == 2, tm.segments
    np.testing.assert_allclose(tm.segment_rate_deg_s, [10.0, -10.0], rtol=1e-4)
    assert np.all(np.diff(tm.segments, axis=1) >= 900)
