"""The compiled heater loop (sim/thermal/_heater_kernel.py) gives the Python step loop's states,
heater powers and controller states bit for bit: one and several heaters, a tracking set
point, saturation at both limits, power switched off and on, split calls."""

from __future__ import annotations

import re
import numpy as np
import pytest

from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator

kernel_module = pytest.importorskip("rlgsim.sim.thermal._heater_kernel")


def network(two_heaters: bool, track: bool, boundary: bool = False) -> ThermalNetwork:
    heaters = {"thermostat": {"node": "base", "sensor": "block", "setpoint_c": 40.0,
                              "max_power_w": 15.0, "kp_w_per_k": 8.0, "ti_s": 3000.0}}
    if track:
        heaters["thermostat"].update(track_node="housing", track_gain=0.5,
                                     track_reference_c=30.0)
    if two_heaters:
        heaters["lid"] = {"node": "housing", "sensor": "housing", "setpoint_c": 35.0,
                          "max_power_w": 6.0, "kp_w_per_k": 3.0, "ti_s": 900.0}
    nodes = {"block": {"capacitance_j_per_k": 400.0, "power_w": 1.0},
             "base": {"capacitance_j_per_k": 2500.0},
             "housing": {"capacitance_j_per_k": 3000.0, "power_w": 4.0}}
    for i in range(20):                          # a realistic size: BLAS's unrolled part too
        nodes[f"n{i}"] = {"capacitance_j_per_k": 50.0 + 10.0 * i}
    links = [{"between": ["block", "base"], "conductance_w_per_k": 0.6},
             {"between": ["base", "housing"], "conductance_w_per_k": 1.0},
             {"between": ["block", "housing"], "conductance_w_per_k": 0.1},
             {"between": ["housing", "chamber_air"], "conductance_w_per_k": 0.4}]
    links += [{"between": [f"n{i}", "block" if i % 2 else "base"],
               "conductance_w_per_k": 0.05 + 0.01 * i} for i in range(20)]
    table = {"nodes": nodes, "links": links, "heaters": heaters}
    if boundary:                                 # two more forcing terms per step
        table["boundaries"] = {"lab": {"temperature_c": 23.0, "amplitude_c": 1.5,
                                       "period_h": 2.0}}
        links.append({"between": ["n3", "lab"], "conductance_w_per_k": 0.8})
    return ThermalNetwork.from_config(table, Ctx("k.toml", "thermal"))


def run(integ: ThermalIntegrator, compiled: bool, splits: list[int], setpoint, power):
    integ.compiled = compiled
    st = integ.initial_state(float(setpoint[0]), True)
    rows, powers, k = [], [], 0
    for m in splits:
        states, st = integ.propagate(st, setpoint[k:k + m + 1], power[k:k + m])
        rows.append(states)
        powers.append(integ.last_heater_power_w.copy())
        k += m
    return np.concatenate(rows), np.concatenate(powers), st


@pytest.mark.parametrize("two_heaters, track, boundary, air_tau_s",
                         [(False, False, False, 60.0), (True, False, False, 60.0),
                          (False, True, False, 60.0), (True, True, False, 0.0),
                          (False, False, True, 60.0), (True, False, True, 0.0)])
def test_compiled_heater_loop_is_bit_identical(two_heaters, track, boundary, air_tau_s):
    if kernel_module._LIB is None:        # numpy's BLAS not the bundled OpenBLAS: the loop stays
        pytest.skip("the compiled heater loop needs numpy's bundled OpenBLAS")
    assert kernel_module.kernel() is not None        # found, and its self-check passed
    integ = ThermalIntegrator(network(two_heaters, track, boundary), 5.0, air_tau_s)
    m = 3000
    t = np.arange(m + 1) * 5.0
    setpoint = np.where(t < 6000, -30.0, 90.0) + 5.0 * np.sin(t / 500.0)
    power = np.ones(m)
    power[700:760] = 0.0                             # off: controllers reset
    power[2000] = 0.0
    splits = [1, 119, 120, 600, 1160, 1000]
    a_states, a_power, a_st = run(integ, False, splits, setpoint, power)
    b_states, b_power, b_st = run(integ, True, splits, setpoint, power)
    assert a_states.tobytes() == b_states.tobytes()
    assert a_power.tobytes() == b_power.tobytes()
    assert np.asarray(a_st).tobytes() == np.asarray(b_st).tobytes()
    assert a_st.modal.tobytes() == b_st.modal.tobytes()
    assert a_st.heaters.tobytes() == b_st.heaters.tobytes()
    p = a_power[power > 0, 0]
    assert np.unique(p).size > 50                    # the controller regulates
    if not (track or two_heaters):    # it reaches both limits: every branch is exercised
        assert (p == 0.0).any() and (p == 15.0).any()


def test_compiled_loop_is_skipped_until_numba_is_imported(monkeypatch):
    import sys
    integ = ThermalIntegrator(network(False, False), 5.0, 60.0)
    monkeypatch.delitem(sys.modules, "numba", raising=False)
    st = integ.initial_state(20.0, True)
    integ.propagate(st, np.full(11, 20.0), np.ones(10))
    assert integ._kernel is None                     # not even looked up


def test_the_kernel_has_no_fused_multiply_add():
    """No fastmath: LLVM may not contract a product and a sum into an FMA (a different
    rounding than numpy's separate multiply and add)."""
    from numba_asm import FMA, compiled_asm
    integ = ThermalIntegrator(network(True, True), 5.0, 60.0)
    integ.compiled = True
    st = integ.initial_state(20.0, True)
    integ.propagate(st, np.full(11, 20.0), np.ones(10))
    asm = compiled_asm(kernel_module.heater_loop, kernel_module.heater_loop.signatures[0])
    assert not re.search(FMA, asm)
