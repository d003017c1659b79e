"""Thermal network and its exact integrator (issue 2 acceptance tests).

References: analytic solutions (single node), scipy.integrate.solve_ivp at tight tolerances,
the steady-state ramp-lag formula, paper 003's FEM (gain area ≈ 3.5 °C above non-gain).
"""

from __future__ import annotations

import copy
import pathlib
import pickle
import tomllib

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import curve_fit

from rlgsim.sim.config import Ctx
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.network_parts import CHAMBER_AIR, STEFAN_BOLTZMANN
from rlgsim.sim.thermal.integrator import ThermalIntegrator, ThermalState

PRESETS = pathlib.Path(__file__).resolve().parents[1] / "scenarios" / "thermal"
GAIN = ("A", "B", "C")
NON_GAIN = ("F", "G", "H")


def load_preset(name: str) -> dict:
    with open(PRESETS / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


def network(name: str, *, heaters: bool = True, lab_swing: bool = True) -> ThermalNetwork:
    """A shipped preset's network; ``heaters=False`` leaves out its controlled heaters (the
    linear network, for the tests of the exact linear integrator — the heaters' own loop is
    checked against solve_ivp in test_thermal_heaters.py), ``lab_swing=False`` holds its further
    boundaries (the laboratory) at their mean temperature."""
    data = load_preset(name)["thermal"]
    if not heaters:
        data.pop("heaters", None)
    if not lab_swing:
        for b in data.get("boundaries", {}).values():
            b.pop("amplitude_c", None)
    return ThermalNetwork.from_config(data, Ctx(f"{name}.toml", "thermal"))


@pytest.fixture(scope="module")
def imu() -> ThermalNetwork:
    return network("rlg_imu")


@pytest.fixture(scope="module")
def imu_linear() -> ThermalNetwork:
    """rlg_imu without its thermostat: the linear network."""
    return network("rlg_imu", heaters=False)


@pytest.fixture(scope="module")
def single() -> ThermalNetwork:
    return network("rlg_single")


def small_network() -> ThermalNetwork:
    """Three nodes, one of them fast (stiff), for solve_ivp comparisons."""
    return ThermalNetwork(
        node_names=("a", "b", "c"),
        capacitance_j_per_k=[50.0, 0.4, 900.0],
        conductance_w_per_k=[[0, 0.02, 0.1], [0.02, 0, 0], [0.1, 0, 0]],
        ambient_conductance_w_per_k=[0.01, 0.0, 1.5],
        power_w=[0.6, 0.03, 4.0])


# --------------------------------------------------------------------------- presets


@pytest.mark.parametrize("name, instances", [("rlg_imu", ("gx", "gy", "gz")),
                                             ("rlg_single", ("g",)),
                                             ("rlg_002_fixture", ("g",))])
def test_presets_have_the_documented_nodes(name, instances):
    net = network(name)
    for inst in instances:
        for local in ("A", "B", "C", "D", "E", "F", "G", "H", "discharge", "preamp",
                      "ballast_D", "ballast_E"):
            net.index(f"{inst}.{local}")
        assert net.instances[inst] == "rlg_block"
        # paper 003 Table 2 heat sources
        assert net.power_w[net.index(f"{inst}.discharge")] == pytest.approx(0.588)
        assert net.power_w[net.index(f"{inst}.preamp")] == pytest.approx(0.784)
        assert net.power_w[net.index(f"{inst}.ballast_D")] == pytest.approx(0.027)
        # rlg_002_fixture's nominal unit: the anode-E ballast at the +5 % tolerance edge
        e = 1.05 if name == "rlg_002_fixture" else 1.0
        assert net.power_w[net.index(f"{inst}.ballast_E")] == pytest.approx(0.027 * e)
    for node in ("electronics", "housing_air"):
        net.index(node)
    if name == "rlg_imu":
        for node in ("ax", "ay", "az", "base"):
            net.index(node)
        assert 35 <= net.n_nodes <= 45
        # the IMU's temperature control (docs/thermal.md §4.3): base plate, 50 °C, 10 W
        (h,) = net.heaters
        assert (h.node, h.sensor) == (net.index("base"), net.index("base"))
        assert (h.setpoint_c, h.max_power_w) == (50.0, 10.0)
    if name == "rlg_002_fixture":
        # the mount path (docs/thermal.md §4.2a): base plate, fixture, the laboratory
        for node in ("base", "table"):
            net.index(node)
        assert net.boundary_names == ("lab",)
    # Zerodur capacity from paper 003 Table 1: ρ·c·V of the 1.126 cm³ gain area
    i = net.index(f"{instances[0]}.discharge")
    assert net.capacitance_j_per_k[i] == pytest.approx(2530 * 800 * 1.126e-6)


@pytest.mark.parametrize("name", ["rlg_imu", "rlg_single", "rlg_002_fixture"])
def test_gain_area_sits_3_to_4_degC_above_non_gain(name):
    """Paper 003 FEM: gain area ≈ 3.5 °C above the non-gain area at 20 °C ambient."""
    net = network(name)
    T = net.steady_state(20.0, True)
    for inst in net.instances:
        gain = np.mean([T[net.index(f"{inst}.{k}")] for k in GAIN])
        non_gain = np.mean([T[net.index(f"{inst}.{k}")] for k in NON_GAIN])
        assert 3.0 <= gain - non_gain <= 4.0
        assert T[net.index(f"{inst}.discharge")] > gain       # the source is the hottest glass
    # unpowered, the laboratory (if any) at the chamber's temperature: everything at the air
    lab = np.full(len(net.boundaries), 20.0)
    np.testing.assert_allclose(net.steady_state(20.0, False, lab), 20.0, atol=1e-12)


@pytest.mark.parametrize("name", ["rlg_imu", "rlg_single", "rlg_002_fixture"])
def test_steady_state_heat_balance(name):
    """Power on, constant chamber (and laboratory): heat to the chamber air and the laboratory
    equals the injected power, the thermostat's included (rlg_imu: at its 10 W limit at 20 °C)."""
    net = network(name, lab_swing=False)
    integ = ThermalIntegrator(net, 1.0, 60.0)
    state = integ.initial_state(20.0, True)
    states, _ = integ.propagate(state, np.full(3601, 20.0), np.ones(3600))
    T = states[-1, 1:]
    heater = integ.last_heater_power_w[-1] if net.heaters else None
    P = net.total_power_w(True) + (float(np.sum(heater)) if net.heaters else 0.0)
    lab = net.boundary_temperatures_c(0.0)
    out = net.heat_to_ambient_w(T, 20.0) + net.heat_to_boundaries_w(T, lab)
    assert abs(out - P) <= 1e-9 * P
    # and per node: C dT/dt = 0 to the same relative accuracy
    dT = net.derivative(T, 20.0, True, lab, heater)
    assert np.max(np.abs(dT * net.capacitance_j_per_k)) <= 1e-9 * P
    # the propagation stays on the steady state
    np.testing.assert_allclose(T, net.steady_state(20.0, True), rtol=0, atol=1e-10)


# --------------------------------------------------------------------------- exactness


def test_single_node_matches_analytic_solution():
    """One node behind a lagged ramp: closed-form solution of the two-state cascade."""
    C, g, P = 400.0, 0.5, 2.0
    tau_n = C / g
    tau_a = 90.0
    net = ThermalNetwork(("n",), [C], [[0.0]], [g], [P])
    h = 2.0
    integ = ThermalIntegrator(net, h, tau_a)
    m = 5000
    t = np.arange(m + 1) * h
    r = 0.02                      # K/s setpoint ramp from 10 °C
    s = 10.0 + r * t
    state = integ.state(10.0, [10.0])
    states, _ = integ.propagate(state, s, np.ones(m))
    tt = t[1:]
    # air: lag of a ramp: Ta = s − rτa(1 − e^{−t/τa})
    air = 10.0 + r * tt - r * tau_a * (1 - np.exp(-tt / tau_a))
    # node: T' = (Ta − T)/τn + P/C; superpose ramp response and power step
    a, b = 1 / tau_a, 1 / tau_n
    ramp = (10.0 + r * tt - r * (tau_a + tau_n)
            + r * (tau_a ** 2 * np.exp(-a * tt) - tau_n ** 2 * np.exp(-b * tt)) / (tau_a - tau_n))
    power = P / g * (1 - np.exp(-b * tt))
    np.testing.assert_allclose(states[:, 0], air, rtol=0, atol=1e-9)
    np.testing.assert_allclose(states[:, 1], ramp + power, rtol=0, atol=1e-9)


def _reference(net, tau, t_knots, y_knots, t_on, x0, t_eval):
    def rhs(t, x):
        s = np.interp(t, t_knots, y_knots)
        u = 1.0 if t >= t_on else 0.0
        return np.concatenate(([(s - x[0]) / tau], net.derivative(x[1:], x[0], u)))
    # integrate piece by piece so the solver never steps across a kink of the input
    edges = np.unique(np.concatenate((t_knots, [t_on], [t_eval[-1]])))
    edges = edges[(edges >= 0) & (edges <= t_eval[-1])]
    out = []
    x = np.asarray(x0, float)
    for t0, t1 in zip(edges[:-1], edges[1:]):
        sel = t_eval[(t_eval > t0) & (t_eval <= t1)]
        sol = solve_ivp(rhs, (t0, t1), x, method="Radau", rtol=1e-11, atol=1e-11,
                        first_step=1e-3, dense_output=True)
        assert sol.success
        if sel.size:
            out.append(sol.sol(sel).T)
        x = sol.y[:, -1]
    return np.vstack(out)


def test_exact_integration_matches_solve_ivp_over_a_chamber_ramp():
    """Step response to a FOH ramp programme with a ZOH power switch (stiff small network)."""
    net = small_network()
    tau = 60.0
    h = 1.0
    integ = ThermalIntegrator(net, h, tau)
    m = 4000
    t = np.arange(m + 1) * h
    t_knots = np.array([0.0, 300.0, 1500.0, 2400.0, 4000.0])
    y_knots = np.array([20.0, 20.0, -10.0, -10.0, 30.0])     # ramps of 1.5 and 2.5 °C/min
    t_on = 120.0
    u = (t[:-1] >= t_on).astype(float)
    x0 = integ.initial_state(20.0, False)
    states, _ = integ.propagate(x0, np.interp(t, t_knots, y_knots), u)
    ref = _reference(net, tau, t_knots, y_knots, t_on, np.asarray(x0), t[1:])
    assert np.max(np.abs(states - ref)) < 1e-6


def test_exact_integration_matches_solve_ivp_on_the_imu(imu_linear):
    """The full 42-node IMU network (linear: without its thermostat) through a 2 °C/min ramp
    with power-on."""
    imu = imu_linear
    tau = 45.0
    integ = ThermalIntegrator(imu, 1.0, tau)
    m = 2400
    t = np.arange(m + 1, dtype=float)
    t_knots = np.array([0.0, 200.0, 1400.0, 2400.0])
    y_knots = np.array([20.0, 20.0, 60.0, 60.0])
    u = (t[:-1] >= 100.0).astype(float)
    x0 = integ.initial_state(20.0, False)
    states, _ = integ.propagate(x0, np.interp(t, t_knots, y_knots), u)
    ref = _reference(imu, tau, t_knots, y_knots, 100.0, np.asarray(x0), t[200::200])
    assert np.max(np.abs(states[199::200] - ref)) < 1e-6


def test_air_lag_equal_to_a_node_rate_stays_exact():
    """A node mode with exactly the air's rate (degenerate closed form) is still exact."""
    C, g = 300.0, 5.0
    net = ThermalNetwork(("n",), [C], [[0.0]], [g], [0.0])
    tau = C / g
    integ = ThermalIntegrator(net, 1.0, tau)
    s = np.full(1001, 1.0)
    states, _ = integ.propagate(integ.state(0.0, [0.0]), s, np.zeros(1000))
    tt = np.arange(1, 1001, dtype=float)
    # step through two equal first-order lags: 1 − (1 + t/τ) e^{−t/τ}
    np.testing.assert_allclose(states[:, 1], 1 - (1 + tt / tau) * np.exp(-tt / tau), atol=1e-12)


def test_no_air_lag_means_air_is_the_setpoint():
    net = small_network()
    integ = ThermalIntegrator(net, 0.5, 0.0)
    s = np.linspace(20, 30, 201)
    states, _ = integ.propagate(integ.initial_state(20.0, True), s, np.ones(200))
    np.testing.assert_array_equal(states[:, 0], s[1:])


# --------------------------------------------------------------------------- splitting


def test_split_propagation_is_bit_identical(imu):
    integ = ThermalIntegrator(imu, 1.0, 60.0)
    m = 17003                     # longer than the integrator's internal chunk
    t = np.arange(m + 1, dtype=float)
    s = np.interp(t, [0, 1000, 3000, 9000, m], [-5.0, -5.0, 25.0, 20.0, 40.0])
    u = (t[:-1] >= 333).astype(float)
    x0 = integ.initial_state(-5.0, False)
    whole, last = integ.propagate(x0, s, u)
    for cuts in ([1, 2, 600, 1200, 1201, 7999, 8001, 16999], [8500],
                 list(range(0, m, 600))[1:]):
        edges = [0, *cuts, m]
        state, parts = x0, []
        for a, b in zip(edges[:-1], edges[1:]):
            part, state = integ.propagate(state, s[a:b + 1], u[a:b])
            parts.append(part)
        np.testing.assert_array_equal(np.vstack(parts), whole)
        np.testing.assert_array_equal(np.asarray(state), np.asarray(last))
    # an empty call changes nothing
    part, same = integ.propagate(last, s[-1:], u[:0])
    assert part.shape == (0, 1 + imu.n_nodes)
    np.testing.assert_array_equal(np.asarray(same), np.asarray(last))


def test_state_is_a_plain_array_of_air_and_nodes(imu):
    integ = ThermalIntegrator(imu, 1.0, 60.0)
    x0 = integ.initial_state(20.0, True)
    assert isinstance(x0, np.ndarray) and x0.shape == (1 + imu.n_nodes,)
    assert x0[0] == 20.0
    np.testing.assert_allclose(x0[1:], imu.steady_state(20.0, True), atol=1e-12)
    # pickling keeps the modal coordinates (bit-identical continuation)
    s = np.full(11, 20.0)
    a, _ = integ.propagate(x0, s, np.ones(10))
    b, _ = integ.propagate(pickle.loads(pickle.dumps(x0)), s, np.ones(10))
    np.testing.assert_array_equal(a, b)
    # a plain copy works too (converted to modal coordinates, exact to rounding)
    c, _ = integ.propagate(np.array(x0), s, np.ones(10))
    np.testing.assert_allclose(c, a, rtol=0, atol=1e-11)
    # an edited state is honoured, not silently replaced by the remembered modal coordinates
    edited = integ.initial_state(20.0, True)
    edited[1:] += 1.0
    d, _ = integ.propagate(edited, s, np.ones(10))
    assert np.all(d[:, 1:] > a[:, 1:] + 0.5)
    assert isinstance(edited[1:], np.ndarray) and not isinstance(edited + 1, ThermalState) or \
        (edited + 1).modal is None


def test_propagate_rejects_bad_shapes(imu):
    integ = ThermalIntegrator(imu, 1.0, 60.0)
    x0 = integ.initial_state(20.0, True)
    with pytest.raises(ValueError):
        integ.propagate(x0, np.zeros(5), np.zeros(5))
    with pytest.raises(ValueError):
        integ.propagate(x0[:-1], np.zeros(5), np.zeros(4))


# --------------------------------------------------------------------------- dynamics figures


def _exp_tail(t, a, b, tau):
    return a - b * np.exp(-t / tau)


@pytest.mark.parametrize("name, lo_min, hi_min", [("rlg_imu", 20.0, 60.0),
                                                  ("rlg_single", 15.0, 60.0),
                                                  ("rlg_002_fixture", 15.0, 60.0)])
def test_warm_up_has_a_dominant_time_constant_of_tens_of_minutes(name, lo_min, hi_min):
    """Power on at 20 °C from the unpowered equilibrium; fit the tail of the block warm-up."""
    net = network(name, lab_swing=False)     # rlg_imu's thermostat stays at its limit at 20 °C
    integ = ThermalIntegrator(net, 1.0, 60.0)
    m = 8 * 3600
    states, _ = integ.propagate(integ.initial_state(20.0, False), np.full(m + 1, 20.0),
                                np.ones(m))
    inst = next(iter(net.instances))
    block = np.mean([states[:, 1 + net.index(f"{inst}.{k}")] for k in "ABCDEFGH"], axis=0)
    t = np.arange(1, m + 1, dtype=float)
    tail = t >= 1.5 * 3600
    (a, b, tau), _ = curve_fit(_exp_tail, t[tail], block[tail], p0=(block[-1], 5.0, 1800.0))
    assert lo_min * 60 <= tau <= hi_min * 60
    # the fitted constant is the network's slowest mode (within the mixing of nearby modes)
    slowest = net.time_constants_s()[0]
    assert tau == pytest.approx(slowest, rel=0.15)
    # and the block ends where the steady state says
    T_ss = net.steady_state(20.0, True)
    assert a == pytest.approx(np.mean([T_ss[net.index(f"{inst}.{k}")] for k in "ABCDEFGH"]),
                              abs=0.02)


def test_block_lags_a_1_degC_per_min_ramp_by_the_predicted_amount(imu_linear):
    """In a steady ramp at rate r each node trails the air by r·(K⁻¹C·1)_i (plus the air's own
    lag r·τ_air behind the setpoint); for the IMU's gyro blocks that is ≈ 48 K at 1 °C/min
    (unpowered, so the thermostat is off: the linear network)."""
    imu = imu_linear
    tau = 60.0
    integ = ThermalIntegrator(imu, 1.0, tau)
    r = 1.0 / 60.0                  # 1 °C/min in K/s
    m = 6 * 3600
    t = np.arange(m + 1, dtype=float)
    states, _ = integ.propagate(integ.initial_state(-100.0, False), -100.0 + r * t,
                                np.zeros(m))
    K = imu.stiffness_w_per_k()
    delay = np.linalg.solve(K, imu.capacitance_j_per_k)        # s
    lag_air = (-100.0 + r * t[-1]) - states[-1, 0]
    assert lag_air == pytest.approx(r * tau, abs=1e-6)
    lag_nodes = states[-1, 0] - states[-1, 1:]
    np.testing.assert_allclose(lag_nodes, r * delay, atol=0.05)
    block = [imu.index(f"gx.{k}") for k in "ABCDEFGH"]
    lag_block = float(np.mean(lag_nodes[block]))
    assert 30.0 <= lag_block <= 70.0            # docs/thermal.md: ≈ 48 K at 1 °C/min


# --------------------------------------------------------------------------- realisation


def test_realise_draws_a_unit_around_the_design(imu):
    unit_a = imu.realise(np.random.default_rng(7))
    unit_b = imu.realise(np.random.default_rng(7))
    np.testing.assert_array_equal(unit_a.capacitance_j_per_k, unit_b.capacitance_j_per_k)
    np.testing.assert_array_equal(unit_a.conductance_w_per_k, unit_b.conductance_w_per_k)
    assert not np.array_equal(unit_a.power_w, imu.power_w)
    # structure kept: same links, symmetric, zero stays zero
    assert np.array_equal(unit_a.conductance_w_per_k > 0, imu.conductance_w_per_k > 0)
    np.testing.assert_array_equal(unit_a.conductance_w_per_k, unit_a.conductance_w_per_k.T)
    # spread of the factors matches the tolerance (many draws)
    ratios = np.array([imu.realise(np.random.default_rng(s)).power_w[imu.power_w > 0]
                       / imu.power_w[imu.power_w > 0] for s in range(200)])
    assert np.std(np.log(ratios)) == pytest.approx(imu.tolerance.power_rel, rel=0.1)
    # left/right arm asymmetry appears in a realised unit
    T = unit_a.steady_state(20.0, True)
    assert abs(T[imu.index("gx.D")] - T[imu.index("gx.E")]) > 1e-4


def test_zero_tolerance_realisation_is_the_design():
    net = small_network()
    unit = net.realise(np.random.default_rng(1))
    np.testing.assert_array_equal(unit.capacitance_j_per_k, net.capacitance_j_per_k)
    np.testing.assert_array_equal(unit.power_w, net.power_w)


# --------------------------------------------------------------------------- configuration


def _mini() -> dict:
    return {
        "materials": {"zerodur": {"density_kg_per_m3": 2530.0, "specific_heat_j_per_kg_k": 800.0,
                                  "conductivity_w_per_m_k": 1.46}},
        "templates": {"blk": {"ports": ["air"],
                              "nodes": {"A": {"material": "zerodur", "volume_cm3": 10.0},
                                        "B": {"capacitance_j_per_k": 5.0, "power_w": 1.0}},
                              "links": [{"between": ["A", "B"],
                                         "conduction": {"material": "zerodur", "area_cm2": 2.0,
                                                        "length_mm": 20.0}},
                                        {"between": ["A", "air"],
                                         "convection": {"h_w_per_m2_k": 5.0, "area_cm2": 10.0},
                                         "radiation": {"emissivity": 0.5, "area_cm2": 10.0}}]}},
        "instances": {"g1": {"template": "blk", "ports": {"air": "box"}},
                      "g2": {"template": "blk", "ports": {"air": "box"}}},
        "nodes": {"box": {"mass_kg": 1.0, "specific_heat_j_per_kg_k": 900.0}},
        "links": [{"between": ["box", CHAMBER_AIR], "conductance_w_per_k": 2.0}],
        "tolerance": {"power_rel": 0.1},
    }


def test_from_config_derives_capacities_and_conductances():
    net = ThermalNetwork.from_config(_mini(), Ctx("mini.toml", "thermal"))
    assert net.node_names == ("g1.A", "g1.B", "g2.A", "g2.B", "box")
    assert net.capacitance_j_per_k[0] == pytest.approx(2530 * 800 * 10e-6)
    assert net.capacitance_j_per_k[4] == pytest.approx(900.0)
    G = net.conductance_w_per_k
    assert G[0, 1] == pytest.approx(1.46 * 2e-4 / 0.02)
    h_rad = 4 * 0.5 * STEFAN_BOLTZMANN * (20.0 + 273.15) ** 3
    assert G[0, 4] == pytest.approx((5.0 + h_rad) * 10e-4)
    assert G[1, 4] == 0 and G[0, 2] == 0
    assert net.ambient_conductance_w_per_k.tolist() == [0, 0, 0, 0, 2.0]
    assert net.template_nodes("g2") == ("g2.A", "g2.B")
    assert net.tolerance.power_rel == 0.1


@pytest.mark.parametrize("edit, key", [
    (lambda d: d["templates"]["blk"]["nodes"]["A"].update(volum_cm3=1.0), "volum_cm3"),
    (lambda d: d["templates"]["blk"]["nodes"]["A"].update(volume_cm3=-1.0), "volume_cm3"),
    (lambda d: d["templates"]["blk"]["nodes"]["A"].update(material="glass"), "material"),
    (lambda d: d["templates"]["blk"]["nodes"]["B"].update(capacitance_j_per_k="5"),
     "capacitance_j_per_k"),
    (lambda d: d["templates"]["blk"]["links"][0].update(between=["A", "Q"]), "between"),
    (lambda d: d["templates"]["blk"]["links"][0]["conduction"].pop("length_mm"), "length_mm"),
    (lambda d: d["templates"]["blk"]["links"][1]["radiation"].update(emissivity=1.5),
     "emissivity"),
    (lambda d: d["instances"]["g1"].update(template="blok"), "template"),
    (lambda d: d["instances"]["g1"]["ports"].update(air="bx"), "ports"),
    (lambda d: d["instances"]["g1"]["ports"].update(water="box"), "water"),
    (lambda d: d.update(tolerance={"power": 0.1}), "power"),
    (lambda d: d["links"][0].update(conductance_w_per_k=0.0), "conductance_w_per_k"),
    (lambda d: d.pop("links"), "chamber air"),
])
def test_from_config_errors_name_the_key(edit, key):
    d = copy.deepcopy(_mini())
    edit(d)
    with pytest.raises(UserInputError) as err:
        ThermalNetwork.from_config(d, Ctx("mini.toml", "thermal"))
    msg = str(err.value)
    assert msg.startswith("mini.toml: thermal")
    assert key in msg


def test_index_suggests_close_names(imu):
    with pytest.raises(KeyError, match="gx.A"):
        imu.index("gx.a")


def test_derivative_by_hand():
    """Eq. (3) written out for two nodes: C1 T1' = G(T2 − T1) + g1(Ta − T1) + P1, ..."""
    net = ThermalNetwork(("a", "b"), [10.0, 40.0], [[0, 0.5], [0.5, 0]], [0.2, 0.0], [1.0, 3.0])
    T = np.array([[25.0, 21.0], [20.0, 20.0]])
    got = net.derivative(T, np.array([18.0, 20.0]), np.array([1.0, 0.0]))
    want = np.array([[(0.5 * (21 - 25) + 0.2 * (18 - 25) + 1.0) / 10.0, (0.5 * (25 - 21) + 3.0) / 40.0],
                     [0.0, 0.0]])
    np.testing.assert_allclose(got, want, rtol=1e-15)
    assert net.heat_to_ambient_w(T[0], 18.0) == pytest.approx(0.2 * 7.0)
    np.testing.assert_allclose(net.stiffness_w_per_k(), [[0.7, -0.5], [-0.5, 0.5]])
