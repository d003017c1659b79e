"""RVR and HHO-RVR benchmark (issue 6): RVR fit times at N = 175, 1e3, 1e4 and the full
paper-000 HHO-RVR (30 hawks x 500 iterations, 5-fold CV) on 175 points.

Data: one temperature-related parameter along a -5 -> 65 °C ramp (paper 000 §4.1: 175
calibrations), with non-polynomial structure and white noise; width in K.
Run: ``python benchmarks/bench_estimators.py rvr`` (or this file directly).
"""

from __future__ import annotations

import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
for p in (str(HERE), str(HERE.parent)):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402

from _machine import machine  # noqa: E402
from rlgsim.estimators.rvr import RVR  # noqa: E402
from rlgsim.estimators.tuned import HHORVR  # noqa: E402


def ramp(n: int, seed: int = 0):
    """n calibration points on a -5 -> 65 °C ramp; parameter in arbitrary units, noise 0.02."""
    rng = np.random.default_rng(seed)
    T = np.sort(np.linspace(-5.0, 65.0, n) + 0.1 * rng.standard_normal(n))
    y = 0.01 * T + 0.3 * np.sin(T / 8.0) + 0.1 * np.tanh((T - 30.0) / 3.0)
    return T[:, None], y + 0.02 * rng.standard_normal(n)


def run() -> None:
    print(f"machine: {machine()}")
    print("RVR fit (width 10 K, fastrvm Tipping-Faul core, true noise std 0.02), best of 3:")
    for n in (175, 1_000, 10_000):
        X, y = ramp(n)
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            m = RVR(width=10.0).fit(X, y)
            times.append(time.perf_counter() - t0)
        cand = min(n, m.max_basis)
        print(f"  N = {n:>6d} ({cand} candidates): {min(times):8.3f} s   relevance vectors "
              f"{m.n_relevance_:3d}   iterations {m.n_iter_:5d}   noise std {m.noise_std_:.4f}")
    X, y = ramp(10_000)
    t0 = time.perf_counter()
    try:
        m = RVR(width=10.0, max_basis=None).fit(X, y)
        outcome = (f"relevance vectors {m.n_relevance_}, iterations {m.n_iter_}, "
                   f"noise std {m.noise_std_:.4f}")
    except FloatingPointError as exc:
        outcome = f"FloatingPointError: {exc}"
    print(f"  N =  10000 (all 10000 candidates, max_basis=None): "
          f"{time.perf_counter() - t0:.1f} s — {outcome}")

    X, y = ramp(175)
    print("HHO-RVR, paper 000 set-up: 30 hawks x 500 iterations, 5-fold CV (contiguous), "
          "N = 175:")
    for label, res in (("width grid 1e-3 decade (default)", 1e-3),):
        t0 = time.perf_counter()
        m = HHORVR(n_agents=30, max_iter=500, validation=5, width_resolution=res,
                   random_state=0).fit(X, y)
        dt = time.perf_counter() - t0
        r = m.optimize_result_
        print(f"  {label}: {dt:.1f} s (target < 30 s); {r.nfev} fitness evaluations = "
              f"{r.nfev / dt:.0f} evaluations/s; {m.n_fits_} distinct widths cross-validated "
              f"({5 * m.n_fits_} RVR fits, {5 * m.n_fits_ / dt:.0f} fits/s)")
        print(f"    width {m.width_:.3f} K, CV RMSE {m.best_score_:.5f}, "
              f"{m.estimator_.n_relevance_} relevance vectors; best-so-far CV RMSE at "
              f"iterations 0/10/50/500: " + ", ".join(
                  f"{r.best_curve[i]:.5f}" for i in (0, 10, 50, 500)))
    t0 = time.perf_counter()
    m = HHORVR(n_agents=30, max_iter=50, validation=5, width_resolution=None,
               random_state=0).fit(X, y)
    dt = time.perf_counter() - t0
    r = m.optimize_result_
    print(f"  exact widths (width_resolution=None), 30 hawks x 50 iterations: {dt:.1f} s, "
          f"{r.nfev} evaluations = {r.nfev / dt:.0f} evaluations/s "
          f"(a full 500-iteration exact run would take ~{dt * 10:.0f} s); width {m.width_:.3f} K")


if __name__ == "__main__":
    run()
