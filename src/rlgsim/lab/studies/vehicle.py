"""Recipe ``vehicle``: compensators trained in the chamber, scored on a vehicle's mission by the
coasting error they leave through its GNSS outages (issue 26; docs/trajectories.md).

A study with ``recipe = "vehicle"`` has these tables::

    [train]                          # the chamber run the compensators learn from
    scenario = "vehicle_train_ramp"
    window_s = 100                   # averaging window [s]

    [mission]                        # the vehicle run they are scored on
    scenario = "vehicle_land_cold"
    duration_h = 0.85                # optional: cut the mission (here: to its first outage)
    sample_rate_hz = 20              # optional: another IMU rate for the mission

    [[compensator]]                  # one per model; inputs "T" (the gyro's cathode probe
    name = "LS cubic T"              # g<axis>.A, window mean) and "dT/dt" (its slope)
    inputs = ["T"]
    degree = 3

For each gyro axis a :class:`rlgsim.estimators.polynomial.PolynomialRegressor` is fitted on the
train run's windows (:func:`rlgsim.lab.api.window_table`: measured bias against the probe's
mean and slope) and predicts the mission's gyro biases window by window; the mission's variants
``raw``, each compensator, ``oracle`` and ``truth`` go through the aided navigator
(:func:`rlgsim.lab.mission.score_mission`). Rows: the coasting error of every outage and the
heading error RMS per variant; the report adds the mission's figure.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.ground.units import DEG, HOUR
from rlgsim.lab.report import Report, Table
from rlgsim.lab.study import Study, StudyResult, scenario_for
from rlgsim.sim.config import (check_known_keys, get_float, get_int, get_list, get_str,
                               get_table)

INPUTS = ("T", "dT/dt")

#: the mission's variants beside the compensators (:func:`rlgsim.lab.mission.score_mission`)
VARIANTS = ("raw", "oracle", "truth")


@dataclass(frozen=True)
class Compensator:
    name: str
    inputs: tuple[str, ...]
    degree: int


@dataclass(frozen=True)
class VehicleConfig:
    train: str
    window_s: float
    mission: str
    mission_changes: dict
    compensators: tuple[Compensator, ...]


def check(study: Study) -> VehicleConfig:
    """Validate the recipe's tables (module docstring)."""
    t = study.tables
    check_known_keys(t, ("study", "train", "mission", "compensator"), study.ctx())
    tr = get_table(t, "train", study.ctx())
    check_known_keys(tr, ("scenario", "window_s"), study.ctx("train"))
    mi = get_table(t, "mission", study.ctx())
    check_known_keys(mi, ("scenario", "duration_h", "sample_rate_hz"), study.ctx("mission"))
    changes = {}
    if "duration_h" in mi:
        changes["duration_h"] = get_float(mi, "duration_h", study.ctx("mission"), min=0.0,
                                          min_exclusive=True)
    if "sample_rate_hz" in mi:
        changes["acquisition.sample_rate_hz"] = get_float(mi, "sample_rate_hz",
                                                          study.ctx("mission"), min=0.0,
                                                          min_exclusive=True)
    comps: list[Compensator] = []
    for i, c in enumerate(get_list(t, "compensator", study.ctx(), [])):
        ctx = study.ctx("compensator").item(i)
        check_known_keys(c, ("name", "inputs", "degree"), ctx)
        inputs = tuple(get_list(c, "inputs", ctx, ["T"], min_len=1))
        for x in inputs:
            if x not in INPUTS:
                raise ctx.error("inputs", f"{x!r} not allowed; one of {', '.join(INPUTS)}")
        if len(set(inputs)) < len(inputs):
            raise ctx.error("inputs", f"{list(inputs)} names an input twice; each of "
                                      f"{', '.join(INPUTS)} at most once")
        name = get_str(c, "name", ctx)
        taken = [*VARIANTS, *(k.name for k in comps)]
        if not name.strip() or name in taken:
            raise ctx.error("name", f"{name!r} not allowed; a compensator's name is its row in "
                                    f"the scores, so it must be non-empty and none of "
                                    f"{', '.join(repr(v) for v in taken)}")
        comps.append(Compensator(name, inputs, get_int(c, "degree", ctx, 3, min=1, max=5)))
    return VehicleConfig(get_str(tr, "scenario", study.ctx("train")),
                         get_float(tr, "window_s", study.ctx("train"), 100.0, min=1.0),
                         get_str(mi, "scenario", study.ctx("mission")), changes, tuple(comps))


def _features(df, axis: str, inputs: tuple[str, ...]) -> np.ndarray:
    cols = {"T": f"probe_g{axis}.A_c", "dT/dt": f"dTdt_g{axis}.A_k_per_s"}
    return np.column_stack([df[cols[x]].to_numpy() for x in inputs])


def run(study: Study, config: VehicleConfig, workdir: pathlib.Path, *, unit: int = 0,
        progress: bool = True) -> StudyResult:
    """Simulate the train and mission runs, fit, score (module docstring)."""
    from rlgsim.estimators.polynomial import PolynomialRegressor
    from rlgsim.lab.api import window_table
    from rlgsim.lab.mission import score_mission
    from rlgsim.sim.run.simulate import simulate
    train_sc = scenario_for(study, config.train, unit=unit, ctx=study.ctx("train", "scenario"))
    mission_sc = scenario_for(study, config.mission, unit=unit,
                              ctx=study.ctx("mission", "scenario"))
    mission_sc = mission_sc.with_changes(config.mission_changes)   # both checked before a run
    if mission_sc.trajectory is None:
        raise study.ctx("mission").error("scenario", f"{config.mission!r} has no [trajectory]; "
                                                     f"the mission is a run on a vehicle "
                                                     f"(docs/trajectories.md)")
    for key, sc in (("train", train_sc), ("mission", mission_sc)):
        if sc.duration_s < config.window_s:
            raise study.ctx(key).error("scenario", f"{sc.name} lasts {sc.duration_s:g} s, "
                                                   f"shorter than train.window_s = "
                                                   f"{config.window_s:g} s")
        _window_fits(study, key, sc, config.window_s)
        axes = list(sc.device.tables.get("gyro", {}).get("axes", ["x", "y", "z"]))
        has_acc = "accelerometer" in sc.device.tables
        if sorted(axes) != ["x", "y", "z"] or (key == "mission" and not has_acc):
            what = f"gyro axes {', '.join(axes)}" + ("" if has_acc else ", no accelerometers")
            raise study.ctx(key).error("scenario", f"{sc.name}'s device {sc.device.name} has "
                                                   f"{what}; the recipe needs three gyros x, y, "
                                                   f"z (and on the mission three accelerometers)")
    for comp in config.compensators:    # too few windows: refused before any run (the late
        _enough_windows(study, comp, _powered_windows(train_sc, config.window_s),  # check stays)
                        _powered_windows(mission_sc, config.window_s), config.window_s,
                        at_most=True)
    # the mission's route built and checked against the sensors' ranges (cached on the scenario
    # for its run): a route past the gyro range is refused before the train run, not after it
    mission_sc.trajectory.build(float(mission_sc.duration_s))
    data = workdir / "data"
    data.mkdir(parents=True, exist_ok=True)
    train = simulate(train_sc, data / "train.h5", progress=progress)
    mission = simulate(mission_sc, data / "mission.h5", progress=progress)
    from rlgsim.lab.studies.input_range import outside_range
    w = config.window_s
    models, outside = {}, {}
    for comp in config.compensators:
        ends, preds, ranges = [], [], []
        for axis in "xyz":
            tdf, mdf = window_table(train, w, gyro=axis), window_table(mission, w, gyro=axis)
            _enough_windows(study, comp, len(tdf), len(mdf), w)
            x_train, x_test = _features(tdf, axis, comp.inputs), _features(mdf, axis, comp.inputs)
            model = PolynomialRegressor(degree=comp.degree).fit(
                x_train, tdf["bias_deg_per_h"].to_numpy())
            ends.append(mdf["time_s"].to_numpy())
            preds.append(model.predict(x_test) * DEG / HOUR)
            ranges.append(outside_range(dict(zip(comp.inputs, x_train.T)),
                                        dict(zip(comp.inputs, x_test.T)), comp.inputs))
        models[comp.name] = _window_function(ends, preds, w)
        # the worst axis: each gyro has its own model and its own probe
        outside[comp.name] = (max(r[0] for r in ranges), max(r[1] for r in ranges))
    scores = score_mission(mission, models=models)
    rows = []
    for name, s in scores.items():
        for i, e in enumerate(s["outage_error_m"]):
            rows.append((name, f"coasting_error_outage{i + 1}_m", float(e)))
        rows.append((name, "heading_rms_arcsec", s["heading_rms_arcsec"]))
        if name in outside:
            rows.append((name, "outside_range_pct", outside[name][0]))
            rows.append((name, "outside_excess_pct", outside[name][1]))
    return StudyResult(rows, details={"scores": scores, "mission": mission,
                                      "outside": outside})


def _window_fits(study: Study, key: str, sc: Any, window_s: float) -> None:
    """One line unless ``window_s`` is a whole number of ``sc``'s IMU samples and of at least
    two thermal steps (a window's temperature slope needs two probe readings)."""
    from rlgsim.estimators.features import samples_per_window
    acq = sc.acquisition
    try:
        samples_per_window(acq.sample_rate_hz, window_s)
        steps = samples_per_window(1.0 / acq.thermal_step_s, window_s)
    except ValueError:
        steps = 0
    if steps < 2:
        raise study.ctx("train").error(
            "window_s", f"{window_s:g} s not allowed; a window holds a whole number of the "
                        f"{key} run's samples ({acq.sample_rate_hz:g} Hz) and of its "
                        f"{acq.thermal_step_s:g}-s thermal steps, at least two of them")


def _powered_windows(sc: Any, window_s: float) -> int:
    """At most how many of ``sc``'s ``window_s`` windows (from the start, back to back) can be
    powered throughout, from ``duration_s`` and ``[power] on_at_s``/``off_at_s`` alone — an
    upper bound (a window holding the switching instant is counted), so a run it refuses
    has too few windows whatever its data."""
    n = math.floor(sc.duration_s / window_s + 1e-9)
    first = math.floor(sc.power.on_at_s / window_s + 1e-9)
    end = n if sc.power.off_at_s is None else min(n, math.ceil(sc.power.off_at_s / window_s))
    return max(0, end - first)


def _enough_windows(study: Study, comp: Compensator, n_train: int, n_mission: int,
                    window_s: float, *, at_most: bool = False) -> None:
    """One line when the runs' powered windows cannot fit or use ``comp`` (a polynomial of
    C(degree + inputs, degree) coefficients) — a window too long for a run, a mission cut short;
    ``at_most``: the counts are :func:`_powered_windows`' bounds (checked before the runs)."""
    need = math.comb(comp.degree + len(comp.inputs), comp.degree)
    if n_train < need:
        bound = "at most " if at_most else ""
        raise study.ctx("train").error("window_s", f"{window_s:g} s leaves {bound}{n_train} "
                                                   f"powered "
                                                   f"window(s) in the train run; compensator "
                                                   f"{comp.name!r} has {need} coefficients to "
                                                   f"fit (a shorter window or a longer run)")
    if n_mission < 1:
        raise study.ctx("mission").error("scenario", f"no powered {window_s:g}-s window "
                                                     f"(train.window_s) in the mission run; the "
                                                     f"compensators predict window by window "
                                                     f"(a longer mission or a shorter window)")


def _window_function(ends: list, preds: list, window_s: float):
    """f(t) → the window prediction holding t (0 outside every window), (k, 3) [rad/s]."""
    def predict(t: np.ndarray) -> np.ndarray:
        cols = []
        for e, p in zip(ends, preds):
            i = np.searchsorted(e, t, side="left")
            j = np.minimum(i, e.size - 1)
            ok = (i < e.size) & (t >= e[j] - window_s)
            cols.append(np.where(ok, p[j], 0.0))
        return np.column_stack(cols)
    return predict


def report(study: Study, config: VehicleConfig, result: StudyResult) -> Report:
    """Scores table and the mission's figure."""
    from rlgsim.lab.mission_report import mission_plot
    rep = Report(study.title)
    if study.description:
        rep.paragraph(study.description)
    rep.paragraph(f"Compensators fitted on {config.train} (windows of {config.window_s:g} s), "
                  f"scored on {config.mission} through the aided navigator "
                  f"(rlgsim.lab.mission; docs/trajectories.md): raw, each compensator, the "
                  f"oracle (the true temperature laws removed) and the floor (exact "
                  f"increments).")
    outside = result.details.get("outside", {})
    if outside:
        worst = max(outside, key=lambda k: outside[k][0])
        rep.paragraph(
            "Inputs outside the training range (read with the scores below): the mission's "
            "windows whose inputs lie outside the chamber run's [min, max] per input (the worst "
            "gyro axis; rows outside_range_pct, outside_excess_pct): "
            + "; ".join(f"{k} {v[0]:.1f} % (largest excess {v[1]:.1f} % of the span)"
                        for k, v in outside.items())
            + (f". Where a compensator extrapolates ({worst}), its coasting error partly "
               "measures how its polynomial runs off outside the range, not how well it learnt "
               "the law." if outside[worst][0] > 0 else
               ". Every window lies inside: the scores compare interpolation."))
    rep.table(Table("Scores", ["variant", "metric", "value"],
                    [[a, b, f"{c:.4g}"] for a, b, c in result.rows], csv_name="scores.csv"))
    details: dict[str, Any] = result.details
    rep.figure(mission_plot(details["mission"], details["scores"]), "mission.png",
               "the route with its GNSS outages, the bay's air and the unit's coldest and "
               "warmest nodes, each variant's horizontal error (outages shaded)")
    return rep
