"""Paper 003 study figures over PSO seeds (issue 16): the distribution of what the two PSO-SVR
compensators of ``rlgsim study paper003`` give, per search definition, over several PSO
``random_state`` values, so that a change of the search is judged by its effect on the
figures' distribution rather than on one seed (the choice inside a validation valley that is
flat in C is noisy).

It reuses the study's own code (``rlgsim.lab.studies.gradient_selection``: configuration, data,
input selection, fitting, scoring) and its datasets: the work folder is the study's report
folder (``./paper003-study`` by default, as ``rlgsim study paper003`` writes it), whose
``data/`` is simulated on first use and reused after. Per variant (the named PSOSVR keyword
sets of ``pso_svr_search_cap.py``, applied to both compensators on top of the study file's
params) and seed it fits both models and scores every test run, then prints per variant the
mean ± standard error over the seeds of: each model's bias STD after compensation (Tables 4-5,
°/h), its improvement %, the improvement over the traditional model (paper 003's relative
gain), the multi/3-point STD ratio, the truth-based RMSE (°/h), and the chosen C and gamma;
and per figure the paired difference of each variant from the first (same seeds) with its
standard error. The first seed is the study's own (what its report shows).

    python benchmarks/pso_svr_study_seeds.py [--seeds 10] [--workdir DIR] [VARIANT ...]
    python benchmarks/pso_svr_study_seeds.py cap10000 1se-cap1000
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
for p in (str(HERE), str(HERE.parent)):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402

from _machine import machine  # noqa: E402
from pso_svr_search_cap import VARIANTS  # noqa: E402
from rlgsim.lab.study import load_study, recipe_module  # noqa: E402
from rlgsim.lab.studies.fitting import fit_all  # noqa: E402
from rlgsim.lab.studies.gradient_selection import (improvement_over_traditional,  # noqa: E402
                                                   select_inputs)
from rlgsim.lab.studies.runs import load_experiment  # noqa: E402
from rlgsim.lab.studies.scoring import score_run  # noqa: E402


def study_figures(config, ex, fitted) -> dict[str, float]:
    """The report figures the PSO-SVR models feed, for one set of fitted models."""
    out: dict[str, float] = {}
    for spec in config.test:
        _, table = score_run(ex.runs[spec.key].series, fitted, ex.y, config, config.cluster_s,
                             config.ddof)
        for f in fitted:
            sc = table[f.spec.name]
            short = f.spec.name.split(" ")[0]
            out[f"{spec.label} {short} STD after"] = sc["stability_after"]
            out[f"{spec.label} {short} improvement %"] = sc["improvement_pct"]
            out[f"{spec.label} {short} RMSE truth"] = sc["rmse_true"]
        for pt in config.paper_tables:
            if pt.test == spec.label:
                t, p = table[pt.traditional], table[pt.proposed]
                out[f"{spec.label} gain over traditional %"] = improvement_over_traditional(
                    t["improvement_pct"], p["improvement_pct"])
                out[f"{spec.label} STD ratio 3/multi"] = (t["stability_after"]
                                                          / p["stability_after"])
    for f in fitted:
        short = f.spec.name.split(" ")[0]
        out[f"{short} C"] = f.hyper["C"]
        out[f"{short} gamma"] = f.hyper["gamma"]
    return out


def mean_se(v) -> str:
    v = np.asarray(v, dtype=float)
    se = np.std(v, ddof=1) / np.sqrt(v.size) if v.size > 1 else float("nan")
    return f"{np.mean(v):.5g} ± {se:.2g}"


def main(argv: list[str]) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="*", default=["cap10000", "1se-cap1000"])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workdir", default="paper003-study")
    a = ap.parse_args(argv)
    unknown = [n for n in a.variants if n not in VARIANTS]
    if unknown or a.seeds < 2:
        sys.exit(f"pso_svr_study_seeds: variants must be among {', '.join(VARIANTS)} and "
                 f"--seeds >= 2, got {' '.join(unknown) or a.seeds}")
    print(f"machine: {machine()}")
    study = load_study("paper003")
    recipe = recipe_module(study)
    config = recipe.check(study)
    ex = load_experiment(study, config.train, config.test, config, pathlib.Path(a.workdir),
                         unit=0, progress=False)
    listings = {}

    def prepare(spec):
        if spec.name not in config.selections:
            return spec
        spec, listings[spec.name] = select_inputs(spec, config.selections[spec.name], ex.X,
                                                  ex.y)
        return spec

    seeds = [ex.random_state] + list(range(1, a.seeds))
    print(f"paper003: {ex.y.size} train windows; seeds {seeds} (the first is the study's)")
    results: dict[str, list[dict[str, float]]] = {}
    for name in a.variants:
        kw = VARIANTS[name]
        specs = [dataclasses.replace(c, params={**c.params, **kw}) if c.kind == "pso_svr"
                 else c for c in config.compensators]
        results[name] = []
        for seed in seeds:
            load = os.getloadavg()[0]
            t0 = time.perf_counter()
            fitted = fit_all(specs, ex.X, ex.y, seed, progress=False, prepare=prepare)
            dt = time.perf_counter() - t0
            fig = study_figures(config, ex, fitted)
            fig["fit wall s"] = dt
            results[name].append(fig)
            print(f"  {name} seed {seed}: fits {dt:.1f} s (load {load:.2f}); "
                  + "; ".join(f"{k} {v:.4g}" for k, v in fig.items()
                              if "STD after" in k or k.endswith((" C", " gamma"))), flush=True)
    base = a.variants[0]
    keys = list(results[base][0])
    print(f"\nmean ± standard error over {len(seeds)} seeds (load now {os.getloadavg()[0]:.2f}); "
          f"difference: variant − {base}, paired by seed")
    for k in keys:
        cols = [f"{n}: {mean_se([r[k] for r in results[n]])}" for n in a.variants]
        diffs = [f"Δ{n}: {mean_se([r[k] - b[k] for r, b in zip(results[n], results[base])])}"
                 for n in a.variants[1:]]
        print(f"  {k:>42}  " + "  ".join(cols + diffs))


if __name__ == "__main__":
    main(sys.argv[1:])
