"""Recipe ``environments``: one gyro in several environments, one model per environment and
compensator, trained on one data set and examined on another (paper 002 Table 1).

Paper 002 (``shared/papers/002_*.txt``) §4.1: six environments (constant −40, 20 and 60 °C;
chamber cycles at 1, 3 and 5 °C/min), "the experiments were performed twice and obtained two
data sets, each of which comprised six groups of data. The two data sets were used in modeling
and examination." So each environment has its own train run(s) (data set 1) and test run(s)
(data set 2: the same scenario with another noise seed), and every compensator is fitted per
environment (§5: "a database of the models is then built, and different models are selected
according to the temperature sensor outputs"). §4.2 / Table 1 compare MLR (BIC), the
traditional RBFNN and the modified (Kohonen + OLS) RBFNN by the σ of the 100 s bias before and
after compensation, the improvement factor before/after, and the running time.

Study tables (runs and features: :mod:`rlgsim.lab.studies.study_tables`; compensators:
:mod:`rlgsim.lab.studies.compensators`)::

    [data]
    window_s = 100                    # averaging window [s] (paper 002 §4.1: 100 s)
    gyro = "x"                        # gyro axis (default: the device's only gyro)

    [features]
    temperature = "g.A"               # inputs "T" [°C] and "dT/dt" [K/s]

    [[compensator]]
    name = "MLR (BIC)"
    kind = "mlr_bic"
    inputs = ["T", "dT/dt"]
    params = { degree = 2 }
    published = { equation = "constant + T + dT/dt" }   # optional: the paper's model terms

    [[environment]]
    name = "const -40C"               # unique; no '@' (results are "metric@environment")
    train = [{ scenario = "paper002_const_m40", seed = 2101, skip_h = 1 }]
    test = [{ scenario = "paper002_const_m40", seed = 2201, skip_h = 1 }]
    [environment.published]           # optional: the paper's numbers for this environment
    stability_before_deg_per_h = 7.218e-3
    stability_after_deg_per_h = { "MLR (BIC)" = 13.953e-4 }     # per compensator name
    improvement_factor = { "MLR (BIC)" = 5.17 }                 # before / after
    running_time_s = { "Modified RBFNN" = 79.5 }

    [metrics]
    cluster_s = 100                   # bias-stability cluster [s], a multiple of window_s
    ddof = 1                          # of the bias-stability std (the paper does not say)
    published_before = "mean"         # the paper's "before" figure is the run's mean bias
                                      # (default "sigma": a bias stability); with "mean" the
                                      # report adds Table 1 under that reading
                                      # (:mod:`rlgsim.lab.studies.environments_reading`)

Scores (:func:`rlgsim.lab.studies.scoring.scores`) are computed per test run against its raw
bias stability; with several test runs the environment's score is their mean (and each run's
own score is a row too, ``metric@environment:run``). Rows of :class:`~rlgsim.lab.study.StudyResult`
are ``(compensator, "metric@environment", value)``, including the reference rows ``raw`` (no
compensation) and ``truth: temperature law`` (the oracle ŷ = b − r, the floor of any
input-driven model). Wall-clock fit times appear in the report only, never in the rows (a
Monte Carlo unit's rows depend on the study and the unit alone).

Beyond the paper, the report scores every model against the simulator's truth, checks the
paper's ranking (modified RBFNN ≥ RBFNN > MLR) per environment by bias stability and by the
truth, and explains a failed claim from the numbers: the noise budget of the test runs (white
angle noise and pulse quantisation per window, the slow random bias; their sum is the oracle's
floor) and each model's in-sample (train) against out-of-sample (test) stability.
"""

from __future__ import annotations

import pathlib
import time
from dataclasses import dataclass

from rlgsim.lab.report import Report
from rlgsim.lab.study import Study, StudyResult
from rlgsim.lab.studies import environments_report
from rlgsim.lab.studies.environment_fits import EnvResult, fit_environment
from rlgsim.lab.studies.environment_tables import Config, parse_config
from rlgsim.lab.studies.runs import load_runs, worth_showing


def check(study: Study) -> Config:
    """Validate the recipe's tables (:mod:`rlgsim.lab.studies.environment_tables`);
    :class:`~rlgsim.ground.errors.UserInputError` naming file/key/value."""
    return parse_config(study)


# ------------------------------------------------------------------------------ the run
@dataclass
class Outcome:
    """What :func:`run` hands to :func:`report` (in ``StudyResult.details``)."""

    loaded: dict                # RunSpec.key → LoadedRun
    results: list[EnvResult]    # one per environment, in file order
    unit: int
    t_data: float               # wall time of simulating/reading the runs [s]
    t_total: float              # wall time of data and fits [s]


def _rows(results: list[EnvResult]) -> list[tuple[str, str, float]]:
    """(compensator, metric@environment, value); per test run too when there are several."""
    rows: list[tuple[str, str, float]] = []
    for res in results:
        for name, sc in res.scores.items():
            rows += [(name, f"{m}@{res.env.name}", float(v)) for m, v in sc.items()]
        if len(res.per_test) > 1:
            for label, table in res.per_test.items():
                for name, sc in table.items():
                    rows += [(name, f"{m}@{res.env.name}:{label}", float(v))
                             for m, v in sc.items()]
    return rows


def run(study: Study, config: Config, workdir: pathlib.Path, *, unit: int = 0,
        progress: bool = True) -> StudyResult:
    """Simulate every run, fit each compensator per environment, score on its test runs.

    Fits and report run with one BLAS thread: the networks' linear algebra is small (288
    windows), and on the shared 2-core machine two BLAS threads made a traditional RBFNN fit
    0.74 s instead of 0.013 s (measured with a second study running)."""
    from threadpoolctl import threadpool_limits

    workdir = pathlib.Path(workdir)
    t_start = time.perf_counter()
    loaded = load_runs(study, tuple(s for env in config.environments
                                    for s in env.train + env.test), config, workdir,
                       unit=unit, progress=progress)
    t_data = time.perf_counter() - t_start
    with threadpool_limits(limits=1):
        results = [fit_environment(env, config, loaded, unit, progress)
                   for env in config.environments]
        first_test = results[0].tests[0]
        params = {k: v for k, v in first_test.coefficients.items() if worth_showing(k)}
    return StudyResult(rows=_rows(results), params=params,
                       details=Outcome(loaded=loaded, results=results, unit=unit, t_data=t_data,
                                       t_total=time.perf_counter() - t_start))


def fitted_models(config: Config, result: StudyResult) -> list:
    """The compensators fitted in each environment (names prefixed by the environment), for
    ``export_models`` (:mod:`rlgsim.lab.study_models`)."""
    from rlgsim.lab.study_models import from_fitted
    return [m for res in result.details.results
            for m in from_fitted(res.fitted, prefix=f"{res.env.name} ")]


def navigation(study: Study, config: Config, result: StudyResult):
    """Every environment's navigation (:func:`rlgsim.lab.studies.environments_report.
    navigation`): ({environment: dataset}, introduction), or None."""
    out: Outcome = result.details
    return environments_report.navigation(study, config, out.results, out.loaded, out.unit)


def report(study: Study, config: Config, result: StudyResult) -> Report:
    """The report (:mod:`rlgsim.lab.studies.environments_report`), refits included, with one
    BLAS thread like the fits of :func:`run`."""
    from threadpoolctl import threadpool_limits

    out: Outcome = result.details
    with threadpool_limits(limits=1):
        return environments_report.report(study, config, out.loaded, out.results, out.unit,
                                          out.t_data, out.t_total)
