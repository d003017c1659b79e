"""One environment of the ``environments`` recipe (paper 002): every compensator fitted on the
environment's train runs and scored on its test runs (:class:`EnvResult`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rlgsim.lab.studies.environment_tables import Config, Environment
from rlgsim.lab.studies.fitting import Fitted, fit_all, predict
from rlgsim.lab.studies.runs import RunSeries, random_state_for, stack
from rlgsim.lab.studies.scoring import score_run, series_stability


@dataclass
class EnvResult:
    """Everything one environment produced (scores in °/h unless the metric says otherwise)."""

    env: Environment
    train: list[RunSeries]
    tests: list[RunSeries]
    fitted: list[Fitted]
    train_after: dict[str, float]                     # in-sample σ after, per compensator
    train_raw: float                                  # in-sample raw σ (train runs' mean)
    per_test: dict[str, dict[str, dict[str, float]]]  # test label → compensator → scores
    predictions: dict[str, dict[str, np.ndarray]]     # test label → compensator → ŷ [°/h]
    scores: dict[str, dict[str, float]]               # compensator → mean over test runs
    random_state: int                                 # the estimators' random_state


def stability(x: np.ndarray, config: Config) -> float:
    """Bias stability [°/h] of a window series: std (ddof) of ``cluster_s`` means."""
    return series_stability(x, config.window_s, config.cluster_s, config.ddof)


def _mean_scores(per_test: dict[str, dict[str, dict[str, float]]]) -> dict[str, dict[str, float]]:
    """Each compensator's scores averaged over the test runs."""
    first = next(iter(per_test.values()))
    return {name: {m: float(np.mean([t[name][m] for t in per_test.values()])) for m in sc}
            for name, sc in first.items()}


def fit_environment(env: Environment, config: Config, loaded: dict, unit: int,
                     progress: bool) -> EnvResult:
    """Fit every compensator on the environment's train runs and score it on its test runs."""
    train = [loaded[s.key].series for s in env.train]
    Xtr, ytr = stack(train)
    first = loaded[env.train[0].key]           # a recording has no scenario: its seed is 0
    random_state = random_state_for(first.scenario.seed if first.scenario is not None
                                    else first.series.seed, unit)
    fitted = fit_all(config.compensators, Xtr, ytr, random_state, progress=progress,
                     desc=f"fitting {env.name}")
    train_after = {f.spec.name: float(np.mean([stability(rs.y - predict(f, rs), config)
                                               for rs in train])) for f in fitted}
    train_raw = float(np.mean([stability(rs.y, config) for rs in train]))

    per_test: dict[str, dict[str, dict[str, float]]] = {}
    predictions: dict[str, dict[str, np.ndarray]] = {}
    for spec in env.test:
        predictions[spec.label], per_test[spec.label] = score_run(
            loaded[spec.key].series, fitted, ytr, config, config.cluster_s, config.ddof)
    return EnvResult(env=env, train=train,
                     tests=[loaded[s.key].series for s in env.test],
                     fitted=fitted, train_after=train_after, train_raw=train_raw,
                     per_test=per_test, predictions=predictions,
                     scores=_mean_scores(per_test), random_state=random_state)

