"""The report of the ``bias_compensation`` recipe (papers 001 and demo): the runs, the
correlation table, the paper's tables beside ours, the truth-based scores, the fitted models,
the rankings (:mod:`rlgsim.lab.studies.bias_compensation_ranking`) and the figures
(:mod:`rlgsim.lab.studies.bias_compensation_figures`)."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.report import Report, Table, slug
from rlgsim.lab.studies.bias_compensation_config import Config, Outcome
from rlgsim.lab.studies.bias_compensation_figures import run_figures
from rlgsim.lab.studies.bias_compensation_ranking import rankings
from rlgsim.lab.studies.compensators import EQUATION_KINDS, RAW
from rlgsim.lab.studies.fitting import Fitted
from rlgsim.lab.studies.recording_runs import recorded_labels, recordings_paragraph, run_origin
from rlgsim.lab.studies.report_text import (before_check, beside_first_test_navigation,
                                            definitions, device_coefficients_section,
                                            first_test_navigation, fmt, truth_score_tables)
from rlgsim.lab.studies.runs import RunSeries
from rlgsim.lab.studies.scoring import has_truth, series_stability
from rlgsim.lab.study import Study, StudyResult


# ------------------------------------------------------------------------------ the report
def report(study: Study, config: Config, result: StudyResult) -> Report:
    """The report of a run (the paper's tables beside ours, truth-based scores, rankings,
    figures). The navigation runs in a worker process meanwhile
    (:class:`rlgsim.lab.studies.task_share.TaskShare`: the same bytes as here)."""
    return beside_first_test_navigation(_report, study, config, result)


def _report(study: Study, config: Config, result: StudyResult, nav_runs) -> Report:
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

    # a user's own study (no paper key, no published numbers) has no paper columns or claims
    paper = bool(study.paper) or any(bool(v) for v in config.published.values()) \
        or any(f.spec.published for f in fitted)
    _correlation_section(rep, config, Xtr, ytr, rs_test, paper)
    _paper_tables_section(rep, config, fitted, sc, test_label, paper)
    _fitted_section(rep, fitted, per_test, truth)

    # -- rankings
    from rlgsim.lab.studies.input_range import range_section
    range_section(rep, [(fitted, {s.label: runs[s.key].series for s in config.test})])
    if paper:
        rep.heading("Rankings: the paper's claims against ours", 2)
        for para in rankings(config, fitted, sc, int(ytr.size), out.train):
            rep.paragraph(para)

    # -- figures, per test run
    multi = len(config.test) > 1
    for spec in config.test:
        run_figures(rep, config, fitted, runs[spec.key].series, predictions[spec.label],
                    per_test[spec.label], ytr, spec.label, multi)

    nav = nav_runs.results()[0]
    if nav is not None:
        from rlgsim.lab.studies.navigation_section import add_section
        add_section(rep, *nav)

    if rs_test.coefficients:
        device_coefficients_section(rep, rs_test.coefficients, rs_test.path)
    return rep


def navigation(study: Study, config: Config, result: StudyResult):
    """The first test run's navigation (:func:`.report_text.first_test_navigation`)."""
    return first_test_navigation(study, config, result.details)


def _correlation_section(rep: Report, config: Config, Xtr, ytr, rs_test: RunSeries, paper: bool) -> None:
    """The correlation of the bias with each input (paper 001 Table 1 beside ours when the
    study follows a paper)."""
    rep.heading("Correlation of the bias with the inputs"
                + (" (paper 001 Table 1)" if paper else ""), 2)
    corr_pub = config.published.get("correlation", {})
    recs = []
    for name in Xtr.names:
        rec = {"input": name}
        if paper:
            rec["paper"] = corr_pub.get(name)
        rec.update({"ours (train, measured y)": fmt(np.corrcoef(Xtr[name], ytr)[0, 1]),
                    "ours (test, measured y)": fmt(np.corrcoef(rs_test.X[name],
                                                               rs_test.y)[0, 1]),
                    "ours (test, true b)": fmt(np.corrcoef(rs_test.X[name],
                                                           rs_test.true_bias)[0, 1])})
        recs.append(rec if paper else {k.removeprefix("ours "): v for k, v in rec.items()})
    rep.table(Table.from_records("Correlation coefficients", recs, csv_name="correlation.csv"))


def _paper_tables_section(rep: Report, config: Config, fitted: list[Fitted], sc: dict,
                  test_label: str, paper: bool) -> None:
    """The scores of every compensator on the test run, per paper table; the published
    numbers beside ours only when the study follows a paper."""
    before_pub = config.published.get("stability_before")
    tables: dict[str, list[Fitted]] = {}
    for f in fitted:
        tables.setdefault(f.spec.table or ("Other compensators" if paper else "Compensators"),
                          []).append(f)
    rep.heading(f"Paper-style scores on test run {test_label} (ours beside the paper)" if paper
                else f"Scores on test run {test_label}", 2)
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
            if not paper:
                rec = {k.replace(" (ours)", ""): v for k, v in rec.items()
                       if "(paper)" not in k}
            recs.append(rec)
        cols: list[str] = []
        for rec in recs:
            cols += [k for k in rec if k not in cols]
        recs = [{k: rec.get(k) for k in cols} for rec in recs]
        note = "paper: the published value; — where the paper gives none." if paper else ""
        if "c (ours)" in cols or "c" in cols:          # kernel models only
            note += (" c is the LS-SVM regularisation (gamma), σ² the squared kernel width in "
                     "standardised inputs" + (" (ours; the paper does not say whether it "
                                              "standardised). The paper's F(x) column is not "
                                              "reproduced: the paper does not define it."
                                              if paper else "."))
        rep.table(Table.from_records(tname, recs, csv_name=f"paper_{slug(tname)}.csv"
                                     if paper else f"scores_{slug(tname)}.csv",
                                     note=note.strip()))


def _fitted_section(rep: Report, fitted: list[Fitted], per_test: dict, truth: bool) -> None:
    """The truth-based scores, the fitted hyper-parameters and the regression equations."""
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



def _raw_stability(rs: RunSeries, config: Config) -> float:
    return series_stability(rs.y, config.window_s, config.cluster_s, config.ddof)
