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
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rlgsim.sim.config import check_known_keys, get_float, get_section, get_str, get_table
from rlgsim.lab.report import Report, Table, slug
from rlgsim.lab.study import Study, StudyResult
from rlgsim.lab.studies.compensators import (EQUATION_KINDS, ORACLE, RAW, CompensatorSpec,
                                              parse_compensators)
from rlgsim.lab.studies.fitting import Fitted, fit_all
from rlgsim.lab.studies.report_text import (anomaly_events, before_check, definitions,
                                             device_coefficients_section, fmt,
                                             truth_score_tables, weight_spread)
from rlgsim.lab.studies.recording_runs import recorded_labels, recordings_paragraph, run_origin
from rlgsim.lab.studies.runs import LoadedRun, RunSeries, load_experiment, worth_showing
from rlgsim.lab.studies.scoring import has_truth, score_run, series_stability
from rlgsim.lab.studies.study_tables import FeatureSpec, RunSpec, parse_experiment, parse_metrics

TOP_KEYS = ("study", "data", "features", "compensator", "metrics", "published")
DATA_KEYS = ("train", "test", "window_s", "gyro")
PUBLISHED_COMP_KEYS = ("stability_deg_per_h", "improvement_pct", "c", "sigma2", "equation")
METRIC_KEYS = ("cluster_s", "ddof", "baseline")
PUBLISHED_KEYS = ("stability_before_deg_per_h", "correlation")


@dataclass(frozen=True)
class Config(FeatureSpec):
    """A validated bias_compensation study: its runs, features, compensators and metrics."""

    train: tuple[RunSpec, ...] = ()
    test: tuple[RunSpec, ...] = ()
    compensators: tuple[CompensatorSpec, ...] = ()
    cluster_s: float = 100.0
    ddof: int = 1
    baseline: str = RAW
    published: dict = field(default_factory=dict)


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


# ------------------------------------------------------------------------------ the run
@dataclass
class Outcome:
    """What :func:`run` hands to :func:`report` (in ``StudyResult.details``)."""

    runs: dict[tuple[str, float], LoadedRun]
    train: list[RunSeries]
    fitted: list[Fitted]
    per_test: dict[str, dict[str, dict[str, float]]]   # test label → compensator → scores
    predictions: dict[str, dict[str, np.ndarray]]      # test label → compensator → ŷ [°/h]
    Xtr: Any                    # the train windows' inputs (Columns)
    ytr: np.ndarray             # their measured bias [°/h]
    unit: int
    t_data: float               # wall time of simulating/reading the runs [s]
    t_total: float              # wall time of the run [s]


def run(study: Study, config: Config, workdir: pathlib.Path, *, unit: int = 0,
        progress: bool = True) -> StudyResult:
    """Simulate, fit every compensator on the train runs, score on the test runs."""
    t_start = time.perf_counter()
    ex = load_experiment(study, config.train, config.test, config, workdir, unit=unit,
                         progress=progress)
    runs, train, Xtr, ytr, random_state = ex.runs, ex.train, ex.X, ex.y, ex.random_state
    t_data = ex.t_data

    fitted = fit_all(config.compensators, Xtr, ytr, random_state, progress=progress)

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


# ------------------------------------------------------------------------------ the report
def report(study: Study, config: Config, result: StudyResult) -> Report:
    """The report of a run (the paper's tables beside ours, truth-based scores, rankings,
    figures)."""
    from rlgsim.sim.writer.dataset import software_version

    out: Outcome = result.details
    runs, fitted, per_test, predictions = out.runs, out.fitted, out.per_test, out.predictions
    Xtr, ytr, unit, t_data, t_total = out.Xtr, out.ytr, out.unit, out.t_data, out.t_total

    rep = Report(study.title)
    if study.description:
        rep.paragraph(study.description)
    test_label = config.test[0].label
    rs_test = runs[config.test[0].key].series
    sc = per_test[test_label]

    rep.heading("Runs, seeds and software", 2)
    rep.bullets([f"rlgsim {software_version()}; recipe bias_compensation; unit {unit}"]
                + [f"{'train' if s in config.train else 'test'} run {s.label}: "
                   f"{run_origin(runs[s.key])}, {runs[s.key].series.y.size} windows of "
                   f"{config.window_s:g} s, raw bias stability "
                   f"{_raw_stability(runs[s.key].series, config):.5f} °/h"
                   for s in dict.fromkeys(config.train + config.test)]
                + [f"Earth-rate projection on the gyro axis: {rs_test.earth_deg_per_h:.4f} °/h "
                   f"(subtracted from the output: 'bias = output − Earth-rate projection')",
                   f"bias stability: std (ddof={config.ddof}) of {config.cluster_s:g} s means; "
                   f"improvement relative to "
                   f"{'the raw bias' if config.baseline == RAW else config.baseline}",
                   f"wall time: data {t_data:.1f} s, total {t_total:.1f} s"])
    from rlgsim.lab.studies.run_days import run_to_run_section
    run_to_run_section(rep, runs, config.train, config.test)

    rep.heading("Definitions", 2)
    rep.bullets(definitions())
    truth = has_truth(rs_test)
    recorded = recorded_labels(runs, config.train + config.test)
    if recorded:
        rep.paragraph(recordings_paragraph(recorded, truth))

    # -- correlation (paper 001 Table 1)
    rep.heading("Correlation of the bias with the inputs (paper 001 Table 1)", 2)
    corr_pub = config.published.get("correlation", {})
    recs = []
    for name in Xtr.names:
        recs.append({"input": name,
                     "paper": corr_pub.get(name),
                     "ours (train, measured y)": fmt(np.corrcoef(Xtr[name], ytr)[0, 1]),
                     "ours (test, measured y)": fmt(np.corrcoef(rs_test.X[name], rs_test.y)[0, 1]),
                     "ours (test, true b)": fmt(np.corrcoef(rs_test.X[name],
                                                             rs_test.true_bias)[0, 1])})
    rep.table(Table.from_records("Correlation coefficients", recs, csv_name="correlation.csv"))

    # -- the paper's tables beside ours
    before_pub = config.published.get("stability_before")
    tables: dict[str, list[Fitted]] = {}
    for f in fitted:
        tables.setdefault(f.spec.table or "Other compensators", []).append(f)
    rep.heading(f"Paper-style scores on test run {test_label} (ours beside the paper)", 2)
    if before_pub:
        # raw: y − constant, so its stability_after is the raw bias stability
        rep.paragraph(before_check(sc[RAW]["stability_after"], before_pub))
    for tname, group in tables.items():
        recs = []
        for f in group:
            s = sc[f.spec.name]
            pub = f.spec.published
            rec = {"compensator": f.spec.name, "inputs": ", ".join(f.spec.inputs)}
            if any(k in f.hyper for k in ("c", "sigma2")) or "c" in pub:
                rec.update({"c (ours)": fmt(f.hyper.get("c")), "c (paper)": pub.get("c"),
                            "σ² (ours)": fmt(f.hyper.get("sigma2")),
                            "σ² (paper)": pub.get("sigma2")})
            rec.update({"before (ours) °/h": fmt(s["stability_before"]),
                        "before (paper) °/h": before_pub if pub else None,
                        "after (ours) °/h": fmt(s["stability_after"]),
                        "after (paper) °/h": pub.get("stability_deg_per_h"),
                        "improvement (ours) %": fmt(s["improvement_pct"]),
                        "improvement (paper) %": pub.get("improvement_pct")})
            recs.append(rec)
        cols: list[str] = []
        for rec in recs:
            cols += [k for k in rec if k not in cols]
        recs = [{k: rec.get(k) for k in cols} for rec in recs]
        note = "paper: the published value; — where the paper gives none."
        if "c (ours)" in cols:          # kernel models only: their hyper-parameters
            note += (" c is the LS-SVM regularisation (gamma), σ² the squared kernel width in "
                     "standardised inputs (ours; the paper does not say whether it "
                     "standardised). The paper's F(x) column is not reproduced: the paper "
                     "does not define it.")
        rep.table(Table.from_records(tname, recs, csv_name=f"paper_{slug(tname)}.csv",
                                     note=note))

    # -- truth-based scores
    if truth:
        truth_score_tables(rep, per_test)
    else:
        rep.heading("Truth-based scores", 2)
        rep.paragraph("Absent: the test run is a recording, which has no ground truth.")
    hyp = [{"compensator": f.spec.name, "kind": f.spec.kind, "fit time s": fmt(f.fit_s),
            **{k: fmt(v) for k, v in f.hyper.items()}} for f in fitted]
    cols = []
    for rec in hyp:
        cols += [k for k in rec if k not in cols]
    irls = any(f.spec.kind == "ir_lssvm" for f in fitted)
    rep.table(Table.from_records("Fitted hyper-parameters", [{k: r.get(k) for k in cols}
                                                             for r in hyp],
                                 csv_name="hyperparameters.csv",
                                 note="IR-LSSVM: (c, σ²) tuned once per input set by "
                                      "cross-validation of the unweighted LS-SVM and shared by "
                                      "the four weights (its time is in the first one's fit "
                                      "time); weight_param: the Huber β / Myriad δ chosen by "
                                      "robust CV." if irls else ""))

    eqs = []
    for f in fitted:
        if f.spec.kind in EQUATION_KINDS:
            eqs.append(f"{f.spec.name} (ours):  {f.model.equation('B')}")
            if "equation" in f.spec.published:
                eqs.append(f"{f.spec.name} (paper): {f.spec.published['equation']}")
    if eqs:
        rep.heading("Regression equations (B in °/h; T in °C, dT/dt in K/s, U in V)", 2)
        rep.verbatim("\n".join(eqs), language="text")

    # -- rankings
    from rlgsim.lab.studies.input_range import range_section
    range_section(rep, [(fitted, {s.label: runs[s.key].series for s in config.test})])
    rep.heading("Rankings: the paper's claims against ours", 2)
    for para in _rankings(config, fitted, sc, int(ytr.size), out.train):
        rep.paragraph(para)

    # -- figures, per test run
    multi = len(config.test) > 1
    for spec in config.test:
        _run_figures(rep, config, fitted, runs[spec.key].series, predictions[spec.label],
                     per_test[spec.label], ytr, spec.label, multi)

    nav = navigation(study, config, result)
    if nav is not None:
        from rlgsim.lab.studies.navigation_section import add_section
        add_section(rep, *nav)

    if rs_test.coefficients:
        device_coefficients_section(rep, rs_test.coefficients, rs_test.path)
    return rep


def navigation(study: Study, config: Config, result: StudyResult):
    """The first test run's navigation (docs/navigation.md, "In the studies"): (dataset,
    introduction), or None for a recording."""
    out: Outcome = result.details
    rs = out.runs[config.test[0].key].series
    if not has_truth(rs) or rs.path.suffix != ".h5":
        return None
    from rlgsim.lab.studies.navigation_section import single_gyro_navigation
    preds = out.predictions[config.test[0].label]
    return single_gyro_navigation(rs.path, config.gyro, rs.time_s,
                                  {f.spec.name: preds[f.spec.name] for f in out.fitted
                                   if f.spec.name in preds}, config.window_s)


def _run_figures(rep: Report, config: Config, fitted: list[Fitted], rs: RunSeries,
                 preds: dict[str, np.ndarray], sc: dict, ytr: np.ndarray, label: str,
                 multi: bool) -> None:
    """The figures of one test run: bias over time (measured, true, predicted; compensated),
    bias against temperature with the truth, Allan deviation before and after."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rlgsim.estimators import metrics as M

    tag = f"_{slug(label)}" if multi else ""
    where = f"Test run {label}. " if multi else ""
    best = _best_per_kind(fitted, sc)
    th = rs.time_s / 3600.0
    top = min(fitted, key=lambda f: sc[f.spec.name]["stability_after"]).spec.name if fitted \
        else None
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    ax.plot(th, rs.y, color="0.6", lw=0.8, label="measured bias y")
    ax.plot(th, rs.true_bias, color="k", lw=1.0, ls="--", label="true bias b")
    if top is not None:
        ax.plot(th, preds[top], color="C3", lw=1.0, label=f"prediction ŷ: {top}")
    ax.set_ylabel("bias [°/h]")
    ax.legend(fontsize=7)
    ax.set_title(f"Test run {label} ({config.window_s:g} s means)")
    ax2.plot(th, rs.y - np.mean(ytr), color="0.6", lw=0.8, label="raw (y − train mean)")
    for name in best:
        ax2.plot(th, rs.y - preds[name], lw=0.9, label=f"y − ŷ: {name}")
    ax2.set_xlabel("time [h]")
    ax2.set_ylabel("compensated [°/h]")
    ax2.legend(fontsize=7, ncol=2)
    rep.figure(fig, f"bias_over_time{tag}",
               f"{where}Top: measured and true bias with the prediction of the model with the "
               "best bias stability. Bottom: the raw and compensated series of the best model "
               "of each kind.")

    if "T" in rs.X:
        fig, ax = plt.subplots(figsize=(7, 5))
        T = rs.X["T"]
        ax.scatter(T, rs.y, s=4, color="0.6", label="measured bias y")
        ax.scatter(T, rs.true_bias, s=4, color="k", label="true bias b")
        ax.scatter(T, rs.true_bias - rs.true_random, s=3, color="C3",
                   label="true temperature law b − r")
        if top is not None:
            ax.scatter(T, preds[top], s=3, color="C0", label=f"prediction: {top}")
        ax.set_xlabel(f"T (probe {config.temperature}) [°C]")
        ax.set_ylabel("bias [°/h]")
        ax.legend(fontsize=8)
        rep.figure(fig, f"bias_vs_temperature{tag}", f"{where}Bias against the probe "
                                                     "temperature, with the truth.")

    from rlgsim.lab.studies.sample_rate import sample_rate_series
    fig, ax = plt.subplots(figsize=(7, 5))
    fast = sample_rate_series(rs, config.gyro, config.window_s)
    rate = 1.0 / config.window_s if fast is None else fast[0]
    resolution = "window" if fast is None else "sample"

    def series(pred):           # y − ŷ at the window or the sample rate (ŷ held per window)
        if fast is None:
            return rs.y - pred
        return fast[1] - np.repeat(pred, fast[2])

    for name, pred, style in ([("raw", np.zeros(rs.y.size), dict(color="0.5"))]
                              + [(n, preds[n], {}) for n in best]
                              + ([(ORACLE, preds[ORACLE], dict(color="k", ls="--"))]
                                 if has_truth(rs) else [])):
        x = series(pred)
        if x.size < 8:
            continue
        ad = M.allan_deviation(x, rate, "octave")
        ax.loglog(ad.tau_s, ad.adev, marker="o", ms=3, label=name, **style)
    ax.set_xlabel("τ [s]")
    ax.set_ylabel("Allan deviation [°/h]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    rep.figure(fig, f"allan_deviation{tag}",
               f"{where}Overlapping Allan deviation before and after compensation "
               f"(allantools), from the {resolution} rate"
               + (f" ({rate:g} Hz: pulse quantisation, slope −1, and angle random walk, "
                  f"slope −½, at short τ; ŷ held over each {config.window_s:g} s window)"
                  if fast is not None else
                  f" ({config.window_s:g} s means)") + ".")


def _raw_stability(rs: RunSeries, config: Config) -> float:
    return series_stability(rs.y, config.window_s, config.cluster_s, config.ddof)


def _best_per_kind(fitted: list[Fitted], sc: dict) -> dict[str, str]:
    best: dict[str, str] = {}
    for f in fitted:
        cur = best.get(f.spec.kind)
        if cur is None or sc[f.spec.name]["stability_after"] < sc[cur]["stability_after"]:
            best[f.spec.kind] = f.spec.name
    return {name: kind for kind, name in best.items()}


def _rankings(config: Config, fitted: list[Fitted], sc: dict, n_train: int,
              train: list[RunSeries]) -> list[str]:
    """The paper's ranking (IR-LSSVM ≥ LSSVM > stepwise > LS; UHFO the strongest single
    input) checked against our numbers, claim by claim, by the paper's score and by the truth;
    with the train runs' labelled anomalies, which mechanism of the device decides each."""
    out = []
    events = anomaly_events([rs.path for rs in train])
    spikes = [abs(e[2]) for e in events if e[1] == "pulse_spike"]
    hops = [e for e in events if e[1].startswith("mode_hop")]
    floor = sc[ORACLE]["stability_after"]
    raw = sc[RAW]["stability_after"]
    truth = bool(np.isfinite(floor))
    if not truth:                     # a recorded test run: judged by the paper's score only
        floor = 0.0

    def best(kind: str, n_inputs: int | None = None) -> Fitted | None:
        cands = [f for f in fitted if f.spec.kind == kind
                 and (n_inputs is None or len(f.spec.inputs) == n_inputs)]
        return min(cands, key=lambda f: sc[f.spec.name]["stability_after"]) if cands else None

    def s(f: Fitted, key: str = "stability_after") -> float:
        return sc[f.spec.name][key]

    out.append(f"Reference points: raw bias stability {raw:.5f} °/h; the oracle (true "
               f"temperature law removed) reaches {floor:.5f} °/h — the flicker, random walk "
               f"and white noise that no input-driven model can remove. Differences between "
               f"compensators that are small against (raw − floor) = {raw - floor:.5f} °/h are "
               f"within what one realisation of that noise decides." if truth else
               f"Reference point: raw bias stability {raw:.5f} °/h. The test run is a "
               f"recording: no oracle floor, no truth; margins below are in % of the raw "
               f"bias stability.")
    ladder = [("ir_lssvm", "IR-LSSVM"), ("lssvm", "LSSVM"), ("stepwise", "stepwise"),
              ("polynomial", "LS")]
    have = [(k, lab, best(k)) for k, lab in ladder if best(k) is not None]
    for (k1, l1, f1), (k2, l2, f2) in zip(have, have[1:]):
        a, b = s(f1), s(f2)
        ta, tb = s(f1, "resid_std_true"), s(f2, "resid_std_true")
        rel = "≥ (not worse than)" if k1 == "ir_lssvm" and k2 == "lssvm" else ">"
        margin = abs(a - b) / max(raw - floor, 1e-12) * 100
        tie = margin < 0.5
        holds = a <= b if rel.startswith("≥") else a < b
        truth_holds = ta <= tb
        text = (f"Paper: {l1} {rel} {l2}. Ours (best of each): {l1} {f1.spec.name!r} "
                f"{a:.5f} °/h vs {l2} {f2.spec.name!r} {b:.5f} °/h — "
                f"{'a tie' if tie else 'holds' if holds else 'does NOT hold'} by bias "
                f"stability (margin "
                f"{margin:.1f} % of raw − floor)"
                + (f"; by the truth (std of ŷ − b) {ta:.5f} vs {tb:.5f} °/h, "
                   f"{'holds' if truth_holds else 'does not hold'}." if truth else "."))
        if not tie and margin < 5 and not (k1 == "ir_lssvm" and k2 == "lssvm"):
            text += (" The margin is small enough for another realisation of the noise to "
                     "reverse it; a Monte Carlo over units tells how often it holds.")
        if k1 == "ir_lssvm" and k2 == "lssvm" and spikes:
            text += (f" Why: the train run{'s hold' if len(train) > 1 else ' holds'} "
                     f"{len(spikes)} read-out spikes (±{min(spikes, default=0):g} … "
                     f"{max(spikes, default=0):g} pulses in one sample: up to "
                     f"{max(spikes, default=0) * _deg_per_h_per_pulse(train[0], config):.4f} °/h "
                     f"in its {config.window_s:g} s window) — outliers the robust weights "
                     "down-weight, which the unweighted fit follows; re-weighting moves the "
                     f"all-input fit by {abs(a - b):.5f} °/h "
                     f"({abs(a - b) / max(raw - floor, 1e-12) * 100:.1f} % of raw − floor).")
        elif k1 == "ir_lssvm" and k2 == "lssvm":
            text += (" Why: the simulated bias noise is Gaussian (white + flicker + random "
                     "walk), without the gross outliers robust weights are built to reject, so "
                     "re-weighting can only trade ordinary tail samples; IR-LSSVM and LSSVM "
                     f"should differ by noise only (here by {abs(a - b):.5f} °/h, "
                     f"{abs(a - b) / max(raw - floor, 1e-12) * 100:.1f} % of raw − floor).")
        elif tie:
            text += " A tie is not the paper's strict ranking, nor its reversal."
        elif not holds and truth:
            la, lb = s(f1, "law_resid_std"), s(f2, "law_resid_std")
            text += (f" Why: by the truth, {l2}'s learnt law is "
                     f"{'closer to' if lb < la else 'as far from'} the true temperature law "
                     f"(law_resid_std {lb:.5f} vs {la:.5f} °/h). ")
            if k1 in ("lssvm", "ir_lssvm"):
                text += ("The simulated bias law (docs/sensors.md) is linear in dT/dt and UHFO "
                         "plus a linear term and a tanh knee in T (and steps at mode hops), "
                         "most of "
                         "which a second-order regression represents directly, while the kernel "
                         f"model has to learn its shape from {n_train} "
                         "auto-correlated windows that also carry the train run's "
                         "slow noise; the paper's gyro may hold non-linearities the simulator "
                         "lacks.")
            else:
                text += ("The extra terms the selection keeps fit the train run's noise as well "
                         "as its law.")
        out.append(text)
    singles = [(f.spec.inputs[0], f) for f in fitted
               if f.spec.kind == "polynomial" and len(f.spec.inputs) == 1]
    if len(singles) >= 2:
        order = sorted(singles, key=lambda t: s(t[1]))
        strongest = order[0][0]
        listing = ", ".join(f"{name} {s(f):.5f}" for name, f in order)
        truth_order = sorted(singles, key=lambda t: s(t[1], "resid_std_true"))
        text = (f"Paper: UHFO is the strongest single input (LS: U 40.5 % > T 35.5 % > dT/dt "
                f"8.0 %). Ours, LS cubic bias stability after (°/h): {listing} — "
                f"{'holds' if strongest == 'U' else 'does NOT hold'} (strongest: "
                f"{strongest}" + (f"; by the truth: {truth_order[0][0]})." if truth else ")."))
        if strongest != "U":
            text += (" Why: in the simulated TRPLG the UHFO follows the discharge temperature "
                     "and its rate, plus a slow wander no thermometer sees; the bias law has a "
                     "UHFO term, but if the wander is small against the temperature-driven "
                     "part, the voltage carries little information beyond T.")
        out.append(text)
    irs = [(f.spec.inputs[0], f) for f in fitted
           if f.spec.kind == "ir_lssvm" and len(f.spec.inputs) == 1]
    if len({x for x, _ in irs}) >= 2:
        best_in: dict[str, float] = {}
        for name, f in irs:
            best_in[name] = min(best_in.get(name, np.inf), s(f))
        strongest = min(best_in, key=best_in.get)
        out.append("IR-LSSVM single inputs (best weight, °/h): "
                   + ", ".join(f"{k} {v:.5f}" for k, v in sorted(best_in.items(),
                                                                   key=lambda t: t[1]))
                   + f" — UHFO strongest {'holds' if strongest == 'U' else 'does NOT hold'}.")
    groups: dict[str, list[str]] = {}
    for f in fitted:
        if f.spec.kind == "ir_lssvm":
            groups.setdefault(", ".join(f.spec.inputs), []).append(f.spec.name)
    if any(len(v) > 1 for v in groups.values()):
        spread, where = weight_spread({f.spec.name: s(f) for f in fitted}, groups)
        out.append(f"IR-LSSVM weight functions: their bias stabilities differ by up to "
                   f"{spread:.1f} % within one input set ({where}; (max − min)/min); paper: up "
                   f"to 26 % (Table 4 dT/dt: Huber 0.01712 vs Hampel 0.01357 °/h).")
    multi = [f for f in fitted if f.spec.kind in ("ir_lssvm", "lssvm") and len(f.spec.inputs) > 1]
    with_u = [f for f in multi if "U" in f.spec.inputs]
    without_u = [f for f in multi if "U" not in f.spec.inputs]
    if with_u and without_u:
        fu = min(with_u, key=s)
        fn = min(without_u, key=s)
        holds = s(fu) < s(fn)
        out.append(f"Paper: UHFO improves the composite LS-SVM models (all inputs 61.19 % vs "
                   f"T, dT/dt 59.35 %). Ours: best with U {fu.spec.name!r} {s(fu):.5f} °/h vs "
                   f"best without U {fn.spec.name!r} {s(fn):.5f} °/h — "
                   f"{'holds' if holds else 'does NOT hold'}"
                   + (f"; by the truth {s(fu, 'resid_std_true'):.5f} vs "
                      f"{s(fn, 'resid_std_true'):.5f} °/h." if truth else "."))
    off = []
    ratios = [sc[f.spec.name]["stability_after"] / f.spec.published["stability_deg_per_h"]
              for f in fitted if f.spec.published.get("stability_deg_per_h")]
    for f in fitted:
        pub = f.spec.published.get("improvement_pct")
        if pub is not None and abs(sc[f.spec.name]["improvement_pct"] - pub) > 5:
            off.append(f"{f.spec.name} {sc[f.spec.name]['improvement_pct']:.1f} % (paper "
                       f"{pub:.1f} %)")
    if off:
        out.append("Improvements more than 5 points from the published ones: " + "; ".join(off)
                   + f". Our raw stability on the test run is {raw:.5f} °/h against the "
                     f"paper's {config.published.get('stability_before', float('nan')):.5f}; "
                     "the percentages depend on how much slow noise one realisation holds"
                   + (f"; the compensated stabilities themselves are closer: ours / paper "
                      f"= {np.median(ratios):.2f} (median), {min(ratios):.2f} … "
                      f"{max(ratios):.2f}." if ratios else "."))
    if events:
        out.append(_mechanisms(train[0], spikes, hops, {f.spec.kind for f in fitted},
                               len(singles) >= 2))
    out.append("Nothing here was tuned to reproduce the paper's ranking: the device preset was "
               "fitted to the paper's Tables 1-2 (docs/sensors.md), the compensators use the "
               "settings in the study file, and the text above is generated from the numbers.")
    return out


def _deg_per_h_per_pulse(rs: RunSeries, config: Config) -> float:
    """What one extra pulse does to its window's measured bias [°/h]."""
    k0 = next((v for k, v in rs.coefficients.items() if k.startswith("gyro.k0[")), np.nan)
    return float(np.degrees(1.0 / (k0 * config.window_s)) * 3600.0)


def _mechanisms(rs: RunSeries, spikes: list[float], hops: list, kinds: set[str],
                singles: bool) -> str:
    """Which mechanism of the simulated device decides each of the study's rankings (paper 001;
    the ablation in docs/studies.md switches each off and shows it), from the unit's drawn
    coefficients and the train run's labelled events."""
    c = rs.coefficients

    def coef(name: str) -> float:
        return next((abs(v) for k, v in c.items() if k.startswith(name + "[")), 0.0)
    parts = []
    if singles:
        wander = coef("gyro.bias.uhfo") * coef("uhfo.wander_v")
        parts.append("UHFO strongest — the discharge wander only UHFO sees (|uhfo coefficient| "
                     f"× wander = {wander:.4f} °/h, 1σ)")
    if {"stepwise", "polynomial"} <= kinds:
        parts.append(f"stepwise > LS — the rate term ({coef('gyro.bias.rate'):.4f} °/h per "
                     "°C/min) that no single-input LS model represents beside T or U"
                     + (", with the mode hops' heating/cooling difference widening the margin"
                        if hops else ""))
    if "stepwise" in kinds and kinds & {"lssvm", "ir_lssvm"}:
        hop_t = ", ".join(f"{e[0] / 3600:.1f} h" for e in hops)
        parts.append("LSSVM vs stepwise — no mechanism: what a second-order polynomial cannot "
                     f"follow, the cold knee ({coef('gyro.bias.knee'):.4f} °/h) and the mode-hop "
                     f"steps with hysteresis ({len(hops)} in the train run"
                     + (f", at {hop_t}" if hops else "") + "), is small against the noise: "
                     "whichever mechanism the paper-001 ablation switches off, the margin stays "
                     "within ±1.8 % of raw − floor")
    if {"lssvm", "ir_lssvm"} <= kinds:
        parts.append(f"IR-LSSVM vs LSSVM — the {len(spikes)} read-out spikes in the train "
                     "windows (without them the two tie)")
    return ("Which mechanism decides each ranking (docs/studies.md, paper 001 ablation: each "
            "mechanism switched off): " + "; ".join(parts) + ". The frequency-stabilisation "
            "heater, the one-sided airflow and the mounting plate shape the temperature field "
            "but enter the bias only through T, dT/dt and UHFO, which every model sees.")
