"""PSO-SVR search definitions compared (issue 16): wall time and converged quality of the
paper-003 PSO-SVR benchmark (``estimators_optimizers.py``: 30 particles x 100 iterations,
N = 2000, train 1600 / validate the last 400) for each named variant, in one run (so the load
affects them alike), with the machine and load.

Quality is the validation RMSE of the chosen (C, gamma) re-fitted to convergence, over that of
the reference optimum re-fitted the same way (target <= 1.01); for the one-standard-error
choice the converged ratio of the search minimum is printed too. Variants (PSOSVR keywords):

    shipped        the default
    cap1000        search_max_iter = 1000
    cap10000       search_max_iter = 10 000, the lowest score chosen (the former default)
    tol0.1         search_tol = 0.1 (libsvm's stopping tolerance of the search fits)
    cap1000-tol0.1 both
    grid0.05       resolution = 0.05 decade
    grid0.05-tol0.1 both
    grid0.1        resolution = 0.1 decade
    1se            selection = "one_se" (cap 10 000)
    1se-cap1000    selection = "one_se", search_max_iter = 1000
    1se-cap3000    selection = "one_se", search_max_iter = 3000
    pse-cap1000    selection = "paired_se", search_max_iter = 1000
    pse            selection = "paired_se" (cap 10 000)

    python benchmarks/pso_svr_search_cap.py cap10000 1se-cap1000
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

VARIANTS = {
    "shipped": {},
    "cap1000": {"search_max_iter": 1000},
    "cap10000": {"search_max_iter": 10_000, "selection": "best"},
    "tol0.1": {"search_tol": 0.1},
    "cap1000-tol0.1": {"search_max_iter": 1000, "search_tol": 0.1},
    "grid0.05": {"resolution": 0.05},
    "grid0.05-tol0.1": {"resolution": 0.05, "search_tol": 0.1},
    "grid0.1": {"resolution": 0.1},
    "1se": {"selection": "one_se", "search_max_iter": 10_000},
    "1se-cap1000": {"selection": "one_se", "search_max_iter": 1000},
    "1se-cap3000": {"selection": "one_se", "search_max_iter": 3000},
    "pse-cap1000": {"selection": "paired_se", "search_max_iter": 1000},
    "pse": {"selection": "paired_se", "search_max_iter": 10_000},
}


def main(argv: list[str]) -> None:
    names = argv or ["cap10000", "cap1000", "1se-cap1000"]
    unknown = [n for n in names if n not in VARIANTS]
    if unknown:
        sys.exit(f"pso_svr_search_cap: unknown variant {unknown[0]!r}; "
                 f"allowed: {', '.join(VARIANTS)}")
    print(f"machine: {machine()}")
    X, y = gradient_data()
    reference = converged_rmse(X, y, BEFORE_C, BEFORE_GAMMA)
    for name in names:
        kw = VARIANTS[name]
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        m = PSOSVR(n_agents=30, max_iter=100, random_state=0, **kw).fit(X, y)
        dt = time.perf_counter() - t0
        p = m.best_params_
        ratio = converged_rmse(X, y, p["C"], p["gamma"]) / reference
        line = (f"{name:>15} {kw}: {dt:6.1f} s wall (target <= {TARGET_S:.0f} s), "
                f"load {load:.2f} -> {os.getloadavg()[0]:.2f}; {m.n_fits_} points, "
                f"{m.n_capped_fits_} capped; C = {p['C']:.4g}, gamma = {p['gamma']:.4g}; "
                f"converged quality ratio {ratio:.4f} (target <= 1.01)")
        if m.selection != "best":
            q = m.min_params_
            line += (f"; search minimum C = {q['C']:.4g}, gamma = {q['gamma']:.4g} "
                     f"(score {m.min_score_:.4g}, one-SE limit {m.one_se_score_:.4g}), "
                     f"its converged ratio "
                     f"{converged_rmse(X, y, q['C'], q['gamma']) / reference:.4f}")
        print(line, flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
