"""Several gyros identified into one device preset (issue 28; src/rlgsim/lab/identify/
twin_gyros.py, gyro_views.py): a drawn three-gyro unit whose gyros have different bias laws
(x: linear, y: linear + quadratic, z: through the UHFO only), recorded the lab way with one
per-axis UHFO column (``uhfo_z_v``), identified without ``--gyro``. Each gyro's law is found
within its stated uncertainty (the model-averaged standard error, selection included), the
three laws are told apart, and the one ``device.toml`` the twin writes runs in the simulator
with every gyro's own law (the drawn coefficients of a simulated unit are the written ones)."""

from __future__ import annotations

import copy
import tomllib

import pytest

import identify_truth as IT
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.cli.main import main
from rlgsim.lab.identify.preset_text import dumps

AXES = ("x", "y", "z")
#: the truth: one bias law per gyro (°/h; x = T − 25 °C at node A; U − U₀ in V)
TRUTH = IT.THREE_GYRO_BIAS
TERMS = IT.BIAS_TERMS


@pytest.fixture(scope="module")
def twin(tmp_path_factory):
    """The unit simulated (rlg_single network, trplg_001 gyros on its one block), exported,
    its UHFO kept for gyro z only, and identified with the sidecar alone (no gyro named)."""
    folder = tmp_path_factory.mktemp("gyros")
    lab = IT.three_gyro_lab_csv(folder, TRUTH)
    from rlgsim.lab.identify import identify
    return identify(str(lab), folder / "twin", suggest_programme=True), folder


def test_each_gyro_law_within_its_stated_uncertainty(twin):
    r, _ = twin
    assert [g.axis for g in r.gyros] == list(AXES)
    assert [g.data.uhfo_v is not None for g in r.gyros] == [False, False, True]
    for i, g in enumerate(r.gyros):
        sel = g.laws.bias
        for key, term in TERMS.items():
            true = TRUTH[key][i]
            if term in sel.averaged:
                v, se, _ = sel.averaged[term]
            elif true == 0.0:
                continue                            # never a candidate, nor in the truth
            else:
                pytest.fail(f"gyro {g.axis}: {term} of the truth is not in the law")
            assert abs(v - true) <= 3.0 * se, (g.axis, term, v, se, true)
    # the three laws are told apart: x falls with T, y rises, only z follows its UHFO
    bx, by, bz = (g.laws.bias for g in r.gyros)
    assert "c1" in bx.terms and bx.value("c1") + 3 * bx.se("c1") < 0
    assert "c1" in by.terms and by.value("c1") - 3 * by.se("c1") > 0
    assert "uhfo" in bz.terms and "uhfo" not in bx.candidates + by.candidates


def test_one_device_preset_holds_every_gyro_law(twin):
    r, folder = twin
    dev = tomllib.loads((folder / "twin" / "device.toml").read_text())
    assert dev["gyro"]["axes"] == list(AXES) and dev["gyro"]["blocks"] == ["g"] * 3
    bias = dev["gyro"]["bias"]
    for i, g in enumerate(r.gyros):
        sel = g.laws.bias
        assert bias["value_deg_per_h"][i] == pytest.approx(sel.value("intercept"), rel=1e-9)
        for key, term in TERMS.items():
            if term != "intercept" and key in bias:
                want = sel.value(term) if term in sel.terms else 0.0
                assert bias[key][i] == pytest.approx(want, rel=1e-9, abs=1e-15), (key, i)
    # the UHFO law: gyro z's fitted, x and y the template's (their channel without a column)
    assert dev["uhfo"]["value_v"][2] == pytest.approx(r.gyros[2].laws.u0_v, rel=1e-9)
    assert dev["uhfo"]["value_v"][:2] == [5.0, 5.0]
    report = (folder / "twin" / "report.md").read_text()
    # the next experiment: one programme, for the first gyro with terms it cannot separate
    want = next((g.axis for g in r.gyros if g.laws.bias.unseparable), "x")
    assert r.next_gyro == want and r.next_path is not None and r.next_path.exists()
    assert f"designed for gyro `{want}` only" in report
    for a in AXES:
        assert f"## Gyro {a}" in report and (folder / "twin" /
                                              f"gyro_{a}_bias_law_coefficients.csv").exists()


def test_the_preset_runs_with_each_gyro_law(twin, tmp_path):
    r, folder = twin
    sc = {"name": "short", "device": str(folder / "twin" / "device.toml"), "seed": 3,
          "duration_s": 600.0, "acquisition": {"sample_rate_hz": 1.0, "thermal_step_s": 1.0},
          "power": {"on_at_s": 0.0}, "chamber": {"start_c": 20.0, "segments": [
              {"type": "ramp", "to_c": 30.0, "rate_c_per_min": 1.0}]}}
    (tmp_path / "short.toml").write_text(dumps(sc), encoding="utf-8")
    assert main(["run", str(tmp_path / "short.toml"), "-o", str(tmp_path / "s.h5"), "-q"]) == 0
    import h5py
    with h5py.File(tmp_path / "s.h5", "r") as f:
        names = [n.decode() for n in f["truth/coefficient"][()]]
        got = dict(zip(names, f["truth/coefficient_value"][()]))
    dev = tomllib.loads((folder / "twin" / "device.toml").read_text())
    tol = dev["tolerance"]["gyro"]["bias"]
    for i, a in enumerate(AXES):        # the drawn unit: each gyro's own nominal law ± 5σ
        for key, coef in (("value_deg_per_h", "value"), ("c1_deg_per_h_per_k", "c1"),
                          ("uhfo_deg_per_h_per_v", "uhfo")):
            v, s = dev["gyro"]["bias"][key], tol.get(key, 0.0)
            v, s = (v[i] if isinstance(v, list) else v), (s[i] if isinstance(s, list) else s)
            assert abs(got[f"gyro.bias.{coef}[{a}]"] - v) <= 5 * s + 1e-12 * abs(v), (a, key)
    assert got["gyro.bias.uhfo[x]"] == got["gyro.bias.uhfo[y]"] == 0.0
    assert got["gyro.bias.uhfo[z]"] != 0.0


def test_gyro_views_and_merge_keep_a_three_gyro_template():
    """A three-gyro template (rlg_imu_000 with a law per gyro) cut into its gyros and merged
    back gives its own laws; one gyro's view is a valid single-gyro template (what --gyro fits
    on); a UHFO law with a value per gyro reads, one with the wrong count is one line."""
    from rlgsim.sim import presets
    from rlgsim.sim.config import Ctx
    from rlgsim.sim.run.scenario import device_from_file, validate_device_tables
    from rlgsim.lab.identify.gyro_views import gyro_view, merge_devices
    from rlgsim.lab.identify.twin_gyros import one_gyro_template
    f = presets.load_device_file("rlg_imu_000")
    tmpl = {k: v for k, v in copy.deepcopy(f.data).items() if k != "run_to_run"}
    tmpl["gyro"]["bias"]["c1_deg_per_h_per_k"] = [1e-4, 2e-4, 3e-4]
    tmpl["gyro"]["bias"]["gradients"][0]["coeff_deg_per_h_per_k"] = [0.004, 0.0, -0.002]
    tmpl["gyro"]["misalignment"]["value_arcsec"] = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    tmpl["uhfo"]["value_v"] = [4.0, 5.0, 6.0]
    validate_device_tables(tmpl, Ctx("rlg_imu_000 with a law per gyro"))
    views = [gyro_view(tmpl, a, i) for i, a in enumerate(AXES)]
    assert [v["gyro"]["blocks"] for v in views] == [["gx"], ["gy"], ["gz"]]
    y = one_gyro_template(tmpl, ["y"], "run.h5")
    assert y == views[1] and y["gyro"]["axes"] == ["y"]
    assert y["gyro"]["bias"]["c1_deg_per_h_per_k"] == 2e-4 and y["uhfo"]["value_v"] == 5.0
    assert y["gyro"]["misalignment"]["value_arcsec"] == [3.0, 4.0]
    validate_device_tables(y, Ctx("the y view"))
    assert one_gyro_template(views[2], ["z"], "run.h5") is views[2]   # one gyro: itself

    class NoHops:
        hops, uhfo = None, None
    merged, _ = merge_devices(tmpl, AXES, views, [{}] * 3, [NoHops()] * 3)
    for law in ("bias", "scale_factor", "misalignment"):
        assert merged["gyro"][law] == tmpl["gyro"][law], law
    assert merged["uhfo"] == tmpl["uhfo"]
    # a knee only gyro x selected: the others' knee 0 at the law's default centre, no spread
    views[0]["gyro"]["bias"].update(knee_deg_per_h=0.01, knee_c=12.0)
    views[0]["tolerance"]["gyro"]["bias"]["knee_c"] = 2.0
    for v in views[1:]:
        for t in (v["gyro"]["bias"], v["tolerance"]["gyro"]["bias"]):
            for key in ("knee_deg_per_h", "knee_c"):
                t.pop(key, None)
    merged, _ = merge_devices(tmpl, AXES, views, [{}] * 3, [NoHops()] * 3)
    assert merged["gyro"]["bias"]["knee_deg_per_h"] == [0.01, 0.0, 0.0]
    assert merged["gyro"]["bias"]["knee_c"] == [12.0, 25.0, 25.0]
    assert merged["tolerance"]["gyro"]["bias"]["knee_c"] == [2.0, 0.0, 0.0]
    d = copy.deepcopy(f.data)
    d["uhfo"]["value_v"] = [4.0, 5.0, 6.0]
    assert device_from_file(presets.TomlFile(**{**vars(f), "data": d})) is not None
    d["uhfo"]["c1_v_per_k"] = [0.1, 0.2]
    with pytest.raises(UserInputError) as e:
        device_from_file(presets.TomlFile(**{**vars(f), "data": d}))
    assert "c1_v_per_k" in str(e.value) and "\n" not in str(e.value)


def test_a_recorded_gyro_the_template_lacks_is_one_line():
    from rlgsim.lab.identify.gyro_views import template_component
    assert template_component({"gyro": {"axes": ["z"]}}, "x", "run.csv") == 0   # stands for all
    assert template_component({"gyro": {"axes": ["x", "y", "z"]}}, "y", "run.csv") == 1
    with pytest.raises(UserInputError) as e:
        template_component({"gyro": {"axes": ["x", "y"]}}, "z", "run.csv")
    assert str(e.value).startswith("run.csv: gyro 'z' not allowed; the device template's gyros "
                                   "are x, y") and "\n" not in str(e.value)


def test_a_gyro_the_recording_cannot_support_is_named():
    """One gyro's refusal in a several-gyro read names it, and the gyros read before it as
    identifiable alone (recording_data.read_recordings); a one-gyro read's stays as it was."""
    from rlgsim.lab.identify.recording_data import _naming
    msg = "run.csv: only 3 complete powered 100 s windows of the gyro"
    with pytest.raises(UserInputError) as e, _naming(["x", "y", "z"], "y", 1):
        raise UserInputError(msg)
    assert str(e.value) == msg + " (gyro y; gyro x can be identified alone: --gyro x)"
    with pytest.raises(UserInputError) as e, _naming(["x", "y", "z"], "x", 0):
        raise UserInputError(msg)
    assert str(e.value) == msg + " (gyro x)"
    with pytest.raises(UserInputError) as e, _naming([None], None, 0):
        raise UserInputError(msg)
    assert str(e.value) == msg
