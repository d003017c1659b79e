"""Recipe ``paper000_system``: paper 000 end to end — the turntable calibration campaign in the
chamber, HHO-RVR and cubic least-squares models of the 15 temperature-related parameters
(Tables 1-2), and the system-level compensation of the pulses to a desired temperature
(eqs. 24-29, Table 3), scored against the paper and against the simulator's truth.

Paper: ``shared/papers/000_*.txt`` §3.2-3.4, §4.1-4.3.

Study tables (defaults are the paper's)::

    [campaign]
    scenario = "paper000_campaign"   # a scenario with a calibration19 turntable programme
    temperature = "sensor"           # x of every model: "sensor" = each sensor's own probe
                                     #   (gyro a: "g<a>.A", the cathode probe its laws follow;
                                     #   accelerometer a: "a<a>"), or one probe name for all
    workers = 2                      # processes (calibration campaigns, model fits);
                                     #   0 = min(2, CPUs)

    [models.hho_rvr]                 # paper 000 §3.2, §4.1
    hawks = 30
    iterations = 500
    folds = 5
    shuffle = true                   # "randomly divided into five parts"
    width_resolution_decades = 1e-3  # HHORVR's width grid (cache of repeated positions)
    seed = 0

    [models.lsm]
    degree = 3                       # the paper's cubic, eq. (30)

    [system]
    desired_temperature_c = 50.0     # §4.3
    compensate = true                # false: Table 2 only (no compensated re-calibration)

Train/test: the paper fits every model to all 175 calibration rows and reports RMSE, MAE and R²
of those fits (Table 2; the only split is HHO's 5-fold cross-validation inside the fit), and the
compensation of §4.3 re-calibrates the same run. The recipe does the same, and adds what the
paper could not: every model scored against the *true* parameter averaged over each window
(the calibration table's ``<p>_true`` column), i.e. the generalisation that in-sample scores
hide.

System-level compensation (eqs. 24-29): :mod:`rlgsim.lab.studies.paper000_compensation`; the
paper's figures beside ours: :mod:`rlgsim.lab.studies.paper000_config`; the report:
:mod:`rlgsim.lab.studies.paper000_report`.
"""

from __future__ import annotations

import contextlib
import os
import pathlib
import time
from typing import Any

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.lifeline import process_pool
from rlgsim.sim.config import Ctx
from rlgsim.lab.report import Report
from rlgsim.lab.study import StudyResult, scenario_for
from rlgsim.lab.studies import paper000_report
from rlgsim.lab.studies.paper000_compensation import compensate_dataset, timed_compensation
from rlgsim.lab.studies.paper000_config import (COMPENSATORS, LABEL, Config, Outcome, improvement,
                                                parse, probe_for)
from rlgsim.lab.studies.runs import device_coefficients, simulated_dataset


def check(study) -> Config:
    """Validate ``[campaign]``, ``[models]``, ``[system]``; UserInputError naming file/key/value."""
    return parse(study)


def _workers(cfg: Config) -> int:
    return cfg.workers or min(2, os.cpu_count() or 1)


def _fit_rvr(x: np.ndarray, y: np.ndarray, cfg: Config, seed: int):
    """HHO-RVR of y on x and its CPU seconds (picklable for workers)."""
    from rlgsim.estimators.tuned import HHORVR
    t0 = time.process_time()
    rvr = HHORVR(n_agents=cfg.hawks, max_iter=cfg.iterations, validation=cfg.folds,
                 shuffle=cfg.shuffle, width_resolution=cfg.width_resolution,
                 random_state=seed).fit(x[:, None], y)
    return rvr, time.process_time() - t0


def _fit_cost(param: str) -> int:
    """Rank of a parameter's HHO-RVR fit time, for submitting the longest fits first (so that
    the workers finish together): on the paper000 campaign an accelerometer parameter's fit
    took 4.7-7.5 s CPU, a gyro one's 1.7-2.8 s (the order changes no result)."""
    return 1 if param.startswith("accel") else 0


def _fit_lsm(x: np.ndarray, y: np.ndarray, cfg: Config):
    """The polynomial least-squares model of y on x."""
    from rlgsim.estimators.polynomial import PolynomialRegressor
    return PolynomialRegressor(degree=cfg.degree).fit(x[:, None], y)



def _metrics(y: np.ndarray, pred: np.ndarray) -> dict[str, float]:
    from rlgsim.estimators.metrics import mae, r2, rmse
    return {"rmse": rmse(y, pred), "mae": mae(y, pred), "r2": r2(y, pred)}




# ----------------------------------------------------------------------------------- run

def _campaign(path: pathlib.Path, cfg: Config, progress: bool, what: str):
    from rlgsim.estimators.calibration import CampaignError, CampaignSettings, run_campaign
    bar = None
    if progress:
        import sys

        from tqdm import tqdm
        from rlgsim.estimators.calibration import DatasetReader, find_windows
        r = DatasetReader(path)
        n = len(find_windows(r.segments()))
        r.close()
        bar = tqdm(total=n, unit="window", desc=f"paper000 {what}", leave=False,
                   file=sys.stderr, delay=1.0)
    try:
        return run_campaign(path, CampaignSettings(workers=_workers(cfg)),
                            progress=bar.update if bar is not None else None)
    except CampaignError as exc:
        raise UserInputError(f"campaign.scenario: {exc}") from None
    finally:
        if bar is not None:
            bar.close()




def run(study, cfg: Config, workdir: pathlib.Path, *, unit: int = 0,
        progress: bool = True) -> StudyResult:
    """Simulate, calibrate, model, compensate, re-calibrate and score (module docstring)."""
    from rlgsim.estimators.calibration import PAPER_PARAMETERS, PARAMETERS

    from rlgsim.estimators._malloc import retain_freed_memory
    retain_freed_memory()       # the campaigns' window arrays reused, not faulted in each time
    workdir = pathlib.Path(workdir)
    clock: dict[str, float] = {}
    t_all = time.perf_counter()
    scenario = scenario_for(study, cfg.scenario, unit=unit,
                            ctx=Ctx(study.source, "campaign.scenario"))
    t = time.perf_counter()
    data_path, reused = simulated_dataset(
        scenario, workdir / "data" / f"{scenario.name}_u{scenario.unit}.h5", progress=progress)
    clock["simulation"] = time.perf_counter() - t

    t = time.perf_counter()
    raw = _campaign(data_path, cfg, progress, "calibration")
    clock["calibration campaign"] = time.perf_counter() - t
    for p in PAPER_PARAMETERS:
        probe = probe_for(p, cfg.temperature)
        if probe not in raw.probes:
            raise UserInputError(
                f"{study.source}: campaign.temperature: no probe {probe!r} in the dataset "
                f"(probes: {', '.join(raw.probes)})")
    raw.write_csv(workdir / "calibration_raw.csv")
    ok = np.array([r["status"] == "ok" for r in raw.rows])
    if ok.sum() < max(cfg.folds, cfg.degree + 1) + 1:
        raise UserInputError(
            f"{study.source}: campaign.scenario: {int(ok.sum())} calibration window(s) "
            f"succeeded; the models need at least {max(cfg.folds, cfg.degree + 1) + 1}")

    # ---- models (Table 1-2) and the compensated datasets (eqs. 24-29). The cubic LSM fits
    # take milliseconds, so the LSM-compensated dataset is written by one worker while the
    # HHO-RVR fits run on the others (in parallel over parameters), and the HHO-RVR one as soon
    # as they are done — while the LSM-compensated data is re-calibrated. Every step's result
    # is the same as in sequence; only the wall times overlap.
    t = time.perf_counter()
    xs = {p: raw.column(f"temp_{probe_for(p, cfg.temperature)}_c")[ok] for p in PAPER_PARAMETERS}
    ys = {p: raw.column(p)[ok] for p in PAPER_PARAMETERS}
    seeds = {p: cfg.seed + 1000 * unit + i for i, p in enumerate(PAPER_PARAMETERS)}
    lsms = {p: _fit_lsm(xs[p], ys[p], cfg) for p in PAPER_PARAMETERS}
    probes = {p: probe_for(p, cfg.temperature) for p in PAPER_PARAMETERS}
    comp_paths = {c: workdir / "data" / f"{data_path.stem}_compensated_{c}.h5"
                  for c in COMPENSATORS}
    workers = _workers(cfg)
    comp_futs: dict[str, Any] = {}
    with (process_pool(max_workers=workers) if workers > 1     # workers die with us
          else contextlib.nullcontext()) as pool:
        if pool is not None:
            if cfg.compensate:
                comp_futs["lsm"] = pool.submit(timed_compensation, data_path,
                                               comp_paths["lsm"], lsms, probes, cfg.desired_c)
            futs = {p: pool.submit(_fit_rvr, xs[p], ys[p], cfg, seeds[p])
                    for p in sorted(PAPER_PARAMETERS, key=_fit_cost, reverse=True)}
            rvrs = {p: futs[p].result() for p in PAPER_PARAMETERS}
        else:
            rvrs = {p: _fit_rvr(xs[p], ys[p], cfg, seeds[p]) for p in PAPER_PARAMETERS}
        fitted: dict[str, tuple] = {p: (rvrs[p][0], lsms[p], rvrs[p][1])
                                    for p in PAPER_PARAMETERS}
        clock["models (15 × HHO-RVR + LSM)"] = time.perf_counter() - t
        if pool is not None and cfg.compensate:
            comp_futs["hho_rvr"] = pool.submit(
                timed_compensation, data_path, comp_paths["hho_rvr"],
                {p: fitted[p][0] for p in PAPER_PARAMETERS}, probes, cfg.desired_c)
        result = _scores_and_compensation(cfg, workdir, progress, data_path, raw, ok, xs, ys,
                                          fitted, comp_futs, comp_paths, probes, clock, pool)
    clock["total"] = time.perf_counter() - t_all
    rows, pred, fit_scores, truth_scores, avg, avg_truth, comp_tables, resid, resvar, desired, \
        nav = result
    units = {q.name: q.unit for q in PARAMETERS}
    params = _device_params(data_path)
    return StudyResult(rows=rows, params=params, details=Outcome(
        scenario=scenario, data_path=data_path, reused=reused, raw=raw, xs=xs, ys=ys, pred=pred,
        fitted=fitted, fit_scores=fit_scores, truth_scores=truth_scores, avg=avg,
        avg_truth=avg_truth, resvar=resvar, resid=resid, desired=desired,
        comp_tables=comp_tables, units=units, clock=clock, ok=ok, navigation=nav))


def _scores_and_compensation(cfg: Config, workdir: pathlib.Path, progress: bool,
                             data_path: pathlib.Path, raw, ok: np.ndarray, xs, ys, fitted,
                             comp_futs, comp_paths, probes, clock: dict[str, float], pool=None):
    """Table 2 scores of the fitted models, then (``cfg.compensate``) the compensated
    datasets — written by the futures in ``comp_futs`` when given, else here — re-calibrated
    (Table 3). With a worker ``pool``, the report's navigation runs in it as soon as both
    compensated datasets exist, beside the last re-calibration (else the report runs it)."""
    from rlgsim.estimators.calibration import PAPER_PARAMETERS
    from rlgsim.estimators.metrics import residual_variance
    pred: dict[str, dict[str, np.ndarray]] = {}
    fit_scores: dict[str, dict[str, dict[str, float]]] = {}
    truth_scores: dict[str, dict[str, dict[str, float]]] = {}
    records = []
    for p in PAPER_PARAMETERS:
        rvr, lsm, _ = fitted[p]
        X = xs[p][:, None]
        pred[p] = {"hho_rvr": rvr.predict(X), "lsm": lsm.predict(X)}
        truth = raw.column(f"{p}_true")[ok]
        fit_scores[p] = {c: _metrics(ys[p], pred[p][c]) for c in COMPENSATORS}
        if np.all(np.isfinite(truth)):
            truth_scores[p] = {c: _metrics(truth, pred[p][c]) for c in COMPENSATORS}
        for i, w in enumerate(raw.column("window")[ok]):
            records.append({"parameter": p, "window": int(w), "temperature_c": xs[p][i],
                            "estimate": ys[p][i], "truth": truth[i],
                            "hho_rvr": pred[p]["hho_rvr"][i], "lsm": pred[p]["lsm"][i]})
    _write_predictions(workdir / "model_predictions.csv", records)

    rows: list[tuple[str, str, float]] = []
    for p in PAPER_PARAMETERS:
        for c in COMPENSATORS:
            for m, v in fit_scores[p][c].items():
                rows.append((c, f"{p}.{m}", v))
            if p in truth_scores:
                for m, v in truth_scores[p][c].items():
                    rows.append((c, f"{p}.truth_{m}", v))
    avg = {m: float(np.mean([improvement(m, fit_scores[p]["lsm"][m], fit_scores[p]["hho_rvr"][m])
                             for p in PAPER_PARAMETERS])) for m in ("rmse", "mae", "r2")}
    avg_truth = ({m: float(np.mean([improvement(m, truth_scores[p]["lsm"][m],
                                                 truth_scores[p]["hho_rvr"][m])
                                    for p in PAPER_PARAMETERS])) for m in ("rmse", "mae", "r2")}
                 if len(truth_scores) == len(PAPER_PARAMETERS) else {})
    for m, v in avg.items():
        rows.append(("hho_rvr", f"avg_improvement_{m}_pct", v))
    for m, v in avg_truth.items():
        rows.append(("hho_rvr", f"avg_improvement_truth_{m}_pct", v))

    # ---- system-level compensation (eqs. 24-29) and re-calibration (Table 3)
    comp_tables = {}
    resid: dict[str, dict[str, np.ndarray]] = {p: {} for p in PAPER_PARAMETERS}
    resvar: dict[str, dict[str, float]] = {p: {} for p in PAPER_PARAMETERS}
    desired: dict[str, dict[str, float]] = {p: {} for p in PAPER_PARAMETERS}
    nav_fut = None
    if cfg.compensate:
        # the LSM-compensated data first: it is ready (or nearly) when the fits end
        for c in sorted(COMPENSATORS, key=lambda c: c != "lsm"):
            models = {p: fitted[p][0 if c == "hho_rvr" else 1] for p in PAPER_PARAMETERS}
            t = time.perf_counter()
            if c in comp_futs:
                clock[f"compensate pulses ({LABEL[c]})"] = comp_futs[c].result()
            else:
                compensate_dataset(data_path, comp_paths[c], models, probes, cfg.desired_c)
                clock[f"compensate pulses ({LABEL[c]})"] = time.perf_counter() - t
            for p in PAPER_PARAMETERS:
                desired[p][c] = float(models[p].predict(np.array([[cfg.desired_c]]))[0])
            if pool is not None and len(desired[PAPER_PARAMETERS[0]]) == len(COMPENSATORS):
                nav_fut = pool.submit(paper000_report.navigation_of, data_path, desired,
                                      cfg.desired_c)
            t = time.perf_counter()
            tab = _campaign(comp_paths[c], cfg, progress, f"re-calibration {c}")
            clock[f"re-calibration ({LABEL[c]})"] = time.perf_counter() - t
            tab.write_csv(workdir / f"calibration_compensated_{c}.csv")
            comp_tables[c] = tab
            cok = np.array([r["status"] == "ok" for r in tab.rows])
            for p in PAPER_PARAMETERS:
                resid[p][c] = tab.column(p)[cok] - desired[p][c]
                resvar[p][c] = residual_variance(resid[p][c], np.zeros(int(cok.sum())))
        comp_tables = {c: comp_tables[c] for c in COMPENSATORS}
        resid = {p: {c: resid[p][c] for c in COMPENSATORS} for p in PAPER_PARAMETERS}
        resvar = {p: {c: resvar[p][c] for c in COMPENSATORS} for p in PAPER_PARAMETERS}
        desired = {p: {c: desired[p][c] for c in COMPENSATORS} for p in PAPER_PARAMETERS}
        for p in PAPER_PARAMETERS:
            resvar[p]["raw"] = residual_variance(ys[p], np.zeros(ys[p].size))
            for c in ("raw", *COMPENSATORS):
                rows.append((c, f"{p}.residual_variance", resvar[p][c]))
        avg["residual_variance"] = float(np.mean([
            improvement("rmse", resvar[p]["lsm"], resvar[p]["hho_rvr"])
            for p in PAPER_PARAMETERS]))
        rows.append(("hho_rvr", "avg_improvement_residual_variance_pct",
                     avg["residual_variance"]))
    return (rows, pred, fit_scores, truth_scores, avg, avg_truth, comp_tables, resid, resvar,
            desired, nav_fut.result() if nav_fut is not None else None)


def _write_predictions(path: pathlib.Path, records: list[dict]) -> None:
    from rlgsim.lab.report import write_atomic
    cols = ["parameter", "window", "temperature_c", "estimate", "truth", "hho_rvr", "lsm"]
    lines = [",".join(cols)] + [",".join(str(r[c]) if isinstance(r[c], (str, int))
                                         else repr(float(r[c])) for c in cols) for r in records]
    write_atomic(path, "\n".join(lines) + "\n")


def _device_params(path: pathlib.Path) -> dict[str, float]:
    """The drawn temperature coefficients worth showing beside a unit's scores (linear term and
    knee of every bias and scale factor)."""
    out: dict[str, float] = {}
    for n, v in device_coefficients(path).items():
        head = n.split("[")[0]
        if (head.startswith(("gyro.bias.", "gyro.scale_factor.", "accel.bias.",
                             "accel.scale_factor"))
                and head.rsplit(".", 1)[-1] in ("c1", "knee", "step")):
            out[n] = float(v)
    return out


def fitted_models(cfg: Config, result: StudyResult) -> list:
    """HHO-RVR and the cubic LSM of every parameter against its probe temperature T [°C],
    for ``export_models`` (:mod:`rlgsim.lab.study_models`)."""
    from rlgsim.lab.study_models import FittedModel
    out: Outcome = result.details
    return [FittedModel(f"{LABEL[c]} {p}", "hho_rvr" if c == "hho_rvr" else "polynomial",
                        out.fitted[p][i], out.xs[p][:, None], ("T",), target=p,
                        target_unit=out.units[p])
            for p in out.fitted for i, c in enumerate(COMPENSATORS)]


def navigation(study, cfg: Config, result: StudyResult):
    """The campaign run's navigation (:func:`.paper000_report.navigation`): (dataset,
    introduction), or None without the compensation."""
    return paper000_report.navigation(study, cfg, result)


def report(study, cfg: Config, result: StudyResult) -> Report:
    """The report of a run (:mod:`rlgsim.lab.studies.paper000_report`)."""
    return paper000_report.report(study, cfg, result)
