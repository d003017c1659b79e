"""The aided navigator's consistency and coasting error over Monte Carlo units (issue 26).

50 units (``--units``) of rlgsim.estimators.ins.aided on the shipped ``vehicle_land_cold``
route from 1800 s for 1200 s (``--start``, ``--seconds``) at 50 Hz: city driving with stops
and the first 10-min GNSS outage (2400–3000 s), started from the true state (plus the drawn
initial errors). Each unit draws the errors the filter models
(src/rlgsim/lab/aided_mc.py: constant biases, white noise, initial errors, noisy fixes and stop
reports) on the route's exact increments. Prints: the mean NEES over the units at every epoch
against its two-sided 95 % χ² band (Bar-Shalom et al. 2001 §5.4) and the share of epochs inside
it (≈ 95 % for a consistent filter); the horizontal error at the end of the outage (coasting);
the heading error; the estimated against the true gyro biases. With the machine line and the
load average before and after. Usage: ``python benchmarks/bench_aided_nees.py [--units N]
[--seconds S]``.
"""

from __future__ import annotations

import argparse
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _machine import load_text, machine  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    from rlgsim.ground.units import DEG
    from rlgsim.lab.aided_mc import NAV_GRADE, monte_carlo, nees_band, sample_route
    from rlgsim.sim.run.scenario import load_scenario
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=50)
    ap.add_argument("--start", type=float, default=1800.0, help="route time of the start [s]")
    ap.add_argument("--seconds", type=float, default=1200.0)
    args = ap.parse_args(argv)
    print(f"machine: {machine()}")
    print(f"load average before: {load_text()}", flush=True)
    t0 = time.perf_counter()
    sc = load_scenario("vehicle_land_cold")
    route = sample_route(sc.trajectory.build(sc.duration_s), args.seconds, 50.0, 50,
                         start_s=args.start)
    mc = monte_carlo(route, args.units)
    lo, hi = nees_band(args.units)
    inside = (mc["mean_nees"] >= lo) & (mc["mean_nees"] <= hi)
    print(f"{args.units} units × {route.epoch_t.size} epochs (1 s): route {args.start:g} s to "
          f"{args.start + args.seconds:g} s at 50 Hz; {time.perf_counter() - t0:.0f} s")
    print(f"mean NEES (15 states): over all epochs {np.mean(mc['mean_nees']):.2f} (expected 15); "
          f"95 % band of the {args.units}-unit mean [{lo:.2f}, {hi:.2f}]: {inside.mean():.1%} of "
          f"the epochs inside (a consistent filter: ~95 %)")
    for name, sl in (("with fixes", route.visible_at), ("in the outage", ~route.visible_at)):
        if sl.any():
            print(f"  {name}: mean NEES {np.mean(mc['mean_nees'][sl]):.2f}, inside the band "
                  f"{inside[sl].mean():.1%}")
    out = np.flatnonzero(~route.visible_at)
    if out.size:
        end = out[out.size - 1]
        h = mc["horizontal"][:, end]
        print(f"coasting: horizontal error at the end of the outage (route t = "
              f"{args.start + route.epoch_t[end]:g} s,"
              f" {out.size} s without fixes): median {np.median(h):.2f} m, 95th percentile "
              f"{np.percentile(h, 95):.2f} m, max {h.max():.2f} m")
    err = mc["errors"]
    heading = np.degrees(np.abs(err[:, -1, 8])) * 3600.0
    print(f"heading error at the end: median {np.median(heading):.1f}″, 95th percentile "
          f"{np.percentile(heading, 95):.1f}″")
    g = err[:, -1, 9:12] / (NAV_GRADE.gyro_bias_sigma)
    print(f"gyro bias: true − estimated at the end, RMS over units per body axis (x, y, z) "
          f"in units of the prior σ {NAV_GRADE.gyro_bias_sigma / DEG * 3600:.4g} °/h: "
          f"{np.sqrt(np.mean(g ** 2, axis=0)).round(2)} (1 = not learnt)")
    print(f"load average after: {load_text()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
