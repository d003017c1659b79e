"""PSO-SVR search cap trade-off (issue 16): wall time and converged quality of the paper-003
PSO-SVR benchmark (``estimators_optimizers.py``: 30 particles x 100 iterations, N = 2000) for
each ``search_max_iter`` named on the command line, in one run, with the machine and load.

Quality is the validation RMSE of the chosen (C, gamma) re-fitted to convergence, over that of
the reference optimum re-fitted the same way (target <= 1.01). The shipped default is 10 000;
lower caps are faster but choose other points of a valley that is flat in C, which moves the
paper-003 study's models (see the PSOSVR docstring).

    python benchmarks/pso_svr_search_cap.py 1000 10000
"""

from __future__ import annotations

import os
import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
for p in (str(HERE), str(HERE.parent)):
    if p not in sys.path:
        sys.path.insert(0, p)

from _machine import machine  # noqa: E402
from estimators_optimizers import (BEFORE_C, BEFORE_GAMMA, TARGET_S,  # noqa: E402
                                   converged_rmse, gradient_data)
from rlgsim.estimators.tuned import PSOSVR  # noqa: E402


def main(argv: list[str]) -> None:
    try:
        caps = [int(a) for a in argv] or [1000, 10000]
    except ValueError:
        sys.exit(f"pso_svr_search_cap: caps must be integers, got {' '.join(argv)}")
    print(f"machine: {machine()}")
    X, y = gradient_data()
    reference = converged_rmse(X, y, BEFORE_C, BEFORE_GAMMA)
    for cap in caps:
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        m = PSOSVR(n_agents=30, max_iter=100, random_state=0, search_max_iter=cap).fit(X, y)
        dt = time.perf_counter() - t0
        p = m.best_params_
        ratio = converged_rmse(X, y, p["C"], p["gamma"]) / reference
        print(f"search_max_iter {cap:>7}: {dt:6.1f} s wall (target <= {TARGET_S:.0f} s), "
              f"load {load:.2f} -> {os.getloadavg()[0]:.2f}; {m.n_fits_} points, "
              f"{m.n_capped_fits_} capped; C = {p['C']:.4g}, gamma = {p['gamma']:.4g}; "
              f"converged quality ratio {ratio:.4f} (target <= 1.01)")


if __name__ == "__main__":
    main(sys.argv[1:])
