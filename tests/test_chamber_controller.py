"""The chamber's own air loop (rlgsim.sim.thermal.chamber_controller) against independent references.

Reference: the same sampled-data loop written out here independently and integrated between
controller samples by scipy.integrate.solve_ivp (DOP853, rtol = atol = 1e-11) with the
refrigeration-cycling disturbance as a continuous sinusoid.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.thermal.chamber import ChamberProgram
from rlgsim.sim.thermal.chamber_controller import ChamberController, ChamberLoop
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator


def reference_loop(c: ChamberController, loop: ChamberLoop, x0, setpoint, t_end: float,
                   nodes: ThermalNetwork | None = None, T0=None, power: float = 0.0):
    """Air (and node temperatures) at every controller sample by solve_ivp; the controller
    equations (C3) written out independently of the module."""
    h = loop.h
    kp, ti, td = loop.kp, loop.ti, c.td_s
    N = 10.0
    qh, qc = c.max_heating_c_per_min / 60.0, c.max_cooling_c_per_min / 60.0
    D, w = loop.d_amp, 2.0 * math.pi / c.ripple_period_s
    ta, ts, i, d, yp = x0[:5]
    n = 0 if nodes is None else nodes.n_nodes
    T = np.zeros(n) if T0 is None else np.array(T0, float)
    steps = int(round(t_end / h))
    out_air, out_nodes = [], []
    for k in range(steps):
        t = k * h
        y = ts
        if td > 0:
            d = td / (td + N * h) * d - kp * td * N / (td + N * h) * (y - yp)
        e = setpoint(t) - y
        v = kp * e + i + d
        f = min(1.0, max(0.0, (ta - loop.t_zero_c) / (c.lab_c - loop.t_zero_c)))
        u = min(qh, max(-qc * f, v))

        def f(tt, z):
            dz = np.empty_like(z)
            dz[0] = u + D * math.sin(w * tt) - (z[0] - c.lab_c) / c.loss_tau_s
            dz[1] = (z[0] - z[1]) / c.sensor_tau_s
            if n:
                dz[2:] = nodes.derivative(z[2:], z[0], power)
            return dz
        sol = solve_ivp(f, (t, t + h), np.concatenate(([ta, ts], T)), method="DOP853",
                        rtol=1e-11, atol=1e-11)
        z = sol.y[:, -1]
        ta, ts, T = z[0], z[1], z[2:]
        i = i + kp * h / ti * e + h / ti * (u - v)
        yp = y
        out_air.append(ta)
        out_nodes.append(T.copy())
    return np.array(out_air), np.array(out_nodes)


def programme(t):
    """20 °C hold, ramp to 40 °C at 4 K/min, hold, step to 75 °C (saturates), hold."""
    return float(np.interp(t, [0, 600, 900, 2400, 2401, 4000], [20, 20, 40, 40, 75, 75]))


def test_loop_matches_solve_ivp_ripple_overshoot_and_rate():
    c = ChamberController(ripple_amplitude_c=0.3, ripple_period_s=300.0)
    loop = ChamberLoop(c, 2.0)                       # thermal step 2 s, controller 1 s
    assert loop.n_sub == 2
    x0 = loop.initial_state(20.0)
    t_grid = np.arange(0, 4000.0 + 1, 2.0)
    sp = np.array([programme(t) for t in t_grid])
    air, _ = loop.run(x0, sp)
    ref, _ = reference_loop(c, loop, x0, programme, 4000.0)
    ref_grid = ref[1::2]                             # samples at the thermal grid points
    np.testing.assert_allclose(air, ref_grid, atol=1e-7)
    t = t_grid[1:]
    # ripple at constant setpoint: the datasheet fluctuation, around the setpoint
    hold = (t >= 0) & (t < 600)
    assert np.max(np.abs(air[hold] - 20.0)) == pytest.approx(0.3, rel=0.01)
    assert np.max(np.abs(ref_grid[hold] - 20.0)) == pytest.approx(0.3, rel=0.01)
    # overshoot at the end of the 4 K/min ramp (integral action holds the ramp rate)
    after = (t > 900) & (t < 2400)
    over = np.max(air[after]) - 40.0
    assert over > 0.5
    assert over == pytest.approx(np.max(ref_grid[after]) - 40.0, abs=1e-7)
    # step to 75 °C: the heater saturates; the air rises at the authority minus the loss
    rising = (t > 2500) & (air < 70.0) & (air > 45.0)
    slope = np.polyfit(t[rising], air[rising], 1)[0] * 60.0
    lo = c.max_heating_c_per_min - (70 - c.lab_c) / c.loss_tau_s * 60.0
    hi = c.max_heating_c_per_min - (45 - c.lab_c) / c.loss_tau_s * 60.0
    assert lo - 0.2 < slope < hi + 0.2          # ± the cycling disturbance averaged out


def test_loop_with_derivative_term_matches_solve_ivp():
    c = ChamberController(td_s=20.0, kp_per_s=0.05, ti_s=150.0, ripple_amplitude_c=0.1)
    loop = ChamberLoop(c, 1.0)
    x0 = loop.initial_state(20.0)
    t_grid = np.arange(0, 1500.0 + 1, 1.0)
    sp = np.array([programme(t) for t in t_grid])
    air, _ = loop.run(x0, sp)
    ref, _ = reference_loop(c, loop, x0, programme, 1500.0)
    np.testing.assert_allclose(air, ref, atol=1e-7)


def test_nodes_driven_by_the_controlled_air_match_solve_ivp():
    """The network sees the controlled air as a first-order hold on the thermal grid; against
    the fully coupled solve_ivp the node error stays below 1 mK."""
    net = ThermalNetwork(node_names=("a", "b"), capacitance_j_per_k=[50.0, 900.0],
                         conductance_w_per_k=[[0, 0.1], [0.1, 0]],
                         ambient_conductance_w_per_k=[0.05, 1.5], power_w=[0.6, 4.0])
    c = ChamberController(ripple_period_s=120.0, ripple_amplitude_c=0.5)
    integ = ThermalIntegrator(net, 1.0, 60.0, controller=c)
    x = integ.initial_state(20.0, True)
    t_grid = np.arange(0, 1200.0 + 1, 1.0)
    sp = np.array([programme(t) for t in t_grid])
    states, _ = integ.propagate(x, sp, np.ones(1200))
    ref_air, ref_nodes = reference_loop(c, integ.chamber_loop, x.chamber, programme, 1200.0,
                                        nodes=net, T0=np.asarray(x)[1:], power=1.0)
    np.testing.assert_allclose(states[:, 0], ref_air, atol=1e-7)
    np.testing.assert_allclose(states[:, 1:], ref_nodes, atol=1e-3)


def test_split_propagation_with_controller_is_bit_identical():
    net = ThermalNetwork(node_names=("a",), capacitance_j_per_k=[100.0],
                         conductance_w_per_k=[[0.0]], ambient_conductance_w_per_k=[0.5],
                         power_w=[1.0])
    integ = ThermalIntegrator(net, 1.0, 60.0, controller=ChamberController())
    x = integ.initial_state(20.0, True)
    sp = np.array([programme(t) for t in np.arange(0, 3001.0)])
    u = np.ones(3000)
    whole, last = integ.propagate(x, sp, u)
    parts, st = [], x
    for a, b in ((0, 1), (1, 777), (777, 2999), (2999, 3000)):
        s, st = integ.propagate(st, sp[a:b + 1], u[a:b])
        parts.append(s)
    assert np.array_equal(np.concatenate(parts), whole)
    assert np.array_equal(np.asarray(st), np.asarray(last))


def test_initial_state_is_the_periodic_ripple():
    loop = ChamberLoop(ChamberController(ripple_period_s=400.0), 1.0)
    x0 = loop.initial_state(-10.0)
    air, _ = loop.run(x0, np.full(4001, -10.0))
    # no start transient: the first period already has the full, centred ripple
    first, last = air[:400], air[-400:]
    assert np.max(first) == pytest.approx(np.max(last), abs=1e-6)
    assert np.mean(last) == pytest.approx(-10.0, abs=1e-3)


def table(**controller):
    return {"start_c": 20.0, "segments": [{"type": "hold", "duration_s": 60}],
            "controller": controller}


def test_chamber_program_reads_the_controller_table():
    p = ChamberProgram.from_config(table(ripple_amplitude_c=0.5, sensor_tau_s=20.0),
                                   Ctx("s.toml", "chamber"))
    assert p.controller.ripple_amplitude_c == 0.5 and p.controller.sensor_tau_s == 20.0
    assert ChamberProgram.from_config({"start_c": 20.0}, Ctx("s.toml", "chamber")
                                      ).controller is None


@pytest.mark.parametrize("edit, key", [
    ({"ripple_amplitude": 0.3}, "chamber.controller.ripple_amplitude"),
    ({"sensor_tau_s": -1.0}, "chamber.controller.sensor_tau_s"),
    ({"max_heating_c_per_min": 0.0}, "chamber.controller.max_heating_c_per_min"),
    ({"ripple_period_s": "long"}, "chamber.controller.ripple_period_s"),
    ({"min_temperature_c": -150.0, "max_cooling_c_per_min": 2.0},
     "chamber.controller.min_temperature_c"),
])
def test_bad_controller_keys_are_one_line_errors(edit, key):
    with pytest.raises(UserInputError) as e:
        ChamberProgram.from_config(table(**edit), Ctx("s.toml", "chamber"))
    msg = str(e.value)
    assert key in msg and "s.toml" in msg and "\n" not in msg


def test_air_tau_with_a_controller_is_an_error():
    t = table()
    t["air_tau_s"] = 30.0
    with pytest.raises(UserInputError, match="chamber.air_tau_s"):
        ChamberProgram.from_config(t, Ctx("s.toml", "chamber"))
    with pytest.raises(UserInputError, match="chamber.controller"):
        ChamberProgram.from_config({"start_c": 20.0, "controller": 3}, Ctx("s.toml", "chamber"))


def test_cooling_capacity_falls_towards_the_lowest_temperature():
    """A step to −90 °C: the refrigeration runs out of capacity as the air cools; the air
    settles where the remaining capacity equals the insulation loss (above −70 °C)."""
    c = ChamberController(ripple_amplitude_c=0.0, min_temperature_c=-70.0)
    loop = ChamberLoop(c, 1.0)
    x0 = loop.initial_state(20.0)
    prog = lambda t: float(np.interp(t, [0, 100, 101, 3000], [20, 20, -90, -90]))  # noqa
    sp = np.array([prog(t) for t in np.arange(0, 3001.0)])
    air, _ = loop.run(x0, sp)
    ref, _ = reference_loop(c, loop, x0, prog, 3000.0)
    np.testing.assert_allclose(air, ref, atol=1e-7)
    # the lowest temperature it can hold is the datasheet's min_temperature_c
    long, _ = loop.run(x0, np.concatenate([sp, np.full(60000, -90.0)]))
    assert long[-1] == pytest.approx(-70.0, abs=0.01)
    # cooling slows down as the capacity falls: the rate at −20 °C exceeds the rate at −55 °C
    rate = -np.gradient(air) * 60.0
    assert rate[np.argmin(np.abs(air + 20))] > 1.5 * rate[np.argmin(np.abs(air + 55))]


def test_a_controller_is_chosen_by_kind_from_the_registry():
    """``[chamber.controller] kind`` picks the class from the registry (default "pid"); an
    unknown kind is one line naming the key and the allowed kinds; every registered class
    names its own kind and builds its loop."""
    from rlgsim.ground.errors import UserInputError
    from rlgsim.sim.config import Ctx
    from rlgsim.sim.thermal.chamber_controllers import (CONTROLLERS, DEFAULT_KIND,
                                                        controller_from_config)

    ctx = Ctx("s.toml", "chamber.controller")
    plain = controller_from_config({"ripple_amplitude_c": 0.2}, ctx)
    named = controller_from_config({"kind": "pid", "ripple_amplitude_c": 0.2}, ctx)
    assert type(plain) is CONTROLLERS[DEFAULT_KIND] and plain == named
    with pytest.raises(UserInputError, match=r"s\.toml.*kind.*'bang_bang'.*allowed: pid"):
        controller_from_config({"kind": "bang_bang"}, ctx)
    for kind, cls in CONTROLLERS.items():
        assert cls.kind == kind
        loop = cls.from_config({}, ctx).loop(1.0)
        state = loop.initial_state(20.0)         # a tuple of floats, the chamber air first
        assert isinstance(state, tuple) and all(isinstance(v, float) for v in state)
        air, after = loop.run(state, np.full(11, 20.0))
        assert air.shape == (10,) and len(after) == len(state)
        assert np.all(np.isfinite(air))
