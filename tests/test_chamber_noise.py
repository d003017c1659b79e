"""The chamber loop's own noise (sim/thermal/chamber_controller.py, issue 27): read-out noise
and quantisation of the control sensor, irregular conditioning. Off by default (every preset's
bytes unchanged); on, the air at a constant setpoint hunts with the variance linear theory
gives (scipy's discrete Lyapunov solver on the sampled loop), and a run keeps its bytes for any
chunk size."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.sim.run.scenario import parse_scenario
from rlgsim.sim.run.simulate import simulate
from rlgsim.sim.thermal.chamber import ChamberProgram
from rlgsim.sim.thermal.chamber_controller import ChamberController, ChamberLoop


def test_noise_is_off_by_default_and_then_nothing_changes():
    loop = ChamberLoop(ChamberController(), 1.0)
    assert loop.noise_channels == 0 and loop.resolution == 0.0
    x0 = loop.initial_state(20.0)
    sp = np.linspace(20.0, 30.0, 2001)
    plain, s1 = loop.run(x0, sp)
    given, s2 = loop.run(x0, sp, np.ones((2000, 2)))      # draws given but no noise asked
    assert np.array_equal(plain, given) and s1 == s2


def _linearised(loop: ChamberLoop, r: float) -> tuple[np.ndarray, np.ndarray]:
    """One controller sample of the loop as z+ = A z + B w about its rest at setpoint r
    (z = T_a, T_s, I, D, y_prev; w the two standard normal draws), by central differences of
    :meth:`ChamberLoop.run` itself (the loop is affine between clips)."""
    rest = np.array(loop.initial_state(r)[:5])

    def step(z, w):
        st = tuple(z) + (1.0, 0.0)
        _, new = loop.run(st, np.array([r, r]), np.array([w]))
        return np.array(new[:5])
    e = 1e-3
    A = np.column_stack([(step(rest + e * np.eye(5)[j], [0, 0]) - step(rest - e * np.eye(5)[j],
                                                                       [0, 0])) / (2 * e)
                         for j in range(5)])
    B = np.column_stack([(step(rest, np.eye(2)[j] * e) - step(rest, -np.eye(2)[j] * e)) / (2 * e)
                         for j in range(2)])
    return A, B


def test_hunting_at_a_constant_setpoint_has_the_variance_of_linear_theory():
    """Ripple off, read-out noise 0.2 K and conditioning noise 0.5 K/min: the air's variance
    over 200 000 samples equals the stationary variance of the sampled loop driven by the two
    white sequences (scipy.linalg.solve_discrete_lyapunov). Tolerance: the sample variance of a
    process with correlation time τ_c ≈ 100 samples has a relative standard error
    √(2τ_c/N) ≈ 3 %; 12 % is four of them."""
    c = ChamberController(ripple_amplitude_c=0.0, sensor_noise_c=0.2,
                          conditioning_noise_c_per_min=0.5)
    loop = ChamberLoop(c, 1.0)
    assert loop.noise_channels == 2
    A, B = _linearised(loop, 20.0)
    P = solve_discrete_lyapunov(A, B @ B.T)
    n = 200_000
    w = np.random.default_rng(7).standard_normal((n, 2))
    air, _ = loop.run(loop.initial_state(20.0), np.full(n + 1, 20.0), w)
    var = np.var(air[2000:])
    assert var == pytest.approx(P[0, 0], rel=0.12), (var, P[0, 0])
    assert abs(np.mean(air[2000:]) - 20.0) < 0.05 * np.sqrt(P[0, 0]) + 1e-3
    # both sources matter here (each alone: at least a fifth of the variance)
    for k in range(2):
        Pk = solve_discrete_lyapunov(A, np.outer(B[:, k], B[:, k]))
        assert Pk[0, 0] > 0.2 * P[0, 0]


def test_the_controller_reads_a_quantised_sensor():
    """With a 0.1 K reading step and nothing else, the integral action cannot settle between
    two readings: the air hunts (a limit cycle) within about a step of the setpoint, instead of
    the exact hold of the unquantised loop."""
    c = ChamberController(ripple_amplitude_c=0.0, sensor_resolution_c=0.1)
    loop = ChamberLoop(c, 1.0)
    x0 = loop.initial_state(20.04)
    air, _ = loop.run(x0, np.full(20001, 20.04))
    tail = air[5000:]
    assert np.ptp(tail) > 0.01                            # it hunts
    assert np.max(np.abs(tail - 20.04)) < 0.3             # within a few reading steps
    plain = ChamberLoop(ChamberController(ripple_amplitude_c=0.0), 1.0)
    still, _ = plain.run(plain.initial_state(20.04), np.full(20001, 20.04))
    assert np.ptp(still[5000:]) < 1e-9


@pytest.mark.parametrize("key", ["sensor_noise_c", "sensor_resolution_c",
                                 "conditioning_noise_c_per_min"])
def test_bad_noise_keys_are_one_line_errors(key):
    t = {"start_c": 20.0, "segments": [{"type": "hold", "duration_s": 60}],
         "controller": {key: -0.1}}
    with pytest.raises(UserInputError) as e:
        ChamberProgram.from_config(t, Ctx("s.toml", "chamber"))
    assert f"chamber.controller.{key}" in str(e.value) and "\n" not in str(e.value)


SCENARIO = """
name = "noisy_chamber"
device = "rlg_002"
seed = 5
duration_s = 1800
[acquisition]
sample_rate_hz = 1
[chamber]
start_c = 20.0
[[chamber.segments]]
type = "hold"
duration_s = 1800
[chamber.controller]
ripple_amplitude_c = 0.1
sensor_noise_c = 0.02
sensor_resolution_c = 0.0625
conditioning_noise_c_per_min = 0.2
"""


def test_a_noisy_chamber_run_has_the_same_bytes_for_any_chunk_size(tmp_path):
    sc = parse_scenario(SCENARIO, str(tmp_path / "s.toml"))
    a = simulate(sc, tmp_path / "a.h5", progress=False, chunk_s=600.0)
    b = simulate(sc, tmp_path / "b.h5", progress=False, chunk_s=1800.0)
    quiet = parse_scenario(SCENARIO.replace("sensor_noise_c = 0.02", "sensor_noise_c = 0.0")
                           .replace("conditioning_noise_c_per_min = 0.2",
                                    "conditioning_noise_c_per_min = 0.0"),
                           str(tmp_path / "q.toml"))
    q = simulate(quiet, tmp_path / "q.h5", progress=False)
    with h5py.File(a) as fa, h5py.File(b) as fb, h5py.File(q) as fq:
        air_a, air_b = fa["thermal/chamber_air"][()], fb["thermal/chamber_air"][()]
        assert np.array_equal(air_a, air_b)
        assert np.array_equal(fa["imu/gyro_pulses"][()], fb["imu/gyro_pulses"][()])
        # the noise is there: the air differs from the noiseless loop's
        assert not np.array_equal(air_a, fq["thermal/chamber_air"][()])
