"""The report of the ``gradient_selection`` recipe (paper 003): Table 3 beside the paper, the
input selection, Tables 4-5, truth-based scores and the ranking claim explained from the numbers
(figures: :mod:`rlgsim.lab.studies.gradient_selection_figures`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rlgsim.lab.report import Report, Table, slug
from rlgsim.lab.study import Study, StudyResult
from rlgsim.lab.studies.compensators import ORACLE, RAW
from rlgsim.lab.studies.fitting import Fitted
from rlgsim.lab.studies.gradient_selection_config import Config, Outcome, PaperTable
from rlgsim.lab.studies.gradient_selection_figures import figures, short
from rlgsim.lab.studies.gradient_selection_ranking import excitations, rankings
from rlgsim.lab.studies.report_text import (before_check, beside_first_test_navigation,
                                            definitions, device_coefficients_section,
                                            first_test_navigation, fmt, truth_score_tables)
from rlgsim.lab.studies.recording_runs import recorded_labels, recordings_paragraph, run_origin
from rlgsim.lab.studies.scoring import has_truth


# ------------------------------------------------------------------------------ the report
def improvement_over_traditional(trad_pct: float, prop_pct: float) -> float:
    """Paper 003 Tables 4-5: relative gain of the improvement percentage,
    100·(prop − trad)/trad (91.9 vs 65.5 % → 40.3 %)."""
    return 100.0 * (prop_pct - trad_pct) / trad_pct if trad_pct else float("nan")


def report(study: Study, config: Config, result: StudyResult, prepare=None) -> Report:
    """The report of a run (Table 3, the selection, Tables 4-5 beside the paper, truth-based
    scores, the ranking, figures); ``prepare``: the recipe's gradient selection, for the
    navigation's drawn units (:func:`navigation`). The navigation runs in a worker process
    meanwhile (:class:`rlgsim.lab.studies.task_share.TaskShare`: the same bytes as here)."""
    return beside_first_test_navigation(_report, study, config, result, prepare)


def _report(study: Study, config: Config, result: StudyResult, nav_runs) -> Report:
    from rlgsim.sim.writer.dataset import software_version

    out: Outcome = result.details
    runs, fitted, listings, per_test = out.runs, out.fitted, out.listings, out.per_test
    predictions, corr, Xtr, unit = out.predictions, out.corr, out.Xtr, out.unit
    t_data, t_total = out.t_data, out.t_total

    rep = Report(study.title)
    if study.description:
        rep.paragraph(study.description)
    rep.heading("Runs, seeds and software", 2)
    bullets = [f"rlgsim {software_version()}; recipe gradient_selection; unit {unit}"]
    for s in dict.fromkeys(config.train + config.test):
        ld = runs[s.key]
        rs = ld.series
        role = "train" if s in config.train else "test"
        stab = per_test.get(s.label, {}).get(RAW, {}).get("stability_before")
        bullets.append(f"{role} run {s.label}: {run_origin(ld)}, {rs.y.size} windows of "
                       f"{config.window_s:g} s"
                       + (f", raw STD {stab:.5f} °/h" if stab is not None else ""))
    bullets += [f"STD: std (ddof={config.ddof}) of {config.cluster_s:g} s cluster means of "
                "the bias (paper 003 eq. 11)",
                f"wall time: data {t_data:.1f} s, total {t_total:.1f} s"]
    rep.bullets(bullets)
    from rlgsim.lab.studies.run_days import run_to_run_section
    run_to_run_section(rep, runs, config.train, config.test)
    rep.heading("Definitions", 2)
    rep.bullets(definitions())
    truth = {s.label: has_truth(runs[s.key].series) for s in config.test}
    recorded = recorded_labels(runs, config.train + config.test)
    if recorded:
        rep.paragraph(recordings_paragraph(recorded, all(truth.values())))

    if corr is not None:
        _correlation_section(rep, config, corr, _train_network(config, runs))
    if listings:
        _selection_section(rep, listings)
    for pt in config.paper_tables:
        _paper_table_section(rep, pt, per_test[pt.test])
    _truth_section(rep, config, fitted, per_test, truth)
    from rlgsim.lab.studies.input_range import range_section
    range_section(rep, [(fitted, {s.label: runs[s.key].series for s in config.test})])
    rep.heading("Ranking: the paper's claim against ours", 2)
    network = _train_network(config, runs)
    for para in rankings(config, per_test, fitted, Xtr, runs, network):
        rep.paragraph(para)
    _series_attachments(rep, config, runs, predictions)
    figures(rep, config, runs, per_test, predictions, fitted, corr)
    first = runs[config.test[0].key].series
    nav = nav_runs.results()[0]
    if nav is not None:
        from rlgsim.lab.studies.navigation_section import add_section
        add_section(rep, *nav)
    if first.coefficients:
        device_coefficients_section(rep, first.coefficients, first.path)
    return rep


def navigation(study: Study, config: Config, result: StudyResult, prepare=None):
    """The first test run's navigation (:func:`.report_text.first_test_navigation`);
    ``prepare(spec, X, y) -> spec``: the recipe's gradient selection, so that each drawn
    unit's compensators select their gradients on that unit's own train windows."""
    return first_test_navigation(study, config, result.details, prepare)


def _matrix_records(points: tuple[str, ...], m: np.ndarray) -> list[dict[str, Any]]:
    """Rows of a thermometer × thermometer table (empty diagonal)."""
    return [{"thermometer": short(a), **{short(b): None if i == j else fmt(m[i, j])
                                          for j, b in enumerate(points)}}
            for i, a in enumerate(points)]


def _correlation_section(rep: Report, config: Config, corr: np.ndarray,
                         network=None) -> None:
    pts = config.points
    rep.heading("Correlation of the bias with the pairwise gradients (paper 003 Table 3)", 2)
    rep.table(Table.from_records("Ours: r(bias, T_row − T_column), train run(s)",
                                 _matrix_records(pts, corr),
                                 csv_name="correlation_matrix.csv",
                                 note="signed: T_row − T_column; the matrix of "
                                      "|r| is symmetric."))
    if config.published_matrix is not None:
        pub = config.published_matrix
        rep.table(Table.from_records("Paper 003 Table 3", _matrix_records(pts, pub),
                                     csv_name="correlation_matrix_paper.csv",
                                     note="the paper prints positive values only (|r|, or "
                                          "gradients oriented to correlate positively)."))
        iu = np.triu_indices(len(pts), 1)
        ours, theirs = np.abs(corr[iu]), np.abs(pub[iu])
        row_a = [abs(corr[0, j]) for j in range(1, len(pts))]
        pairs = [f"{short(pts[i])}−{short(pts[j])}" for i, j in zip(*iu)]
        far = sorted(zip(np.abs(ours - theirs), pairs, ours, theirs), reverse=True)[:3]
        rep.paragraph(
            f"Pattern check. Paper: all seven gradients from {short(pts[0])} (cathode) "
            f"correlate > 0.90 ({theirs[:len(pts) - 1].min():.3f} … "
            f"{theirs[:len(pts) - 1].max():.3f}); ours: {min(row_a):.3f} … {max(row_a):.3f}. "
            f"Over all {len(pairs)} pairs the rank correlation of ours with the paper's |r| is "
            f"{_spearman(ours, theirs):+.2f}, and {int(np.sum(ours >= 0.9))} of ours vs "
            f"{int(np.sum(theirs >= 0.9))} of the paper's reach 0.90. Largest differences: "
            + "; ".join(f"{p} ours {o:.3f} vs paper {t:.3f}" for _, p, o, t in far) + ".")
        figs = table3_figures(pts, corr, pub)
        rep.table(Table.from_records(
            "Table 3 figures: ours against the paper",
            [{"figure": name, "ours": fmt(o), "paper": fmt(t)} for name, o, t in figs],
            csv_name="table3_figures.csv",
            note="pattern: Pearson correlation of our |r| with the paper's over all pairs; "
                 "mirror pairs: the left/right counterparts B−C (gain-arm corners), D−E "
                 "(anodes), F−H (non-gain sides); A row: the gradients from the cathode "
                 "region."))
    if network is not None:
        rep.paragraph(_asymmetry_text(pts, network))


def table3_figures(points: tuple[str, ...], corr: np.ndarray, pub: np.ndarray
                   ) -> list[tuple[str, float, float]]:
    """(name, ours, paper) of the Table 3 figures: the pattern correlation (Pearson of |r| over
    all pairs), each mirror pair present among ``points`` and the smallest |r| of the first
    point's row (the cathode region A in paper 003)."""
    iu = np.triu_indices(len(points), 1)
    ours, theirs = np.abs(corr[iu]), np.abs(pub[iu])
    out = [(f"pattern correlation over {len(ours)} pairs", float(np.corrcoef(ours, theirs)[0, 1]),
            1.0)]
    letters = [short(p) for p in points]
    for a, b in MIRROR_PAIRS:
        if a in letters and b in letters:
            i, j = letters.index(a), letters.index(b)
            out.append((f"mirror pair {a}−{b}", float(abs(corr[i, j])), float(abs(pub[i, j]))))
    out.append((f"{letters[0]} row, smallest |r|", float(np.abs(corr[0, 1:]).min()),
                float(np.abs(pub[0, 1:]).min())))
    return out


#: Left/right counterparts of paper 003 Fig. 2 (gain-arm corners, anodes, non-gain sides).
MIRROR_PAIRS = (("B", "C"), ("D", "E"), ("F", "H"))


def _train_network(config: Config, runs) -> Any:
    """The (nominal) thermal network of the first train run's device, or None."""
    scenario = runs[config.train[0].key].scenario
    device = getattr(scenario, "device", None)
    thermal = getattr(device, "thermal", None)
    return getattr(thermal, "network", None)



def _asymmetry_text(points: tuple[str, ...], network) -> str:
    """What the nominal thermal design gives the mirror pairs and which excitations drive the
    block, from the network itself."""
    names = list(network.node_names)
    warm = network.steady_state(20.0, True)
    diffs = []
    for a, b in MIRROR_PAIRS:
        na = next((p for p in points if short(p) == a), None)
        nb = next((p for p in points if short(p) == b), None)
        if na in names and nb in names:
            diffs.append((f"{a}−{b}", float(warm[names.index(na)] - warm[names.index(nb)])))
    text = ("Why the mirror pairs look as they do: the nominal thermal design (unit 0) is "
            "driven by " + ", ".join(excitations(network)) + ". ")
    if diffs and max(abs(d) for _, d in diffs) < 1e-6:
        text += ("Its block is left/right symmetric, so the mirror pairs heat alike and their "
                 "difference carries only probe noise; the paper's block has the residual "
                 "asymmetries it names (anode material, ballast resistance). Monte Carlo units "
                 "≥ 1 draw an asymmetric network (docs/montecarlo.md).")
    elif diffs:
        text += ("Its block is not left/right symmetric (steady differences at 20 °C, powered: "
                 + ", ".join(f"{n} {d:+.3f} K" for n, d in diffs)
                 + "), and the arms see different parts of the boundary, so the mirror "
                   "gradients move with the chamber programme and carry information of their "
                   "own (docs/thermal.md §7 lists the mechanisms and what each one does).")
    return text


def _spearman(a: np.ndarray, b: np.ndarray) -> float:
    from scipy.stats import spearmanr
    return float(spearmanr(a, b).statistic)


def _selection_section(rep: Report, listings) -> None:
    rep.heading("Input selection on the train run(s) (paper 003 §4.3)", 2)
    for name, listing in listings.items():
        recs = [{"gradient": g, "r": fmt(r), "|r|": fmt(abs(r)), "selected": "yes" if k else ""}
                for g, r, k in listing]
        rep.table(Table.from_records(f"{name}: candidate gradients", recs,
                                     csv_name=f"selection_{slug(name)}.csv"))


def _paper_table_section(rep: Report, pt: PaperTable, sc: dict) -> None:
    t, p = sc[pt.traditional], sc[pt.proposed]
    ours_over = improvement_over_traditional(t["improvement_pct"], p["improvement_pct"])
    recs = [
        {"RLG bias (°/h)": "before compensation",
         f"{pt.traditional} (ours)": fmt(t["stability_before"]),
         f"{pt.traditional} (paper)": pt.before,
         f"{pt.proposed} (ours)": fmt(p["stability_before"]),
         f"{pt.proposed} (paper)": pt.before},
        {"RLG bias (°/h)": "after compensation",
         f"{pt.traditional} (ours)": fmt(t["stability_after"]),
         f"{pt.traditional} (paper)": pt.after.get(pt.traditional),
         f"{pt.proposed} (ours)": fmt(p["stability_after"]),
         f"{pt.proposed} (paper)": pt.after.get(pt.proposed)},
        {"RLG bias (°/h)": "improvement from original accuracy (%)",
         f"{pt.traditional} (ours)": fmt(t["improvement_pct"]),
         f"{pt.traditional} (paper)": pt.improvement_pct.get(pt.traditional),
         f"{pt.proposed} (ours)": fmt(p["improvement_pct"]),
         f"{pt.proposed} (paper)": pt.improvement_pct.get(pt.proposed)},
        {"RLG bias (°/h)": "improvement from traditional method (%)",
         f"{pt.traditional} (ours)": None, f"{pt.traditional} (paper)": None,
         f"{pt.proposed} (ours)": fmt(ours_over),
         f"{pt.proposed} (paper)": pt.improvement_over_traditional_pct},
        {"RLG bias (°/h)": "STD after, traditional / proposed",
         f"{pt.traditional} (ours)": None, f"{pt.traditional} (paper)": None,
         f"{pt.proposed} (ours)": fmt(t["stability_after"] / p["stability_after"]),
         f"{pt.proposed} (paper)": (pt.after[pt.traditional] / pt.after[pt.proposed]
                                    if pt.traditional in pt.after and pt.proposed in pt.after
                                    else None)},
    ]
    rep.heading(f"{pt.title} (test run {pt.test})", 2)
    rep.table(Table.from_records(pt.title, recs, csv_name=f"paper_{slug(pt.title)}.csv",
                                 note="improvement from the traditional method = "
                                      "100·(improvement_proposed − improvement_traditional) / "
                                      "improvement_traditional, as the paper computes it."))
    if pt.before:
        rep.paragraph(before_check(t["stability_before"], pt.before))


def _truth_section(rep: Report, config: Config, fitted: list[Fitted], per_test,
                   truth: dict[str, bool]) -> None:
    scored = {label: t for label, t in per_test.items() if truth[label]}
    if scored:
        truth_score_tables(rep, scored)
    else:
        rep.heading("Truth-based scores", 2)
    absent = [label for label in per_test if not truth[label]]
    if absent:
        rep.paragraph(f"Absent for {', '.join(absent)}: "
                      f"{'the test run is a recording' if len(absent) == 1 else 'recordings'}, "
                      f"which {'has' if len(absent) == 1 else 'have'} no ground truth.")
    recs = [{"compensator": f.spec.name, "kind": f.spec.kind, "inputs": ", ".join(f.spec.inputs),
             "fit time s": fmt(f.fit_s), **{k: fmt(v) for k, v in f.hyper.items()}}
            for f in fitted]
    cols: list[str] = []
    for rec in recs:
        cols += [k for k in rec if k not in cols]
    rep.table(Table.from_records("Fitted models", [{k: r.get(k) for k in cols} for r in recs],
                                 csv_name="hyperparameters.csv",
                                 note="PSO-SVR: C and gamma (RBF kernel on standardised "
                                      "inputs) tuned by particle swarm on a validation RMSE."))



def _series_attachments(rep: Report, config: Config, runs, predictions) -> None:
    rep.heading("Window series (CSV)", 2)
    for spec in config.test:
        rs = runs[spec.key].series
        preds = predictions[spec.label]
        cols = {"time_s": rs.time_s, "y_deg_per_h": rs.y, "true_bias_deg_per_h": rs.true_bias,
                "true_random_deg_per_h": rs.true_random}
        cols.update({f"pred: {n}": v for n, v in preds.items() if n not in (RAW, ORACLE)})
        names = list(cols)
        rows = [list(map(float, r)) for r in zip(*cols.values())]
        rep.attachment(Table(f"Test run {spec.label}: window series", names, rows,
                             csv_name=f"series_{slug(spec.label)}.csv",
                             note=f"{config.window_s:g} s windows; pred: each compensator's ŷ"))
