"""Features, metrics and the regression compensators (LS polynomial, MLR with BIC, stepwise) at
the papers' sizes: prints wall-clock times (best of repeats) and what each model chose.

Sizes:

* paper 001 large temperature cycle (§3): 2 h at 25 °C, −1 °C/min to −40 °C, 6 h, +1 °C/min
  to 70 °C, 10 h, −1 °C/min to 25 °C, 4 h ≈ 25.7 h → 924 windows of 100 s; inputs T, dT/dt,
  UHFO; raw channels at 10 Hz (924 000 samples) for the feature step;
* paper 002 (§4.1): 8 h at 100 Hz (2.88 M samples) for windowing and the metrics;
  six environments pooled = 1728 windows for the cubic;
* paper 003 (§4.2): eight probes A–H → 28 pairwise gradients as MLR candidates.

The data are synthetic (``estimators`` never needs ``sim``): the gyro temperature lags the
chamber by a first-order 20 min, UHFO follows the discharge (a smooth function of T), and the
bias (°/h) is a second-order polynomial in T, dT/dt, UHFO plus a non-polynomial term and white
noise.  Run ``python benchmarks/bench_estimators.py regression``.
"""

from __future__ import annotations

import os
import pathlib
import sys
import time
from collections.abc import Callable

import numpy as np
from scipy.signal import lfilter
from threadpoolctl import threadpool_limits

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from _machine import machine  # noqa: E402
from rlgsim.estimators.columns import Columns  # noqa: E402
from rlgsim.estimators.features import pairwise_gradients, window_average, window_features  # noqa: E402
from rlgsim.estimators.input_selection import correlation_ranking, select_by_correlation  # noqa: E402,E501
from rlgsim.estimators.metrics import allan_deviation, bias_stability, improvement_percent  # noqa: E402
from rlgsim.estimators.mlr import MLRBICRegressor  # noqa: E402
from rlgsim.estimators.polynomial import PolynomialRegressor  # noqa: E402
from rlgsim.estimators.stepwise import StepwiseRegressor  # noqa: E402

WINDOW_S = 100.0
MODEL1_START = ("T", "T^2", "dT/dt")


def timed(func: Callable[[], object], repeats: int = 5) -> tuple[float, object]:
    """Shortest wall time (s) of ``repeats`` calls (the least disturbed by other load on the
    machine) and the last result."""
    times, result = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        result = func()
        times.append(time.perf_counter() - t0)
    return min(times), result


def paper001_cycle(rate_hz: float, seed: int) -> Columns:
    """Raw channels of paper 001's large temperature cycle at ``rate_hz``: T (°C), UHFO (V),
    probes A–H (°C) and the gyro bias B (°/h)."""
    legs = [(2 * 3600, 25.0, 25.0), (65 * 60, 25.0, -40.0), (6 * 3600, -40.0, -40.0),
            (110 * 60, -40.0, 70.0), (10 * 3600, 70.0, 70.0), (45 * 60, 70.0, 25.0),
            (4 * 3600, 25.0, 25.0)]
    chamber = np.concatenate([np.linspace(a, b, int(d * rate_hz), endpoint=False)
                              for d, a, b in legs])
    rng = np.random.default_rng(seed)
    alpha = 1.0 / (20 * 60 * rate_hz)                    # 20 min first-order lag
    T, _ = lfilter([alpha], [1.0, alpha - 1.0], chamber, zi=[(1 - alpha) * chamber[0]])
    dTdt = np.gradient(T) * rate_hz
    U = 4.2 - 0.006 * (T - 25) + 2e-5 * (T - 25) ** 2
    bias = (1.4e-3 + 4.9e-4 * T - 4.6e-6 * T**2 - 0.9 * dTdt - 0.35 * (U - 4.2) ** 2
            + 2e-3 * np.tanh((T - 30) / 8)) + rng.normal(0, 0.05, T.size)
    probes = {p: T + (i - 3.5) * 0.3 * (1 + 0.01 * T) + rng.normal(0, 0.01, T.size)
              for i, p in enumerate("ABCDEFGH")}
    return Columns({"T": T + rng.normal(0, 0.01, T.size), "UHFO": U + rng.normal(0, 1e-3, T.size),
                    **probes, "B": bias})


def run() -> None:
    print(f"times: best of 5 runs (1 for the octave ADEV), BLAS limited to 1 thread; load "
          f"average at start {os.getloadavg()[0]:.1f}")
    X = np.random.default_rng(5).uniform(size=(924, 3))
    y = np.random.default_rng(6).normal(size=924)
    default_s, _ = timed(lambda: PolynomialRegressor().fit(X, y))
    with threadpool_limits(limits=1, user_api="blas"):
        single_s, _ = timed(lambda: PolynomialRegressor().fit(X, y))
        print(f"LS cubic, 924 x 3 inputs: {default_s * 1e3:.1f} ms with default BLAS threads, "
              f"{single_s * 1e3:.1f} ms with 1 (small solves only lose to thread start-up and "
              "oversubscription on a busy machine)")
        _run()


def _run() -> None:
    t0 = time.perf_counter()
    raw = paper001_cycle(rate_hz=10.0, seed=1)
    raw_test = paper001_cycle(rate_hz=10.0, seed=2)
    print(f"synthetic paper-001 cycle: {raw.n_samples} samples x {len(raw)} channels at 10 Hz "
          f"(built in {time.perf_counter() - t0:.1f} s)")

    # --- features ------------------------------------------------------------------------
    sec, table = timed(lambda: window_features(raw, 10.0, WINDOW_S, rate_of=["T"],
                                               gradients_of=list("ABCDEFGH")))
    test = window_features(raw_test, 10.0, WINDOW_S, rate_of=["T"],
                           gradients_of=list("ABCDEFGH"))
    print(f"window_features (924k samples -> {table.n_samples} windows, T/UHFO/B means, dT/dt, "
          f"28 gradients): {sec * 1e3:.0f} ms")
    big = np.random.default_rng(0).normal(size=(8 * 3600 * 100, 3))
    sec, _ = timed(lambda: window_average(big, 100.0, WINDOW_S))
    print(f"window_average 2.88 M samples x 3 channels at 100 Hz: {sec * 1e3:.0f} ms")

    # --- metrics -----------------------------------------------------------------------------
    gyro = big[:, 0]
    sec, bs = timed(lambda: bias_stability(gyro, 100.0, WINDOW_S))
    print(f"bias_stability 2.88 M samples, 100 s clusters: {sec * 1e3:.1f} ms")
    sec, ad = timed(lambda: allan_deviation(gyro, 100.0, "octave"), repeats=1)
    print(f"allan_deviation (oadev, octave taus: {len(ad.tau_s)}) 2.88 M samples: {sec:.2f} s")
    sec, ad100 = timed(lambda: allan_deviation(gyro, 100.0, [WINDOW_S]))
    print(f"allan_deviation at tau = 100 s only: {sec * 1e3:.0f} ms "
          f"(ADEV {ad100.adev[0]:.5f} vs bias stability {bs:.5f}, same white noise)")

    # --- compensators on the paper-001 windows ------------------------------------------------
    y, y_test = table["B"], test["B"]
    before = bias_stability(y_test, 1 / WINDOW_S, WINDOW_S)
    inputs3, inputs2 = ["T", "dT/dt", "UHFO"], ["T", "dT/dt"]
    cases = [
        ("LS cubic in T (paper 001 eq. 19)", lambda: PolynomialRegressor(), ["T"]),
        ("LS cubic in T, dT/dt, UHFO (20 coef)", lambda: PolynomialRegressor(), inputs3),
        ("MLR-BIC degree 2 in T, dT/dt (exhaustive, 32 fits)", lambda: MLRBICRegressor(),
         inputs2),
        ("MLR-BIC degree 2 in T, dT/dt, UHFO (exhaustive, 512 fits)",
         lambda: MLRBICRegressor(), inputs3),
        ("MLR-BIC over 28 probe gradients (greedy; they span 7 dimensions, rank-deficient "
         "subsets skipped)", lambda: MLRBICRegressor(degree=1),
         list(pairwise_gradients(raw.select(list("ABCDEFGH")).rows(slice(0, 2))).names)),
        ("stepwise Model 1 (T, dT/dt)",
         lambda: StepwiseRegressor(initial_terms=MODEL1_START), inputs2),
        ("stepwise Model 2 (T, dT/dt, UHFO)",
         lambda: StepwiseRegressor(initial_terms=MODEL1_START), inputs3),
    ]
    print(f"\nfit on {table.n_samples} windows (train cycle), scored on the test cycle; "
          f"bias stability before: {before:.4f} deg/h")
    for label, make, cols in cases:
        X, Xt = table.select(cols), test.select(cols)
        sec, model = timed(lambda: make().fit(X, y))
        after = bias_stability(y_test - model.predict(Xt), 1 / WINDOW_S, WINDOW_S)
        print(f"  {label}: fit {sec * 1e3:.1f} ms, bias stability {after:.4f} deg/h "
              f"({improvement_percent(before, after):.1f} %), {len(model.terms_)} terms")
        if hasattr(model, "search_used_") or hasattr(model, "history_"):
            print(f"      {model.equation('B')}")

    # --- paper 002 pooled size and paper 003 selection -----------------------------------
    rng = np.random.default_rng(3)
    T = rng.uniform(-40, 60, 1728)
    r = rng.uniform(-5 / 60, 5 / 60, 1728)
    b = 7e-3 + 3e-6 * T - 4e-3 * r + 1e-8 * T**3 + rng.normal(0, 6e-4, 1728)
    X002 = Columns({"T": T, "dT/dt": r})
    sec, _ = timed(lambda: PolynomialRegressor().fit(X002, b))
    print(f"\nLS cubic in T, dT/dt on 1728 windows (paper 002, six environments): "
          f"{sec * 1e3:.1f} ms")
    sec, mlr = timed(lambda: MLRBICRegressor().fit(X002, b))
    print(f"MLR-BIC degree 2 on 1728 windows: {sec * 1e3:.0f} ms -> {', '.join(mlr.terms_)}")
    grads = table.select([n for n in table.names if "-" in n])
    sec, kept = timed(lambda: select_by_correlation(grads, y, threshold=0.9))
    top = correlation_ranking(grads, y)[0]
    print(f"select_by_correlation over 28 gradients (|r| >= 0.9, paper 003): {sec * 1e3:.1f} ms, "
          f"kept {len(kept)} (strongest: {top.name}, r = {top.r:.2f})")


if __name__ == "__main__":
    print(f"machine: {machine()}")
    run()
