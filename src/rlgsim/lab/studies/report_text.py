"""Report text the single-gyro recipes share: the definitions of the series and scores, the
"before compensation" check against a paper, the truth-based score tables, and table cells."""

from __future__ import annotations

import numpy as np

from rlgsim.lab.studies.compensators import ORACLE, RAW
from rlgsim.lab.studies.runs import worth_showing


def fmt(x: float | None) -> float | None:
    """A table cell: ``None`` (shown as —) for a missing or non-finite number."""
    return None if x is None or not np.isfinite(x) else float(x)


def definitions() -> list[str]:
    """The report's definitions of the series and scores (module docstring), as bullets."""
    return [
        "y: measured bias per window = pulses / (nominal scale factor × window) − Earth-rate "
        "projection, °/h; ŷ: a compensator's prediction; y − ŷ: the compensated series.",
        "b: true bias = window mean of truth/gyro_bias (temperature law + flicker + random "
        "walk), °/h; r: its flicker + random-walk part (truth/gyro_bias_random).",
        "stability_before / stability_after: bias stability of y / of y − ŷ (papers 001, "
        "003); improvement_pct = 100·(before − after)/before; improvement_factor = before / "
        "after (paper 002).",
        "rmse_true, mae_true, r2_true: ŷ against b. b leaves out the constant that the "
        "scale-factor error and misalignment add to a static gyro's output (Earth rate × a few "
        "ppm/arcsec), which the compensators fold into their constant.",
        "resid_std_true = std(ŷ − b): true bias left after compensation, offset-free (the "
        "stability a noise-free gyro would show); law_resid_std = std(ŷ − (b − r)): error of "
        "the learnt temperature law alone.",
        f"'{ORACLE}': the oracle ŷ = b − r (the true temperature law); its stability_after is "
        f"the floor for any input-driven model. '{RAW}': no compensation (ŷ = train mean).",
    ]


def before_check(ours: float, paper: float, factor: float = 1.5) -> str:
    """One sentence comparing our raw bias stability with the paper's "before compensation"
    (issue 7: within a factor 1.5)."""
    ratio = ours / paper
    within = 1 / factor <= ratio <= factor
    return (f"Before compensation: ours {ours:.5f} °/h vs paper {paper:.5f} °/h (ratio "
            f"{ratio:.2f}; {'within' if within else 'NOT within'} a factor {factor:g}).")


def truth_score_tables(rep, per_test: dict[str, dict[str, dict[str, float]]]) -> None:
    """The report's section of every score of every compensator, one table (and CSV
    ``scores_<test run>.csv``) per test run."""
    from rlgsim.lab.report import Table, slug
    rep.heading("Truth-based scores (what no paper could measure)", 2)
    for label, table in per_test.items():
        recs = [{"compensator": name, **{k: fmt(v) for k, v in s.items()}}
                for name, s in table.items()]
        rep.table(Table.from_records(f"All scores, test run {label}", recs,
                                     csv_name=f"scores_{slug(label)}.csv",
                                     note="°/h except r2_true (1), improvement_pct (%) and "
                                          "improvement_factor (1)."))


def device_coefficients_section(rep, coefficients: dict[str, float], path=None) -> None:
    """The report's section of the drawn device coefficients worth showing (non-zero bias and
    UHFO law terms; ``device_coefficients.csv``), each with its unit as the preset writes it
    (read from the dataset at ``path``; :mod:`rlgsim.lab.studies.device_units`)."""
    from rlgsim.lab.report import Table
    from rlgsim.lab.studies.device_units import coefficient_units, in_preset_units
    units = coefficient_units(path) if path is not None else {}
    rows = []
    for k, v in coefficients.items():
        if worth_showing(k) and v != 0.0:
            value, unit = in_preset_units(k, v, units.get(k, ""))
            rows.append({"coefficient": k, "value": value, "unit": unit})
    rep.heading("Drawn device parameters (truth)", 2)
    rep.table(Table.from_records("Device coefficients", rows,
                                 csv_name="device_coefficients.csv"))


def anomaly_events(paths) -> list[tuple[float, str, float, str]]:
    """The labelled anomaly events (time [s], kind, size, size units) of the datasets at
    ``paths`` (docs/sensors.md "Anomalies"); none for a dataset without the record (a
    recording, or a device without ``[anomalies]``)."""
    from rlgsim.ground.dataset_format import ANOMALIES, open_dataset
    from rlgsim.ground.errors import UserInputError
    out = []
    for path in paths:
        try:
            ds = open_dataset(path)
        except UserInputError:          # a recording (CSV, Parquet, ...): no truth, no record
            continue
        with ds:
            if not ds.has(ANOMALIES, "kind"):
                continue
            out += list(zip(ds.read(ANOMALIES, "time").tolist(), ds.strings(ANOMALIES, "kind"),
                            ds.read(ANOMALIES, "size").tolist(),
                            ds.strings(ANOMALIES, "size_units")))
    return out


def weight_spread(scores: dict[str, float], groups: dict[str, list[str]]
                  ) -> tuple[float, str]:
    """Largest relative spread [%] of ``scores`` within a group (the four IR-LSSVM weights of
    one input set: (max − min)/min of their bias stability) and that group's name."""
    best, where = 0.0, ""
    for name, members in groups.items():
        v = [scores[m] for m in members]
        if len(v) > 1 and min(v) > 0 and (max(v) - min(v)) / min(v) * 100 >= best:
            best, where = (max(v) - min(v)) / min(v) * 100, name
    return best, where


def first_test_navigation(study, config, out, prepare=None):
    """The navigation of a single-gyro study's first test run by the three-gyro IMU
    (:func:`rlgsim.lab.studies.imu_axes.imu_navigation`; docs/navigation.md, "In the
    studies"): (dataset, introduction), or None for a recording; ``out`` the recipe's outcome
    (``runs``, ``predictions``, ``fitted``, ``unit``); ``prepare(spec, X, y) -> spec`` the
    recipe's input selection."""
    from rlgsim.lab.studies.imu_axes import ImuRun, imu_navigation
    test = config.test[0]
    exp = ImuRun(out.runs, tuple(config.train), test, out.fitted, out.predictions[test.label])
    return imu_navigation(study, config, exp, unit=out.unit, prepare=prepare)


def beside_first_test_navigation(build, study, config, result, prepare=None):
    """``build(study, config, result, nav)`` — a single-gyro study's report — while
    :func:`first_test_navigation` runs in a worker process
    (:class:`rlgsim.lab.studies.task_share.TaskShare`, ``nav``: the same bytes as here); the
    worker is stopped when the report is built or fails."""
    from rlgsim.lab.studies.task_share import TaskShare
    nav = TaskShare(first_test_navigation, [(study, config, result.details, prepare)],
                    background=True)
    try:
        return build(study, config, result, nav)
    finally:
        nav.close()
