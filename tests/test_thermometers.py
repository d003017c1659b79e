"""Thermometer probes: exact first-order lag (vs analytic and solve_ivp), noise, resolution."""

from __future__ import annotations

import copy
import pathlib
import tomllib

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rlgsim.sim.config import Ctx
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.thermometers import ProbeSet

PRESETS = pathlib.Path(__file__).resolve().parents[1] / "scenarios" / "thermal"


def preset(name: str) -> tuple[ThermalNetwork, ProbeSet, dict]:
    with open(PRESETS / f"{name}.toml", "rb") as fh:
        data = tomllib.load(fh)
    net = ThermalNetwork.from_config(data["thermal"], Ctx(name, "thermal"))
    return net, ProbeSet.from_config(data["probes"], net, Ctx(name, "probes")), data


def one_node_net() -> ThermalNetwork:
    return ThermalNetwork(("n",), [100.0], [[0.0]], [1.0], [0.0])


def ideal(tau: float, sigma: float = 0.0, q: float = 0.0) -> ProbeSet:
    return ProbeSet(("p",), [0], [tau], [sigma], [q])


RNG = np.random.default_rng


def test_presets_place_the_documented_probes():
    net, probes, _ = preset("rlg_imu")
    expected = [f"{g}.{k}" for g in ("gx", "gy", "gz") for k in "ABCDEFGH"]
    assert list(probes.names) == expected + ["ax", "ay", "az", "base", "housing"]
    assert net.node_names[probes.node_index[probes.names.index("housing")]] == "housing_air"
    assert net.node_names[probes.node_index[probes.names.index("gy.D")]] == "gy.D"
    assert probes.tau_s[probes.names.index("housing")] == 20.0
    assert probes.resolution_c[0] == 0.0625
    net, probes, _ = preset("rlg_single")
    assert list(probes.names) == [f"g.{k}" for k in "ABCDEFGH"] + ["housing"]


def test_lag_of_a_ramp_is_exact():
    """Node ramping at r from equilibrium: θ = T − rτ(1 − e^{−t/τ})."""
    tau, h, r = 7.0, 0.5, 0.03
    probes = ideal(tau)
    t = np.arange(0, 201) * h
    T = (20.0 + r * t)[:, None]
    state = probes.initial_state(T[0])
    reading, _ = probes.read(state, T[1:], h, RNG(0))
    tt = t[1:]
    expected = 20.0 + r * tt - r * tau * (1 - np.exp(-tt / tau))
    np.testing.assert_allclose(reading[:, 0], expected, rtol=0, atol=1e-12)


def test_lag_matches_solve_ivp_for_piecewise_linear_node_temperatures():
    tau, h = 12.0, 1.0
    probes = ideal(tau)
    knots_t = np.array([0.0, 30.0, 90.0, 150.0, 300.0])
    knots_y = np.array([20.0, 25.0, 10.0, 10.0, 40.0])
    t = np.arange(0, 301, dtype=float) * h
    T = np.interp(t, knots_t, knots_y)[:, None]
    reading, _ = probes.read(probes.initial_state(T[0]), T[1:], h, RNG(0))
    sol = solve_ivp(lambda s, th: (np.interp(s, knots_t, knots_y) - th) / tau, (0, 300),
                    [20.0], t_eval=t[1:], rtol=1e-12, atol=1e-12, max_step=0.5)
    assert np.max(np.abs(reading[:, 0] - sol.y[0])) < 1e-8


def test_zero_lag_reads_the_node():
    probes = ideal(0.0)
    T = np.linspace(0, 5, 11)[:, None]
    reading, state = probes.read(probes.initial_state(T[0]), T[1:], 1.0, RNG(0))
    np.testing.assert_array_equal(reading[:, 0], T[1:, 0])
    np.testing.assert_array_equal(state[:, 0], [5.0, 5.0])


def test_splitting_is_bit_identical():
    net, probes, _ = preset("rlg_imu")
    probes = ProbeSet(probes.names, probes.node_index, probes.tau_s,
                      np.zeros(probes.n_probes), np.zeros(probes.n_probes))
    rng = RNG(5)
    T = 20.0 + np.cumsum(rng.normal(0, 0.01, (3000, net.n_nodes)), axis=0)
    start = np.full(net.n_nodes, 20.0)
    whole, last = probes.read(probes.initial_state(start), T, 1.0, RNG(0))
    state, parts = probes.initial_state(start), []
    for a, b in ((0, 1), (1, 600), (600, 601), (601, 3000)):
        part, state = probes.read(state, T[a:b], 1.0, RNG(0))
        parts.append(part)
    np.testing.assert_array_equal(np.vstack(parts), whole)
    np.testing.assert_array_equal(state, last)


def test_noise_is_white_with_the_given_sigma_and_from_the_given_rng():
    probes = ProbeSet(("p", "q"), [0, 0], [0.0, 5.0], [0.05, 0.0], [0.0, 0.0])
    T = np.full((20000, 1), 25.0)
    a, _ = probes.read(probes.initial_state([25.0]), T, 1.0, RNG(11))
    b, _ = probes.read(probes.initial_state([25.0]), T, 1.0, RNG(11))
    c, _ = probes.read(probes.initial_state([25.0]), T, 1.0, RNG(12))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a[:, 0], c[:, 0])
    e = a[:, 0] - 25.0
    assert np.std(e) == pytest.approx(0.05, rel=0.03)
    assert abs(np.mean(e)) < 4 * 0.05 / np.sqrt(e.size)
    assert abs(np.corrcoef(e[:-1], e[1:])[0, 1]) < 0.03            # white
    np.testing.assert_array_equal(a[:, 1], 25.0)                     # σ = 0: no noise


def test_readings_are_quantised_to_the_resolution():
    q = 0.0625
    probes = ideal(3.0, sigma=0.02, q=q)
    T = np.linspace(20, 22, 2001)[:, None]
    reading, _ = probes.read(probes.initial_state(T[0]), T[1:], 1.0, RNG(1))
    steps = reading[:, 0] / q
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    exact, _ = ideal(3.0).read(ideal(3.0).initial_state(T[0]), T[1:], 1.0, RNG(1))
    # quantisation error within half a step of the noisy value (noise 0.02 → 5σ bound)
    assert np.max(np.abs(reading[:, 0] - exact[:, 0])) <= q / 2 + 5 * 0.02


def _probes_table() -> dict:
    return {"defaults": {"tau_s": 5.0, "noise_sigma_c": 0.01, "resolution_c": 0.0625},
            "groups": [{"template": "rlg_block", "nodes": ["A", "F"], "instances": ["gy"],
                        "tau_s": 2.0}],
            "points": {"base": {"node": "base", "resolution_c": 0.01}}}


def test_from_config_groups_points_and_overrides():
    net, _, _ = preset("rlg_imu")
    probes = ProbeSet.from_config(_probes_table(), net, Ctx("p.toml", "probes"))
    assert probes.names == ("gy.A", "gy.F", "base")
    assert probes.tau_s.tolist() == [2.0, 2.0, 5.0]
    assert probes.resolution_c.tolist() == [0.0625, 0.0625, 0.01]
    assert [net.node_names[i] for i in probes.node_index] == ["gy.A", "gy.F", "base"]


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["defaults"].update(tau=5.0), "tau"),
    (lambda d: d["defaults"].update(tau_s=-1.0), "tau_s"),
    (lambda d: d["defaults"].pop("noise_sigma_c"), "noise_sigma_c"),
    (lambda d: d["groups"][0].update(template="rlg"), "template"),
    (lambda d: d["groups"][0].update(nodes=["A", "Z"]), "nodes"),
    (lambda d: d["groups"][0].update(instances=["gw"]), "instances"),
    (lambda d: d["points"]["base"].update(node="bas"), "node"),
    (lambda d: d["points"]["base"].update(resolution_c="0.1"), "resolution_c"),
    (lambda d: d["points"].update({"gy.A": {"node": "base"}}), "gy.A"),
    (lambda d: d.update(extra={}), "extra"),
])
def test_bad_probe_tables_name_the_key(edit, key):
    net, _, _ = preset("rlg_imu")
    d = copy.deepcopy(_probes_table())
    edit(d)
    with pytest.raises(UserInputError) as err:
        ProbeSet.from_config(d, net, Ctx("p.toml", "probes"))
    assert str(err.value).startswith("p.toml: probes")
    assert key in str(err.value)


def test_read_checks_shapes():
    probes = ideal(1.0)
    with pytest.raises(ValueError):
        probes.read(np.zeros(3), np.zeros((4, 1)), 1.0, RNG(0))
    with pytest.raises(ValueError):
        probes.read(probes.initial_state([0.0]), np.zeros(4), 1.0, RNG(0))
