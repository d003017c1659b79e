"""Several independent excitations and asymmetry in the thermal network (issue 12):
further boundaries (the laboratory through the turntable shaft), per-face convection with an
airflow direction, fixed nominal asymmetry of an instance. References: scipy.integrate.solve_ivp,
the heat balance, hand-computed conductances."""

from __future__ import annotations

import copy
import pathlib
import tomllib

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator

PRESETS = pathlib.Path(__file__).resolve().parents[1] / "scenarios" / "thermal"


def mount_preset() -> dict:
    """A block on an IMU base, the base on a turntable whose shaft reaches the laboratory."""
    return {
        "boundaries": {"lab": {"temperature_c": 23.0, "amplitude_c": 1.5, "period_h": 2.0,
                               "phase_deg": 30.0}},
        "nodes": {
            "block": {"capacitance_j_per_k": 300.0, "power_w": 2.0},
            "base": {"capacitance_j_per_k": 2000.0},
            "table": {"capacitance_j_per_k": 20000.0},
        },
        "links": [
            {"between": ["block", "base"], "conductance_w_per_k": 0.5},
            {"between": ["block", "chamber_air"], "convection": {"h_w_per_m2_k": 10.0,
                                                                 "area_cm2": 300.0}},
            {"between": ["base", "table"], "conductance_w_per_k": 1.5},
            {"between": ["table", "chamber_air"], "conductance_w_per_k": 4.0},
            {"between": ["table", "lab"], "conductance_w_per_k": 0.8},
        ],
    }


def build(table: dict) -> ThermalNetwork:
    return ThermalNetwork.from_config(table, Ctx("p.toml", "thermal"))


def test_boundary_enters_the_stiffness_and_the_heat_balance():
    net = build(mount_preset())
    assert net.boundary_names == ("lab",)
    i = net.index("table")
    assert net.boundary_conductance_w_per_k[0, i] == 0.8
    lab0 = 23.0 + 1.5 * np.sin(np.radians(30.0))
    np.testing.assert_allclose(net.boundary_temperatures_c(0.0), [lab0])
    T = net.steady_state(-20.0, True)
    # heat balance: all the power leaves to the air and to the laboratory
    out = net.heat_to_ambient_w(T, -20.0) + net.heat_to_boundaries_w(T, [lab0])
    assert out == pytest.approx(2.0, rel=1e-12)
    # unpowered, the table sits between the chamber air and the laboratory
    T0 = net.steady_state(-20.0, False)
    assert -20.0 < T0[i] < lab0
    np.testing.assert_allclose(net.derivative(T0, -20.0, 0.0), 0.0, atol=1e-12)


def test_integration_with_a_boundary_matches_solve_ivp():
    net = build(mount_preset())
    h = 2.0
    integ = ThermalIntegrator(net, h, 60.0)
    x0 = integ.initial_state(20.0, False)
    m = 1800
    t = h * np.arange(m + 1)
    sp = np.interp(t, [0, 600, 2400, 3600], [20, 20, -40, -40])
    u = (t[:-1] >= 300).astype(float)
    states, _ = integ.propagate(x0, sp, u)
    lab = net.boundary_temperatures_c(t)[:, 0]            # the FOH definition of the input

    def f(tt, z):
        s = np.interp(tt, t, sp)
        dair = (s - z[0]) / 60.0
        return np.concatenate(([dair], net.derivative(z[1:], z[0], float(tt >= 300),
                                                       [np.interp(tt, t, lab)])))
    ref = np.empty((m, 1 + net.n_nodes))
    z = np.asarray(x0, float)
    # integrate between input kinks (every grid point is one for the lab FOH): per step
    for k in range(m):
        sol = solve_ivp(f, (t[k], t[k + 1]), z, method="Radau", rtol=1e-11, atol=1e-11)
        z = sol.y[:, -1]
        ref[k] = z
    np.testing.assert_allclose(states, ref, atol=1e-6)
    # the laboratory's cycle is an excitation of its own: without it the table differs
    t2 = mount_preset()
    t2["boundaries"]["lab"]["amplitude_c"] = 0.0
    flat = ThermalIntegrator(build(t2), h, 60.0)
    s_flat, _ = flat.propagate(flat.initial_state(20.0, False), sp, u)
    i = 1 + net.index("table")
    assert np.max(np.abs(s_flat[:, i] - states[:, i])) > 0.05


def test_energy_balance_with_two_boundaries():
    """Σ C ΔT = ∫ (P − heat to the air − heat to the laboratory) dt on a fine grid."""
    net = build(mount_preset())
    h = 0.5
    integ = ThermalIntegrator(net, h, 0.0)
    x0 = integ.initial_state(20.0, True)
    m = 14400
    t = h * np.arange(m + 1)
    sp = np.interp(t, [0, 1200, 4800, 7200], [20, 20, 60, 60])
    states, _ = integ.propagate(x0, sp, np.ones(m))
    T = np.vstack([np.asarray(x0)[1:], states[:, 1:]])
    air = np.concatenate(([x0[0]], states[:, 0]))
    lab = net.boundary_temperatures_c(t)
    flow = 2.0 - net.heat_to_ambient_w(T, air) - net.heat_to_boundaries_w(T, lab)
    stored = net.capacitance_j_per_k @ (T[-1] - T[0])
    from scipy.integrate import simpson
    assert stored == pytest.approx(simpson(flow, x=t), rel=1e-6, abs=1e-3)
    assert abs(stored) > 1e4                                  # a real test: heat moved


def test_split_calls_with_a_periodic_boundary_are_bit_identical():
    net = build(mount_preset())
    integ = ThermalIntegrator(net, 1.0, 60.0)
    x0 = integ.initial_state(20.0, True)
    sp = np.full(20001, 20.0)
    u = np.ones(20000)
    whole, last = integ.propagate(x0, sp, u)
    parts, st = [], x0
    for a, b in ((0, 600), (600, 601), (601, 8500), (8500, 20000)):
        s, st = integ.propagate(st, sp[a:b + 1], u[a:b])
        parts.append(s)
    assert np.array_equal(np.concatenate(parts), whole)
    assert st.time_s == last.time_s == 20000.0
    # a plain array continues at the time given explicitly
    s2, _ = integ.propagate(np.asarray(parts[0][-1]), sp[600:1201], u[600:1200], t0_s=600.0)
    np.testing.assert_allclose(s2, whole[600:1200], atol=1e-9)


def test_airflow_face_factors_scale_the_convection_of_each_face():
    t = mount_preset()
    t["links"][1]["convection"]["face"] = "windward"
    t["links"].append({"between": ["base", "chamber_air"],
                       "convection": {"h_w_per_m2_k": 10.0, "area_cm2": 200.0,
                                      "face": "leeward"}})
    plain = build(copy.deepcopy(t))                # tagged faces, no airflow: factor 1
    t["airflow"] = {"face_factors": {"windward": 1.6, "leeward": 0.5}}
    net = build(t)
    i, j = net.index("block"), net.index("base")
    assert plain.ambient_conductance_w_per_k[i] == pytest.approx(0.30)
    assert net.ambient_conductance_w_per_k[i] == pytest.approx(0.30 * 1.6)
    assert net.ambient_conductance_w_per_k[j] == pytest.approx(0.20 * 0.5)
    t["links"][1]["convection"]["face"] = "top"
    with pytest.raises(UserInputError, match=r"links\[1\]\.convection\.face.*windward"):
        build(t)


def rlg_single() -> dict:
    with open(PRESETS / "rlg_single.toml", "rb") as fh:
        return tomllib.load(fh)["thermal"]


def test_nominal_asymmetry_of_an_instance_breaks_the_arm_symmetry():
    base = rlg_single()
    sym = build(copy.deepcopy(base))
    T = sym.steady_state(20.0, True)
    assert T[sym.index("g.D")] == pytest.approx(T[sym.index("g.E")], abs=1e-12)
    t = copy.deepcopy(base)
    t["instances"]["g"]["power_factors"] = {"ballast_D": 1.3}
    t["instances"]["g"]["link_factors"] = {"discharge--D": 1.05}
    net = build(t)
    k = net.index("g.ballast_D")
    assert net.power_w[k] == pytest.approx(1.3 * sym.power_w[k])
    iD, iq = net.index("g.D"), net.index("g.discharge")
    assert net.conductance_w_per_k[iD, iq] == pytest.approx(1.05 * sym.conductance_w_per_k[iD, iq])
    T = net.steady_state(20.0, True)
    assert T[net.index("g.D")] - T[net.index("g.E")] > 0.01
    # every other number of the design is untouched
    assert np.array_equal(net.capacitance_j_per_k, sym.capacitance_j_per_k)


@pytest.mark.parametrize("edit, key", [
    (lambda t: t["boundaries"]["lab"].update(temp_c=3), "boundaries.lab.temp_c"),
    (lambda t: t["boundaries"]["lab"].update(period_h=0), "boundaries.lab.period_h"),
    (lambda t: t["links"][4].update(between=["table", "lob"]), "links[4].between"),
    (lambda t: t["links"].append({"between": ["lab", "chamber_air"],
                                  "conductance_w_per_k": 1.0}), "links[5].between"),
    (lambda t: t.update(airflow={"face_factors": {"front": -1.0}}),
     "airflow.face_factors.front"),
])
def test_bad_boundary_and_airflow_keys_are_one_line_errors(edit, key):
    t = mount_preset()
    edit(t)
    with pytest.raises(UserInputError) as e:
        build(t)
    assert key in str(e.value) and "p.toml" in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("key, value", [("power_factors", {"Z": 1.1}),
                                        ("link_factors", {"A--Z": 1.1}),
                                        ("capacitance_factors", {"A": 0.0})])
def test_bad_instance_factors_are_errors(key, value):
    t = rlg_single()
    t["instances"]["g"][key] = value
    with pytest.raises(UserInputError, match=f"instances.g.{key}"):
        build(t)


def test_realise_keeps_the_draws_of_a_network_without_boundaries():
    t = mount_preset()
    t["tolerance"] = {"capacitance_rel": 0.05, "conductance_rel": 0.1,
                      "ambient_conductance_rel": 0.1, "power_rel": 0.05}
    with_b = build(copy.deepcopy(t))
    t2 = copy.deepcopy(t)
    del t2["boundaries"]
    t2["links"] = t2["links"][:4]
    without = build(t2)
    a = with_b.realise(np.random.default_rng(5))
    b = without.realise(np.random.default_rng(5))
    assert np.array_equal(a.capacitance_j_per_k, b.capacitance_j_per_k)
    assert np.array_equal(a.power_w, b.power_w)
    i = with_b.index("table")
    assert a.boundary_conductance_w_per_k[0, i] != with_b.boundary_conductance_w_per_k[0, i]
