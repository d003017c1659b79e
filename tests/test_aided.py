"""The aided navigator (estimators/ins/aided.py) on a simulated route (src/rlgsim/lab/aided_mc.py).

Reference: the truth of the route and the errors each unit draws — exactly the filter's model —
so the filter must be consistent: its NEES eᵀP⁻¹e over units ~ χ²(15). With 4 units the mean
NEES at one epoch has σ = √(2·15/4) ≈ 2.7, and its average over 12 minutes of epochs (whose
errors stay correlated for minutes: roughly 4 independent windows) σ ≈ 1.4; the test asks for
15 ± 4.5 (±3.2σ, so a consistent filter practically never fails it, while a filter told fixes
three times better than they are does, second test). benchmarks/bench_aided_nees.py runs 50 units against the χ² band per epoch.
"""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.estimators.ins.aided import aided_navigation, error_dynamics
from rlgsim.estimators.ins.mechanization import InsState
from rlgsim.ground.errors import UserInputError
from rlgsim.lab.aided_mc import NAV_GRADE, monte_carlo, sample_route
from rlgsim.sim.run.scenario import load_scenario


@pytest.fixture(scope="module")
def route():
    sc = load_scenario("vehicle_land_cold")
    return sample_route(sc.trajectory.build(sc.duration_s), 720.0, 50.0, 50)


def test_consistent_and_aided(route):
    mc = monte_carlo(route, 4, seed0=100)
    assert 15.0 - 4.5 < np.mean(mc["mean_nees"]) < 15.0 + 4.5
    # fixes every second (3 m) and the stops hold the horizontal error near the fix noise
    assert np.percentile(mc["horizontal"][:, 60:], 99) < 5.0


def test_a_wrong_model_is_caught(route):
    """The same draws, the filter told the fixes are 1 m (they are 3 m): its NEES is far above
    15 — the check can fail."""
    import dataclasses
    from rlgsim.estimators.ins.aided import nees
    from rlgsim.lab.aided_mc import run_unit
    told = dataclasses.replace(NAV_GRADE, fix_sigma_h_m=1.0, fix_sigma_u_m=1.5)
    values = [np.mean(nees(err, sol.P)) for sol, err in
              (run_unit(route, seed, NAV_GRADE, told) for seed in (100, 101))]
    assert np.mean(values) > 15.0 + 4.5


def test_error_dynamics_at_rest_match_the_alignment_model():
    """The 15-state F at rest restricted to (ψ_E, ψ_N, ψ_U, δv_E, δv_N) is the fine
    alignment's 5-state model (rlgsim.estimators.ins.alignment.error_model_matrix)."""
    from rlgsim.estimators.ins.alignment import error_model_matrix
    from rlgsim.ground.earth import normal_gravity
    from rlgsim.ground.units import DEG
    lat = 34.0
    f = error_dynamics(np.eye(3), np.array([0, 0, normal_gravity(lat, 0.0)]), lat * DEG, 0.0,
                       np.zeros(3))
    idx = [6, 7, 8, 3, 4]
    np.testing.assert_allclose(f[np.ix_(idx, idx)], error_model_matrix(lat), rtol=1e-12,
                               atol=1e-18)


def test_bad_input_one_line():
    start = InsState.at_rest(np.eye(3), 34.0)
    with pytest.raises(UserInputError, match="shape"):
        aided_navigation(start, np.zeros((10, 2)), np.zeros((10, 2)), 0.01, NAV_GRADE)
    with pytest.raises(UserInputError, match="update_every"):
        aided_navigation(start, np.zeros((10, 3)), np.zeros((10, 3)), 0.01, NAV_GRADE,
                         update_every=0)
