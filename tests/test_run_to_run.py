"""Run-to-run draws (sim/run/run_to_run.py): off without run_seed (the run is the same), the
draws' statistics over many run seeds, each mechanism's own stream (the ablation changes only
what it switches off), the varied network against the same network parsed from an edited
preset (an independent path through the thermal parser), the turn-on bias in the pulses' truth,
and bad tables refused in one line."""

from __future__ import annotations

import dataclasses
import pathlib
import re

import h5py
import numpy as np
import pytest
from scipy import stats

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.run import run_to_run
from rlgsim.sim.run.scenario import load_device, load_scenario, parse_scenario
from rlgsim.sim.run.simulate import simulate

ROOT = pathlib.Path(__file__).resolve().parents[1]
SC = ROOT / "scenarios"


def _short(name: str = "paper003_cycles", **changes):
    return load_scenario(name).with_changes(
        {"duration_h": 0.5, "acquisition.sample_rate_hz": 10, **changes})


def _arrays(path: pathlib.Path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(path) as f:
        f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset)
                     else None)
    return out


def test_without_run_seed_nothing_changes(tmp_path):
    sc = _short(run_seed=None)
    assert sc.run_seed is None and run_to_run.applied(sc) is sc and run_to_run.attrs(sc) == {}
    # a run_seed on a device without [run_to_run] draws nothing: the same arrays
    plain = load_scenario("paper002_const_20").with_changes({"duration_h": 0.2})
    seeded = plain.with_changes(run_seed=5)
    assert run_to_run.draw(seeded) is None
    a, b = simulate(plain, tmp_path / "a.h5", progress=False), simulate(
        seeded, tmp_path / "b.h5", progress=False)
    xa, xb = _arrays(a), _arrays(b)
    assert xa.keys() == xb.keys()
    assert all(np.array_equal(xa[k], xb[k]) for k in xa)
    with h5py.File(b) as f:
        assert int(f.attrs["run_seed"]) == 5 and "run_film_factor" not in f.attrs


def test_draw_statistics_over_run_seeds():
    sc = load_scenario("paper003_cycles")
    spec = sc.device.parts["run_to_run"]
    draws = [run_to_run.draw(dataclasses.replace(sc, run_seed=s)) for s in range(2000)]
    bias = np.array([d.turn_on_bias_deg_per_h[0] for d in draws])
    film = np.log([d.film_factor for d in draws])
    lab = np.array([d.lab_offset_c for d in draws])
    # each a normal with the table's sigma: Kolmogorov-Smirnov at 1 % (2000 draws)
    for x, sigma in ((bias, spec.turn_on_bias_deg_per_h), (film, spec.film_coefficient_rel),
                     (lab, spec.lab_offset_c)):
        assert stats.kstest(x / sigma, "norm").pvalue > 0.01
    # independent streams: correlation within 4/sqrt(n)
    assert abs(np.corrcoef(bias, film)[0, 1]) < 4 / np.sqrt(len(draws))
    # another unit of the same run seed is another draw
    other = run_to_run.draw(dataclasses.replace(sc, run_seed=0, unit=1))
    assert other.turn_on_bias_deg_per_h != draws[0].turn_on_bias_deg_per_h


def test_one_mechanism_off_leaves_the_others():
    sc = load_scenario("paper003_cycles")
    spec = sc.device.parts["run_to_run"]
    off = dataclasses.replace(spec, film_coefficient_rel=0.0)
    sc_off = dataclasses.replace(sc, device=dataclasses.replace(
        sc.device, parts={**sc.device.parts, "run_to_run": off}))
    a, b = run_to_run.draw(sc), run_to_run.draw(sc_off)
    assert b.film_factor == 1.0 and a.film_factor != 1.0
    assert (a.turn_on_bias_deg_per_h, a.lab_offset_c, a.chamber_offset_c, a.mount_factor) == (
        b.turn_on_bias_deg_per_h, b.lab_offset_c, b.chamber_offset_c, b.mount_factor)


def test_varied_network_matches_an_edited_preset(tmp_path):
    """Film factor f on every chamber-air link, mount factor m on base-table, lab offset on the
    boundary: the steady state and time constants equal those of the preset with the same
    numbers written into its TOML (parsed by the thermal parser, not by this module)."""
    sc = load_scenario("paper003_cycles")
    d = run_to_run.RunDraw(run_seed=0, turn_on_bias_deg_per_h=(0.0,), lab_offset_c=1.7,
                           chamber_offset_c=0.0, film_factor=1.23, mount_factor=0.71)
    varied = run_to_run.varied_network(sc.device.thermal.network, d, (("base", "table"),))
    text = (SC / "thermal" / "rlg8_003_block.toml").read_text()
    text = text.replace("temperature_c = 23.0", "temperature_c = 24.7")
    text = re.sub(r'(between = \["base", "table"\]\nconductance_w_per_k = )6\.0',
                  lambda m: m.group(1) + repr(6.0 * 0.71), text)
    # chamber-air links: scale every area of a link to chamber_air (h·A and ε·A both ∝ A)
    def scale_areas(m):
        return re.sub(r"area_cm2 = ([0-9.]+)",
                      lambda a: f"area_cm2 = {float(a.group(1)) * 1.23!r}", m.group(0))
    text = re.sub(r'between = \["[a-z_]+", "chamber_air"\]\n(?:(?:convection|radiation)[^\n]*\n)+',
                  scale_areas, text)
    (tmp_path / "th.toml").write_text(text)
    dev = (SC / "devices" / "rlg8_003.toml").read_text().replace(
        'thermal_preset = "rlg8_003_block"', f'thermal_preset = "{tmp_path / "th.toml"}"')
    (tmp_path / "dev.toml").write_text(dev)
    ref = load_device(str(tmp_path / "dev.toml")).thermal.network
    np.testing.assert_allclose(varied.ambient_conductance_w_per_k,
                               ref.ambient_conductance_w_per_k, rtol=1e-12)
    np.testing.assert_allclose(varied.conductance_w_per_k, ref.conductance_w_per_k,
                               rtol=1e-12, atol=1e-15)
    for ambient in (-40.0, 20.0, 60.0):
        np.testing.assert_allclose(varied.steady_state(ambient, True),
                                   ref.steady_state(ambient, True), rtol=0, atol=1e-9)
    np.testing.assert_allclose(varied.time_constants_s(), ref.time_constants_s(), rtol=1e-9)


def test_turn_on_bias_in_the_truth_and_attrs(tmp_path):
    sc = _short()
    d = run_to_run.draw(sc)
    assert d is not None and d.turn_on_bias_deg_per_h[0] != 0.0
    same_day_off = _short(run_seed=None)
    a = simulate(sc, tmp_path / "a.h5", progress=False)
    b = simulate(same_day_off, tmp_path / "b.h5", progress=False)

    def value(path):
        with h5py.File(path) as f:
            names = [n.decode() if isinstance(n, bytes) else n
                     for n in f["truth/coefficient"][()]]
            return float(f["truth/coefficient_value"][()][names.index("gyro.bias.value[z]")])
    assert value(a) - value(b) == pytest.approx(d.turn_on_bias_deg_per_h[0], abs=1e-15)
    with h5py.File(a) as f:
        assert int(f.attrs["run_seed"]) == sc.run_seed
        assert float(f.attrs["run_film_factor"]) == d.film_factor


@pytest.mark.parametrize("table, needle", [
    ("turn_on_bias_deg_per_h = -0.1", "run_to_run.turn_on_bias_deg_per_h"),
    ("film_coefficient_rel = 2.0", "run_to_run.film_coefficient_rel"),
    ("mount_conductance_rel = 0.1", "run_to_run.mount_links: missing"),
    ('mount_conductance_rel = 0.1\nmount_links = [["base", "nowhere"]]', "'nowhere'"),
    ('mount_links = [["base"]]', "run_to_run[0].mount_links"),
    ("colour = 1", "colour"),
])
def test_bad_table_one_line(tmp_path, table, needle):
    dev = (SC / "devices" / "rlg8_003.toml").read_text()
    dev = dev.split("[run_to_run]")[0] + "[run_to_run]\n" + table + "\n"
    dev = dev.replace('thermal_preset = "rlg8_003_block"',
                      f'thermal_preset = "{SC / "thermal" / "rlg8_003_block.toml"}"')
    (tmp_path / "dev.toml").write_text(dev)
    with pytest.raises(UserInputError) as e:
        load_device(str(tmp_path / "dev.toml"))
    msg = str(e.value)
    assert "\n" not in msg and needle in msg and "dev.toml" in msg


def test_bad_run_seed_one_line():
    text = (SC / "paper003_cycles.toml").read_text().replace("run_seed = 3010", "run_seed = -3")
    with pytest.raises(UserInputError) as e:
        parse_scenario(text, "x.toml", base_dir=SC)
    assert "run_seed" in str(e.value) and "\n" not in str(e.value)
