"""Recipe ``gradient_selection``: multiple-point temperature-gradient compensation (paper 003).

Paper 003 (shared/papers/003_*.txt) measures eight points A-H on the RLG block, correlates the
bias with every pairwise temperature gradient (§4.2, Table 3), keeps the gradients with
|r| > 0.90 as the inputs of a PSO-tuned SVM and compares that "multiple-point" model with the
"traditional three-point" one (thermometers on the anode, cathode and shell, §1) on the
training/verification cycles (Table 4) and on a random-rate test (Table 5).

A study with ``recipe = "gradient_selection"`` has, besides ``[study]``, the tables of
:mod:`rlgsim.lab.studies.study_tables` (``[data]`` train/test/window_s/gyro, ``[features]``),
``[[compensator]]`` (:mod:`rlgsim.lab.studies.compensators`) and::

    [[compensator]]                   # a compensator may choose inputs from the train data:
    name = "multi-point PSO-SVM"
    kind = "pso_svr"
    inputs = ["T"]                    # fixed inputs (may be empty: [])
    select = { among = ["g.A", "g.B", "g.C"], min_abs_r = 0.90 }
                                      # + every pairwise gradient of these probes whose |r|
                                      # with the train bias is >= min_abs_r (paper 003 §4.3)

    [correlation]                     # Table 3: r(bias, T_a − T_b) for every pair of points
    points = ["g.A", "g.B", "g.C"]    # (each must be in features.gradients)
    published = [[0, 0.939, 0.938], [0.939, 0, 0.781], [0.938, 0.781, 0]]   # the paper's

    [[paper_table]]                   # Tables 4-5: one per test run
    title = "Table 5: random temperature experiment"
    test = "paper003_random"          # a test run's label (scenario name[-seed<seed>])
    traditional = "3-point PSO-SVM"   # compensator names
    proposed = "multi-point PSO-SVM"
    before_deg_per_h = 0.0283         # the paper's figures: bias STD before [°/h],
    after_deg_per_h = { "3-point PSO-SVM" = 0.0091, "multi-point PSO-SVM" = 0.0023 }   # after
    improvement_pct = { "3-point PSO-SVM" = 67.8, "multi-point PSO-SVM" = 91.9 }
    improvement_over_traditional_pct = 35.5

    [metrics]
    cluster_s = 100                   # STD of 100 s clusters (paper 003 eq. 11)
    ddof = 1

"Improvement from the traditional method" in paper 003 Tables 4-5 is the relative gain of the
improvement percentage: (91.9 − 65.5)/65.5 = 40.3 %, (91.9 − 67.8)/67.8 = 35.5 %; we compute it
the same way and also give the ratio of the compensated STDs. Series:
:mod:`rlgsim.lab.studies.runs`; scores: :mod:`rlgsim.lab.studies.scoring`.
"""

from __future__ import annotations
import dataclasses
import itertools
import pathlib
import time

import numpy as np

from rlgsim.lab.report import Report
from rlgsim.lab.study import Study, StudyResult
from rlgsim.lab.studies import gradient_selection_report
from rlgsim.lab.studies.compensators import CompensatorSpec
from rlgsim.lab.studies.fitting import fit_all
from rlgsim.lab.studies.gradient_selection_config import (Config, Outcome, Selection, column_name,
                                                          parse)
from rlgsim.lab.studies.gradient_selection_report import (  # noqa: F401 (the recipe's figures)
    improvement_over_traditional, table3_figures)
from rlgsim.lab.studies.runs import dataset_for, load_experiment, run_scenario, worth_showing
from rlgsim.lab.studies.scoring import score_run


def check(study: Study) -> Config:
    """Validate the recipe's tables; :class:`UserInputError` naming file/key/value."""
    return parse(study)


# ------------------------------------------------------------------------------ selection
def correlation_matrix(X, y: np.ndarray, points: tuple[str, ...]) -> np.ndarray:
    """r(y, T_a − T_b) for every pair of ``points`` (symmetric, zero diagonal: Table 3's
    layout). The gradient columns are named "a-b" with a before b in features.gradients."""
    n = len(points)
    m = np.zeros((n, n))
    names = set(X.names)
    for i, j in itertools.combinations(range(n), 2):
        a, b = points[i], points[j]
        col, sign = (f"{a}-{b}", 1.0) if f"{a}-{b}" in names else (f"{b}-{a}", -1.0)
        m[i, j] = m[j, i] = sign * float(np.corrcoef(X[col], y)[0, 1])
    return m



def select_inputs(spec: CompensatorSpec, sel: Selection, X, y: np.ndarray
                  ) -> tuple[CompensatorSpec, list[tuple[str, float, bool]]]:
    """``spec`` with the gradients of ``sel`` that pass |r| ≥ min_abs_r appended to its inputs
    (strongest first, as rlgsim.estimators.input_selection ranks them); also every candidate with
    its r and whether it was kept."""
    from rlgsim.estimators.input_selection import correlation_ranking
    names = set(X.names)
    cands = [column_name(a, b, names) for a, b in itertools.combinations(sel.among, 2)]
    ranked = correlation_ranking(X.select(cands), y)
    kept = [r.name for r in ranked if abs(r.r) >= sel.min_abs_r and r.name not in spec.inputs]
    if not kept and not spec.inputs:
        best = ranked[0]
        raise spec.ctx.error("select", f"no gradient among {', '.join(sel.among)} reaches "
                                       f"|r| >= {sel.min_abs_r:g} with the train bias (largest: "
                                       f"{best.name} with r = {best.r:+.3f}); lower min_abs_r")
    listing = [(r.name, float(r.r), r.name in kept) for r in ranked]
    return dataclasses.replace(spec, inputs=spec.inputs + tuple(kept)), listing



def _simulate(study: Study, spec, workdir: pathlib.Path, unit: int) -> tuple:
    """(path, reused) of :func:`rlgsim.lab.studies.runs.dataset_for` (a task of
    :func:`_simulated`: the scenario stays with the caller)."""
    path, _, reused = dataset_for(study, spec, workdir, unit=unit, progress=False)
    return path, reused


def _start_test_runs(study: Study, config: Config, workdir: pathlib.Path, unit: int):
    """The test runs' datasets started in a worker process
    (:class:`rlgsim.lab.studies.task_share.TaskShare`), to be simulated while the train runs
    are simulated here (:func:`_runs_done`): (share, its specs), or None — inside a worker
    process, on one core, with a recording among the runs, a dataset label used with two
    different skips (:func:`rlgsim.lab.studies.runs.load_runs` would report the second as
    reused), or no test run with a dataset of its own."""
    from rlgsim.lab.recordings import recording_path
    from rlgsim.lab.studies.task_share import TaskShare
    specs = list({s.key: s for s in config.train + config.test}.values())
    if len({s.label for s in specs}) != len(specs) or any(
            recording_path(s.ref, study.base_dir, str(study.source)) is not None for s in specs):
        return None
    train_labels = {s.label for s in config.train}
    later = [s for s in specs if s.label not in train_labels]
    share = TaskShare(_simulate, [(study, s, workdir, unit) for s in later], background=True)
    return (share, later) if share.pool is not None else None


def _runs_done(started, study: Study, config: Config, workdir: pathlib.Path, unit: int,
               progress: bool) -> dict | None:
    """``done`` for :func:`load_experiment` (RunSpec.key → dataset_for's answer): the train
    runs simulated here, then the test runs the worker started (:func:`_start_test_runs`;
    those it has not begun are simulated here) — the same files and flags as one after the
    other. None when nothing was started."""
    if started is None:
        return None
    share, later = started
    try:
        done = {}
        for s in config.train:
            if s.key not in done:                       # once per run, as load_runs does
                done[s.key] = dataset_for(study, s, workdir, unit=unit, progress=progress)
        for s, (path, reused) in zip(later, share.results()):
            done[s.key] = (path, run_scenario(study, s, unit), reused)
    finally:
        share.close()
    return done


def _start_workers(rows: int, n_jobs) -> None:
    """:func:`rlgsim.estimators.tuned.start_search_workers`; a failure only loses the head
    start (the search starts its workers itself)."""
    from rlgsim.estimators.tuned import start_search_workers
    try:
        start_search_workers(rows, n_jobs)
    except Exception:           # noqa: BLE001 — an optimisation only
        pass


def _start_search_workers(study: Study, config: Config, unit: int):
    """A started thread that starts the PSO-SVR search's worker processes
    (:func:`rlgsim.estimators.tuned.start_search_workers`) while the runs are simulated, or
    None: no ``pso_svr`` compensator, inside a worker process, or a recording among the train
    runs. The train windows, estimated from the scenarios' durations, go with it: with fewer
    than a parallel search needs the thread starts no worker (the search decides again)."""
    import multiprocessing
    import threading

    from rlgsim.lab.study import scenario_for
    pso = [c for c in config.compensators if c.kind == "pso_svr"]
    if not pso or multiprocessing.parent_process() is not None:
        return None
    try:
        rows = sum(max(0.0, scenario_for(study, s.ref, unit=unit, ctx=s.ctx).duration_s
                       - s.skip_s) / config.window_s for s in config.train)
    except Exception:           # noqa: BLE001 — a recording: no warm-up, nothing else changes
        return None
    thread = threading.Thread(target=_start_workers, args=(int(rows), pso[0].params.get("n_jobs")),
                              name="rlgsim-search-workers", daemon=True)
    thread.start()
    return thread


def run(study: Study, config: Config, workdir: pathlib.Path, *, unit: int = 0,
        progress: bool = True) -> StudyResult:
    """Simulate, correlate, select inputs, fit every compensator on the train runs, score on
    every test run."""
    t_start = time.perf_counter()
    started = _start_test_runs(study, config, workdir, unit)     # fork before any thread
    warm = _start_search_workers(study, config, unit)
    ex = load_experiment(study, config.train, config.test, config, workdir, unit=unit,
                         progress=progress,
                         done=_runs_done(started, study, config, workdir, unit, progress))
    t_data = time.perf_counter() - t_start      # the runs, not the search workers' start
    if warm is not None:
        warm.join()
    runs, Xtr, ytr, random_state = ex.runs, ex.X, ex.y, ex.random_state

    listings: dict[str, list[tuple[str, float, bool]]] = {}

    def prepare(spec: CompensatorSpec) -> CompensatorSpec:
        if spec.name not in config.selections:
            return spec
        spec, listings[spec.name] = select_inputs(spec, config.selections[spec.name], Xtr, ytr)
        return spec

    fitted = fit_all(config.compensators, Xtr, ytr, random_state, progress=progress,
                     prepare=prepare)

    rows: list[tuple[str, str, float]] = []
    per_test: dict[str, dict[str, dict[str, float]]] = {}
    predictions: dict[str, dict[str, np.ndarray]] = {}
    for spec in config.test:
        preds, table = score_run(runs[spec.key].series, fitted, ytr, config, config.cluster_s,
                                 config.ddof)
        per_test[spec.label] = table
        predictions[spec.label] = preds
        for name, sc in table.items():
            rows += [(name, f"{metric}@{spec.label}", float(v)) for metric, v in sc.items()]
    corr = correlation_matrix(Xtr, ytr, config.points) if config.points else None
    if corr is not None:
        for i, j in itertools.combinations(range(len(config.points)), 2):
            rows.append(("correlation", f"r[{config.points[i]}-{config.points[j]}]",
                         float(corr[i, j])))

    first_test = runs[config.test[0].key].series
    params = {k: v for k, v in first_test.coefficients.items() if worth_showing(k)}
    return StudyResult(rows=rows, params=params, details=Outcome(
        runs=runs, fitted=fitted, listings=listings, per_test=per_test, predictions=predictions,
        corr=corr, Xtr=Xtr, unit=unit, t_data=t_data, t_total=time.perf_counter() - t_start))


def fitted_models(config: Config, result: StudyResult) -> list:
    """The fitted compensators, for ``export_models`` (:mod:`rlgsim.lab.study_models`)."""
    from rlgsim.lab.study_models import from_fitted
    return from_fitted(result.details.fitted)


def navigation(study: Study, config: Config, result: StudyResult):
    """The first test run's navigation (:func:`.gradient_selection_report.navigation`):
    (dataset, introduction), or None for a recording. Each drawn unit of the IMU selects its
    gradients on its own train windows, as :func:`run` does."""
    return gradient_selection_report.navigation(study, config, result, _selector(config))


def _select(config: Config, spec: CompensatorSpec, X, y) -> CompensatorSpec:
    """:func:`select_inputs` of ``spec`` if it selects, else ``spec``."""
    sel = config.selections.get(spec.name)
    return spec if sel is None else select_inputs(spec, sel, X, y)[0]


def _selector(config: Config):
    """prepare(spec, X, y) -> spec: :func:`select_inputs` of the compensators that select
    (picklable: the report's navigation runs in a worker process)."""
    import functools
    return functools.partial(_select, config)


def report(study: Study, config: Config, result: StudyResult) -> Report:
    """The report of a run (:mod:`rlgsim.lab.studies.gradient_selection_report`)."""
    return gradient_selection_report.report(study, config, result, _selector(config))
