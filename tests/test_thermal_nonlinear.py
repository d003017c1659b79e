"""Nonlinear links: exact radiation to chamber walls that lag the air, natural convection with
h(ΔT). References: solve_ivp (Radau, 1e-10) of the full nonlinear network; the energy balance;
the nonlinear steady state; the linearised network (to show the difference matters)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from scipy.integrate import simpson, solve_ivp

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.network_parts import STEFAN_BOLTZMANN
from rlgsim.sim.thermal.integrator import ThermalIntegrator


def preset() -> dict:
    return {
        "nodes": {"block": {"capacitance_j_per_k": 300.0, "power_w": 2.0},
                  "housing": {"capacitance_j_per_k": 3000.0, "power_w": 6.0},
                  "wall": {"capacitance_j_per_k": 60000.0}},
        "links": [
            {"between": ["block", "housing"], "conductance_w_per_k": 0.5},
            # the housing sees the chamber walls (which lag the air) by radiation ...
            {"between": ["housing", "wall"], "radiation_exact": {"emissivity": 0.8,
                                                                 "area_cm2": 4000.0}},
            # ... and the air by natural convection, h ∝ ΔT^1/4
            {"between": ["housing", "chamber_air"],
             "natural_convection": {"h_ref_w_per_m2_k": 3.0, "reference_dt_k": 5.0,
                                    "area_cm2": 4000.0}},
            {"between": ["wall", "chamber_air"], "conductance_w_per_k": 40.0},
        ],
    }


def build(t: dict) -> ThermalNetwork:
    return ThermalNetwork.from_config(t, Ctx("n.toml", "thermal"))


def programme(t):
    return np.interp(t, [0, 1800, 7800, 12000, 18000], [20, 20, 80, 80, -40])


def test_links_split_into_a_linear_part_and_a_residual():
    net = build(preset())
    assert len(net.nonlinear_links) == 2
    i, j = net.index("housing"), net.index("wall")
    c = 0.8 * STEFAN_BOLTZMANN * 0.4
    assert net.conductance_w_per_k[i, j] == pytest.approx(4 * c * 293.15 ** 3)
    assert net.ambient_conductance_w_per_k[i] == pytest.approx(3.0 * 0.4)
    T = np.array([50.0, 60.0, 20.0])
    flow = net.derivative(T, 10.0, 0.0) * net.capacitance_j_per_k
    # the true flows: radiation housing → wall, convection housing → air with h(ΔT)
    rad = c * ((60 + 273.15) ** 4 - (20 + 273.15) ** 4)
    conv = 3.0 * 0.4 * (50.0 / 5.0) ** 0.25 * 50.0
    assert flow[j] == pytest.approx(rad - 40.0 * 10.0)
    assert flow[i] == pytest.approx(-rad - conv - 0.5 * 10.0)


def test_nonlinear_network_matches_solve_ivp():
    net = build(preset())
    h = 1.0
    integ = ThermalIntegrator(net, h, 60.0)
    x0 = integ.initial_state(20.0, True)
    np.testing.assert_allclose(net.derivative(np.asarray(x0)[1:], 20.0, 1.0), 0.0, atol=1e-12)
    m = 18000
    t = h * np.arange(m + 1)
    sp = programme(t)
    states, _ = integ.propagate(x0, sp, np.ones(m))

    def f(tt, z):
        return np.concatenate(([(programme(tt) - z[0]) / 60.0],
                               net.derivative(z[1:], z[0], 1.0)))
    knots = [0, 1800, 7800, 12000, 18000]
    z = np.asarray(x0, float)
    ref = []
    for a, b in zip(knots[:-1], knots[1:]):
        te = t[(t > a) & (t <= b)]
        sol = solve_ivp(f, (a, b), z, method="Radau", rtol=1e-10, atol=1e-10, t_eval=te)
        ref.append(sol.y.T)
        z = sol.y[:, -1]
    ref = np.concatenate(ref)
    err = np.max(np.abs(states - ref))
    assert err < 2e-3                               # exponential Euler, h = 1 s
    # the nonlinearity matters: the network linearised at 20 °C is off by much more
    t2 = copy.deepcopy(preset())
    t2["links"][1] = {"between": ["housing", "wall"],
                      "radiation": {"emissivity": 0.8, "area_cm2": 4000.0}}
    t2["links"][2] = {"between": ["housing", "chamber_air"],
                      "convection": {"h_w_per_m2_k": 3.0, "area_cm2": 4000.0}}
    lin = ThermalIntegrator(build(t2), h, 60.0)
    s_lin, _ = lin.propagate(lin.initial_state(20.0, True), sp, np.ones(m))
    assert np.max(np.abs(s_lin - ref)) > 100 * err


def test_energy_balance_with_nonlinear_links():
    net = build(preset())
    h = 1.0
    integ = ThermalIntegrator(net, h, 0.0)
    x0 = integ.initial_state(20.0, True)
    m = 12000
    t = h * np.arange(m + 1)
    sp = programme(t)
    states, _ = integ.propagate(x0, sp, np.ones(m))
    T = np.vstack([np.asarray(x0)[1:], states[:, 1:]])
    # Σ C dT/dt = P + heat from the air (linear + nonlinear parts); internal links cancel
    rate = (net.derivative(T, sp, 1.0) * net.capacitance_j_per_k).sum(axis=1)
    stored = net.capacitance_j_per_k @ (T[-1] - T[0])
    assert stored == pytest.approx(simpson(rate, x=t), rel=2e-3)
    assert abs(stored) > 1e6


def test_split_calls_with_nonlinear_links_are_bit_identical():
    net = build(preset())
    integ = ThermalIntegrator(net, 1.0, 60.0)
    x0 = integ.initial_state(20.0, True)
    sp = programme(np.arange(9001.0))
    u = np.ones(9000)
    whole, _ = integ.propagate(x0, sp, u)
    parts, st = [], x0
    for a, b in ((0, 7), (7, 5000), (5000, 9000)):
        s, st = integ.propagate(st, sp[a:b + 1], u[a:b])
        parts.append(s)
    assert np.array_equal(np.concatenate(parts), whole)


def test_realised_unit_scales_the_whole_link():
    t = preset()
    t["tolerance"] = {"conductance_rel": 0.2, "ambient_conductance_rel": 0.2}
    net = build(t)
    unit = net.realise(np.random.default_rng(1))
    i, j = net.index("housing"), net.index("wall")
    f = unit.conductance_w_per_k[i, j] / net.conductance_w_per_k[i, j]
    assert f != 1.0
    rad = [ln for ln in unit.nonlinear_links if ln.kind == "radiation"][0]
    assert rad.coefficient == pytest.approx(0.8 * STEFAN_BOLTZMANN * 0.4 * f)


@pytest.mark.parametrize("link, key", [
    ({"radiation_exact": {"emissivity": 1.5, "area_cm2": 10.0}}, "radiation_exact.emissivity"),
    ({"natural_convection": {"h_ref_w_per_m2_k": 3.0, "area_cm2": 10.0}},
     "natural_convection.reference_dt_k"),
    ({"natural_convection": {"h_ref_w_per_m2_k": 3.0, "reference_dt_k": 5.0, "area_cm2": 10,
                             "exponent": 2.0}}, "natural_convection.exponent"),
])
def test_bad_nonlinear_link_keys_are_one_line_errors(link, key):
    t = preset()
    t["links"][1] = {"between": ["housing", "wall"], **link}
    with pytest.raises(UserInputError) as e:
        build(t)
    assert key in str(e.value) and "\n" not in str(e.value)
