"""Controlled heaters: state-dependent, saturating heat sources in the thermal network.

References: solve_ivp of the same sampled-data loop (the controller written out here), the
energy balance with the heaters' energy, the steady state of the active-set solution."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import simpson, solve_ivp

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator


def preset(**heater) -> dict:
    """An IMU-like network: sensor block on a base inside a housing, a heater on the base
    holding the block at 40 °C (paper 000 §1: IMU temperature control)."""
    h = {"node": "base", "sensor": "block", "setpoint_c": 40.0, "max_power_w": 15.0,
         "kp_w_per_k": 8.0, "ti_s": 3000.0}
    h.update(heater)
    return {
        "nodes": {"block": {"capacitance_j_per_k": 400.0, "power_w": 1.0},
                  "base": {"capacitance_j_per_k": 2500.0},
                  "housing": {"capacitance_j_per_k": 3000.0, "power_w": 4.0}},
        "links": [{"between": ["block", "base"], "conductance_w_per_k": 0.6},
                  {"between": ["base", "housing"], "conductance_w_per_k": 1.0},
                  {"between": ["block", "housing"], "conductance_w_per_k": 0.1},
                  {"between": ["housing", "chamber_air"], "conductance_w_per_k": 0.4}],
        "heaters": {"thermostat": h},
    }


def build(t: dict) -> ThermalNetwork:
    return ThermalNetwork.from_config(t, Ctx("h.toml", "thermal"))


def reference(net: ThermalNetwork, h: float, x0, integ0, sp, u):
    """solve_ivp of the sampled loop: PI read at each grid point, power held over the step."""
    H = net.heaters[0]
    T = np.asarray(x0, float)[1:]
    air = float(x0[0])
    I = float(integ0[0])
    Ts, Ps = [], []
    for k in range(len(u)):
        if u[k] > 0:
            target = H.setpoint_c
            if H.track_node >= 0:
                target += H.track_gain * (T[H.track_node] - H.track_reference_c)
            e = target - T[H.sensor]
            v = H.kp_w_per_k * e + I
            P = min(max(v, 0.0), H.max_power_w)
            I = I + H.kp_w_per_k * h / H.ti_s * e + h / H.ti_s * (P - v)
        else:
            P, I = 0.0, 0.0
        s0, s1 = sp[k], sp[k + 1]

        def f(t, z, k=k, P=P, s0=s0, s1=s1):
            a = s0 + (s1 - s0) * (t - k * h) / h
            return net.derivative(z, a, u[k], heater_w=[P])
        sol = solve_ivp(f, (k * h, (k + 1) * h), T, method="Radau", rtol=1e-11, atol=1e-11)
        T = sol.y[:, -1]
        Ts.append(T.copy())
        Ps.append(P)
    del air
    return np.array(Ts), np.array(Ps)


def test_heater_loop_matches_solve_ivp_through_saturation_and_power_off():
    net = build(preset())
    h = 5.0
    integ = ThermalIntegrator(net, h, 0.0)
    x0 = integ.initial_state(10.0, True)
    m = 1200
    t = h * np.arange(m + 1)
    sp = np.interp(t, [0, 600, 3000, 6000], [10, 10, -30, -30])   # cold: heater saturates
    u = np.ones(m)
    u[900:960] = 0.0                                                # power off for 5 min
    states, last = integ.propagate(x0, sp, u)
    P = integ.last_heater_power_w[:, 0]
    ref_T, ref_P = reference(net, h, x0, x0.heaters, sp, u)
    np.testing.assert_allclose(states[:, 1:], ref_T, atol=1e-6)
    np.testing.assert_allclose(P, ref_P, atol=1e-5)
    assert P.max() == pytest.approx(15.0) and np.all(P[900:960] == 0.0)
    assert np.any((P > 0.5) & (P < 14.5))                          # and unsaturated


def test_steady_state_holds_the_set_point_or_sits_at_a_limit():
    net = build(preset())
    i = net.index("block")
    T = net.steady_state(10.0, True)
    P = net.steady_heater_power_w(10.0, True)
    assert T[i] == pytest.approx(40.0, abs=1e-9) and 0 < P[0] < 15
    # heat balance: device power + heater = loss to the air
    assert net.heat_to_ambient_w(T, 10.0) == pytest.approx(5.0 + P[0], rel=1e-10)
    cold = net.steady_heater_power_w(-40.0, True)
    assert cold[0] == pytest.approx(15.0) and net.steady_state(-40.0, True)[i] < 40.0
    hot = net.steady_heater_power_w(45.0, True)
    assert hot[0] == 0.0 and net.steady_state(45.0, True)[i] > 45.0
    # a long integration at constant air settles on the same state
    integ = ThermalIntegrator(net, 10.0, 0.0)
    x = integ.state(10.0, net.steady_state(10.0, False))
    st, last = integ.propagate(x, np.full(20001, 10.0), np.ones(20000))
    np.testing.assert_allclose(st[-1, 1:], T, atol=1e-6)
    assert integ.last_heater_power_w[-1, 0] == pytest.approx(P[0], abs=1e-6)


def test_energy_balance_with_the_state_dependent_heater():
    net = build(preset())
    h = 1.0
    integ = ThermalIntegrator(net, h, 0.0)
    x0 = integ.initial_state(20.0, True)
    m = 7200
    t = h * np.arange(m + 1)
    sp = np.interp(t, [0, 1200, 4800, 7200], [20, 20, -20, -20])
    states, _ = integ.propagate(x0, sp, np.ones(m))
    T = np.vstack([np.asarray(x0)[1:], states[:, 1:]])
    heater_j = integ.last_heater_power_w[:, 0].sum() * h           # exact: held per step
    out_j = simpson(net.heat_to_ambient_w(T, sp), x=t)
    stored = net.capacitance_j_per_k @ (T[-1] - T[0])
    assert stored == pytest.approx(5.0 * t[-1] + heater_j - out_j, rel=1e-5, abs=0.5)
    assert heater_j > 1e4


def test_tracking_set_point_follows_another_node():
    """Paper 001 §2.1: the frequency-stabilisation heater holds the air channel at a
    temperature that follows the cavity (here: sensor = housing, tracking the block)."""
    t = preset(node="housing", sensor="housing", setpoint_c=30.0, track_node="block",
               track_gain=0.5, track_reference_c=30.0, max_power_w=50.0)
    net = build(t)
    T = net.steady_state(15.0, True)
    i, j = net.index("housing"), net.index("block")
    assert T[i] == pytest.approx(30.0 + 0.5 * (T[j] - 30.0), abs=1e-9)
    h = 2.0
    integ = ThermalIntegrator(net, h, 0.0)
    x0 = integ.initial_state(15.0, True)
    sp = np.interp(2.0 * np.arange(601), [0, 200, 1200], [15, 15, 5])
    states, _ = integ.propagate(x0, sp, np.ones(600))
    ref_T, ref_P = reference(net, h, x0, x0.heaters, sp, np.ones(600))
    np.testing.assert_allclose(states[:, 1:], ref_T, atol=1e-6)


def test_split_calls_with_heaters_are_bit_identical():
    net = build(preset())
    integ = ThermalIntegrator(net, 1.0, 60.0)
    x0 = integ.initial_state(0.0, True)
    sp = np.interp(np.arange(9001.0), [0, 3000, 6000], [0, -30, -30])
    u = np.ones(9000)
    whole, last = integ.propagate(x0, sp, u)
    Pw = integ.last_heater_power_w.copy()
    parts, powers, st = [], [], x0
    for a, b in ((0, 1), (1, 4000), (4000, 9000)):
        s, st = integ.propagate(st, sp[a:b + 1], u[a:b])
        parts.append(s)
        powers.append(integ.last_heater_power_w.copy())
    assert np.array_equal(np.concatenate(parts), whole)
    assert np.array_equal(np.concatenate(powers), Pw)


@pytest.mark.parametrize("edit, key", [
    ({"node": "bse"}, "heaters.thermostat.node"),
    ({"sensor": 3}, "heaters.thermostat.sensor"),
    ({"max_power_w": 0}, "heaters.thermostat.max_power_w"),
    ({"track_gain": 1.0}, "heaters.thermostat.track_node"),
    ({"gain": 1.0}, "heaters.thermostat.gain"),
])
def test_bad_heater_keys_are_one_line_errors(edit, key):
    with pytest.raises(UserInputError) as e:
        build(preset(**edit))
    assert key in str(e.value) and "h.toml" in str(e.value) and "\n" not in str(e.value)


def test_a_drawn_unit_draws_its_heater_limit_and_set_point():
    t = preset()
    t["tolerance"] = {"power_rel": 0.1, "heater_setpoint_k": 0.5, "capacitance_rel": 0.05}
    net = build(t)
    units = [net.realise(np.random.default_rng(s)) for s in range(200)]
    sp = np.array([u.heaters[0].setpoint_c for u in units])
    pm = np.array([u.heaters[0].max_power_w for u in units])
    assert abs(sp.mean() - 40.0) < 0.15 and 0.4 < sp.std() < 0.6
    assert 0.07 < np.std(np.log(pm / 15.0)) < 0.13
    # the other draws are those of the same network without heaters
    t2 = preset()
    t2["tolerance"] = t["tolerance"]
    del t2["heaters"]
    plain = build(t2).realise(np.random.default_rng(0))
    assert np.array_equal(plain.capacitance_j_per_k, units[0].capacitance_j_per_k)
