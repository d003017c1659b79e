"""The airflow of a vehicle's bay (sim/thermal/vehicle_bay.py and its residual heat in
sim/thermal/integrator.py).

Reference: the integrator's exact propagation of the same network with every ambient conductance
scaled by the constant factor φ (dataclasses.replace) — the airflow's residual heat, held over
each step, must converge to it at first order in the step (exponential Euler).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.run.scenario import load_thermal_preset, parse_scenario
from rlgsim.sim.thermal.integrator import ThermalIntegrator
from rlgsim.sim.thermal.vehicle_bay import VehicleBay

NETWORK = load_thermal_preset("rlg_imu").network


def test_factor():
    bay = VehicleBay()
    assert bay.factor(0.0) == 1.0
    # u = 0.1·20 m/s = 2 m/s = 4 u_eq: (1 + 4^2.4)^(1/3)
    assert bay.factor(20.0) == pytest.approx((1 + 4 ** 2.4) ** (1 / 3))
    v = np.linspace(0, 300, 50)
    assert np.all(np.diff(bay.factor(v)) > 0)


def run(network, step, phi, hours=1.0):
    integ = ThermalIntegrator(network, step, 0.0)
    m = int(round(hours * 3600 / step))
    t = np.arange(m + 1) * step
    setpoint = -30.0 + 40.0 * np.minimum(t / 2400.0, 1.0)        # the bay warms
    x0 = integ.initial_state(-30.0, False)
    film = None if phi is None else np.full(m, phi - 1.0)
    states, _ = integ.propagate(x0, setpoint, np.ones(m), film_factor=film)
    return states[:, 1:]


def test_constant_airflow_converges_to_the_scaled_network():
    phi = 2.5
    scaled = dataclasses.replace(
        NETWORK, ambient_conductance_w_per_k=NETWORK.ambient_conductance_w_per_k * phi)
    errs = []
    for step in (2.0, 1.0):
        exact = run(scaled, step, None)
        approx = run(NETWORK, step, phi)
        errs.append(np.max(np.abs(approx - exact)))
    still = run(NETWORK, 1.0, None)
    # the airflow matters (kelvins), the splitting error is small and first order in the step
    assert np.max(np.abs(still - run(scaled, 1.0, None))) > 1.0
    assert errs[1] < 0.02
    assert errs[0] / errs[1] == pytest.approx(2.0, rel=0.1)


def test_no_airflow_is_the_still_air_run():
    a = run(NETWORK, 1.0, None, hours=0.2)
    b = run(NETWORK, 1.0, 1.0, hours=0.2)                        # φ − 1 = 0: stepwise path
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-9)


def test_bay_only_with_a_trajectory():
    text = """
device = "rlg_imu_000"
duration_s = 600
[chamber]
start_c = 20.0
[vehicle_bay]
airflow_fraction = 0.2
"""
    with pytest.raises(UserInputError, match="vehicle_bay: only with"):
        parse_scenario(text, "bay.toml")
    with pytest.raises(UserInputError, match="airflow_fraction"):
        parse_scenario(text.replace("0.2", "2.0") + "[trajectory]\nlatitude_deg = 30\n"
                       "[[trajectory.segment]]\nkind = 'hold'\nduration_s = 60\n", "bay.toml")


def test_profile_segment_joins_its_points_linearly():
    from rlgsim.sim.config import Ctx
    from rlgsim.sim.thermal.chamber import ChamberProgram
    table = {"start_c": -30.0, "segments": [
        {"type": "hold", "duration_min": 5},
        {"type": "profile", "time_min": [0, 10, 30, 40], "temperature_c": [-30, -30, 5, 0]}]}
    sp = ChamberProgram.from_config(table, Ctx("bay.toml", "chamber")).setpoint()
    t = np.array([0, 300, 900, 1500, 2100, 2700, 2900])
    np.testing.assert_allclose(sp(t), [-30, -30, -30, -12.5, 5, 0, 0])
    bad = dict(table)
    bad["segments"] = [{"type": "profile", "time_s": [0, 10, 10], "temperature_c": [1, 2, 3]}]
    with pytest.raises(UserInputError, match="chamber.segments\\[0\\].time_s: needs at least"):
        ChamberProgram.from_config(bad, Ctx("bay.toml", "chamber"))
