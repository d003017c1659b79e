"""Recipe ``bias_compensation``: one experiment (train runs → test runs) of a single gyro,
every compensator of a paper's tables with the published numbers beside ours (paper 001; also
the demo study).

A study with ``recipe = "bias_compensation"`` (see :mod:`rlgsim.lab.study`) has these tables (runs
and features: :mod:`rlgsim.lab.studies.study_tables`; compensators:
:mod:`rlgsim.lab.studies.compensators`)::

    [data]
    train = ["paper001_train"]
    test = ["paper001_test"]
    window_s = 100                    # averaging window [s] (papers 001-003: 100 s)
    gyro = "z"                        # gyro input axis (default: the device's only gyro)

    [features]
    temperature = "g.A"
    uhfo = true

    [[compensator]]
    name = "LS cubic T"
    kind = "polynomial"
    inputs = ["T"]
    params = { degree = 3 }
    table = "Table 2"                 # optional: the paper table it re-creates
    published = { stability_deg_per_h = 0.01194, improvement_pct = 35.46 }

    [metrics]
    cluster_s = 100                   # bias-stability cluster [s] (a multiple of window_s)
    ddof = 1                          # of the bias-stability std (the papers do not say)
    baseline = "raw"                  # "before" series: the raw bias, or a compensator's name

    [published]                       # optional: the paper's numbers not tied to a compensator
    stability_before_deg_per_h = 0.0185
    correlation = { T = 0.71, "dT/dt" = -0.43, U = -0.82 }

Each compensator is fitted on the train runs (windows stacked) and applied to each test run;
the scores (:func:`rlgsim.lab.studies.scoring.scores`) are the rows of
:class:`~rlgsim.lab.study.StudyResult`. The row ``truth: temperature law`` is the oracle
``ŷ = b − r``: the best any input-driven model can do.
"""

from __future__ import annotations

import pathlib
import time
from typing import Any

import numpy as np

from rlgsim.lab.report import Report
from rlgsim.lab.studies import bias_compensation_report
from rlgsim.lab.studies.bias_compensation_config import (Config, DATA_KEYS, METRIC_KEYS, Outcome,
                                                         PUBLISHED_COMP_KEYS, PUBLISHED_KEYS,
                                                         TOP_KEYS)
from rlgsim.lab.studies.compensators import RAW, parse_compensators
from rlgsim.lab.studies.fitting import fit_all
from rlgsim.lab.studies.imu_axes import parse_navigation
from rlgsim.lab.studies.runs import load_experiment, worth_showing
from rlgsim.lab.studies.scoring import score_run
from rlgsim.lab.studies.study_tables import parse_experiment, parse_metrics
from rlgsim.lab.study import Study, StudyResult
from rlgsim.sim.config import check_known_keys, get_float, get_section, get_str, get_table


def check(study: Study) -> Config:
    """Validate the recipe's tables; :class:`UserInputError` naming file/key/value."""
    data, ctx = study.tables, study.ctx()
    d, features = parse_experiment(study, TOP_KEYS, DATA_KEYS)
    train, test, window_s = d.train, d.test, d.window_s
    feature_names = features.feature_names()
    comps = parse_compensators(data, ctx, feature_names, PUBLISHED_COMP_KEYS,
                               base_dir=study.base_dir)
    names = [c.name for c in comps]
    mtable, mctx, cluster_s, ddof = parse_metrics(data, ctx, window_s, METRIC_KEYS)
    baseline = get_str(mtable, "baseline", mctx, RAW, choices=[RAW] + names)
    parse_navigation(study, names)              # the three-gyro IMU's [navigation] table

    ptable, pctx = get_section(data, "published", ctx, PUBLISHED_KEYS, {})
    published: dict[str, Any] = {}
    if "stability_before_deg_per_h" in ptable:
        published["stability_before"] = get_float(ptable, "stability_before_deg_per_h", pctx)
    corr = get_table(ptable, "correlation", pctx, {})
    cctx = pctx.child("correlation")
    check_known_keys(corr, feature_names, cctx)
    published["correlation"] = {k: get_float(corr, k, cctx, min=-1.0, max=1.0) for k in corr}
    return Config(**vars(features), train=train, test=test, compensators=comps,
                  cluster_s=cluster_s, ddof=ddof, baseline=baseline, published=published)


def run(study: Study, config: Config, workdir: pathlib.Path, *, unit: int = 0,
        progress: bool = True) -> StudyResult:
    """Simulate, fit every compensator on the train runs, score on the test runs."""
    t_start = time.perf_counter()
    ex = load_experiment(study, config.train, config.test, config, workdir, unit=unit,
                         progress=progress)
    runs, train, Xtr, ytr, random_state = ex.runs, ex.train, ex.X, ex.y, ex.random_state
    t_data = ex.t_data

    fitted = fit_all(config.compensators, Xtr, ytr, random_state, progress=progress,
                     share=True)

    rows: list[tuple[str, str, float]] = []
    per_test: dict[str, dict[str, dict[str, float]]] = {}
    predictions: dict[str, dict[str, np.ndarray]] = {}
    multi = len(config.test) > 1
    for spec in config.test:
        preds, table = score_run(runs[spec.key].series, fitted, ytr, config, config.cluster_s,
                                 config.ddof, config.baseline)
        per_test[spec.label] = table
        predictions[spec.label] = preds
        for name, sc in table.items():
            for metric, value in sc.items():
                rows.append((name, f"{metric}@{spec.label}" if multi else metric, float(value)))

    test0 = runs[config.test[0].key].series
    params = {k: v for k, v in test0.coefficients.items() if worth_showing(k)}
    return StudyResult(rows=rows, params=params, details=Outcome(
        runs=runs, train=train, fitted=fitted, per_test=per_test, predictions=predictions,
        Xtr=Xtr, ytr=ytr, unit=unit, t_data=t_data, t_total=time.perf_counter() - t_start))


def fitted_models(config: Config, result: StudyResult) -> list:
    """The fitted compensators, for ``export_models`` (:mod:`rlgsim.lab.study_models`)."""
    from rlgsim.lab.study_models import from_fitted
    return from_fitted(result.details.fitted)


def navigation(study: Study, config: Config, result: StudyResult):
    """The first test run's navigation (:func:`.bias_compensation_report.navigation`):
    (dataset, introduction), or None for a recording."""
    return bias_compensation_report.navigation(study, config, result)


def report(study: Study, config: Config, result: StudyResult) -> Report:
    """The report of a run (:mod:`rlgsim.lab.studies.bias_compensation_report`)."""
    return bias_compensation_report.report(study, config, result)
