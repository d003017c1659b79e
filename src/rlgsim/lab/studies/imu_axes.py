"""The three-gyro IMU that a single-gyro study navigates (demo, papers 001–003;
docs/navigation.md, "In the studies").

A single-gyro study simulates one gyro; an INS needs three. Its navigation section builds an IMU
of three such gyros:

* **units** — the study's own unit (its train and test datasets as they are) and two more units
  drawn from the same preset: the same runs with the Monte Carlo unit index
  ``unit + j·AXIS_UNIT_STRIDE`` (j = 1, 2), i.e. the existing unit mechanism of the seed tree
  (``rlgsim.sim.rng``): another drawn device (the preset's spreads), its own run-to-run draws
  (``sim/run/run_to_run.py`` keys them by unit: turn-on bias, and also the laboratory and
  chamber air offsets, which in one real chamber the three would share — a simplification)
  and noise. They start from the study unit's loaded scenario, so a Monte Carlo campaign's
  chamber variation (``sim/run/unit_variations.py``) is the study unit's for all three: the three
  gyros of one IMU share one chamber programme. The drawn units are simulated into the study's
  data folder by the study's one dataset writer (:func:`rlgsim.lab.studies.runs.
  simulated_dataset`: reused when the fingerprint matches) and streamed chunk by chunk into the
  navigator (:func:`rlgsim.lab.navigation_source.gyro_units_source`), never copied into a
  combined dataset.
* **compensation** — each navigated compensator is the same method trained per axis: each unit's
  model is fitted on that unit's own train windows (the recipe's fit, and its input selection
  when it has one) and predicts that unit's own test windows; the study unit's models are the
  study's own fits.
* **mounting** — the study's unit on body y (North at the table's zero: a North gyro error costs
  the most position), the drawn units on x (East) and z (up); each unit's gyro error (pulses ×
  nominal weight minus the true increment along its input axis) rides on the exact increments
  of the run's motion on its axis. The three thermal networks are independent (no heat passes
  between the gyros).
* **accelerometers** — ideal: the studies' compensators model the gyro bias only, and a real
  accelerometer's temperature law would add one Schuler-bounded error (bias·R/g, about 0.64 km
  per 100 µg) to every variant but an oracle, hiding what the gyro compensation buys; so there
  is no accelerometer oracle.

Optional study table (validated by the recipe's ``check``)::

    [navigation]
    compensators = ["LS cubic T"]     # the compensators the IMU navigates with (default: all);
                                      # each is fitted twice more (the drawn units)
    retune = true                     # false: a model whose fit tunes its hyper-parameters by an
                                      # optimiser (pso_svr, hho_rvr) is refitted on each drawn
                                      # unit's train windows at the study unit's tuned point and
                                      # inputs, instead of searching again (the search is most of
                                      # such a fit's time)
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from rlgsim.lab.studies.fitting import Fitted, fit, predict
from rlgsim.lab.studies.runs import RunSeries, random_state_for, read_run, simulated_dataset, stack
from rlgsim.lab.study import Study
from rlgsim.sim.config import check_known_keys, get_bool, get_list, get_table

#: unit-index step between the axes of one study unit's IMU (axis j of unit u is unit
#: u + j·stride), far above any Monte Carlo campaign's unit count, so no two IMUs share a gyro
AXIS_UNIT_STRIDE = 1 << 20
#: body axis (0 x, 1 y, 2 z) of the study's unit, then of the two drawn units
MOUNTS = (1, 0, 2)
NAV_KEYS = ("compensators", "retune")


@dataclass(frozen=True)
class NavPlan:
    """The ``[navigation]`` table: the compensators navigated and whether tuned models search
    again on the drawn units."""

    compensators: tuple[str, ...]
    retune: bool = True


def parse_navigation(study: Study, names: list[str]) -> NavPlan:
    """The study's ``[navigation]`` table (module docstring); ``names`` the study's
    compensators. A bad key or name is a one-line
    :class:`~rlgsim.ground.errors.UserInputError`."""
    ctx = study.ctx()
    table = get_table(study.tables, "navigation", ctx, {})
    nctx = ctx.child("navigation")
    check_known_keys(table, NAV_KEYS, nctx)
    chosen = get_list(table, "compensators", nctx, list(names))
    for i, name in enumerate(chosen):
        if not isinstance(name, str) or name not in names:
            raise nctx.error("compensators", f"entry {i + 1} {name!r} is not a compensator of "
                                             f"this study; allowed: {', '.join(names)}")
    if len(set(chosen)) != len(chosen):
        raise nctx.error("compensators", "a compensator is named twice")
    return NavPlan(tuple(chosen), get_bool(table, "retune", nctx, True))


def axis_unit(unit: int, j: int) -> int:
    """The Monte Carlo unit index of axis ``j`` of study unit ``unit`` (j = 0: the unit)."""
    return int(unit) + j * AXIS_UNIT_STRIDE


def unit_series(specs, runs: dict, features, unit_id: int) -> dict[tuple, RunSeries] | None:
    """The window series of ``specs`` for drawn unit ``unit_id``: the study unit's scenarios
    (``runs``: RunSpec.key → LoadedRun) with the other unit index, simulated next to the study
    unit's datasets (or reused). None when a run is a recording (no scenario to draw from)."""
    out: dict[tuple, RunSeries] = {}
    for spec in specs:
        if spec.key in out:
            continue
        loaded = runs[spec.key]
        if loaded.scenario is None:
            return None
        scenario = dataclasses.replace(loaded.scenario, unit=unit_id)
        path = loaded.series.path.parent / f"{spec.label}-unit{unit_id}.h5"
        simulated_dataset(scenario, path, progress=False)
        out[spec.key] = read_run(path, features, spec.label, spec.ctx, spec.skip_s)
    return out


def _refit_at_tuned_point(f: Fitted, X, y: np.ndarray) -> Fitted:
    """``f``'s model refitted on (X, y) at its tuned point (module docstring, ``retune``)."""
    from sklearn.base import clone
    t0 = time.perf_counter()
    model = copy.copy(f.model)
    Xi = X.select(f.spec.inputs)
    model.estimator_ = clone(f.model.estimator_).fit(np.asarray(Xi, dtype=float), y)
    return Fitted(f.spec, model, time.perf_counter() - t0, dict(f.hyper), Xi)


def axis_predictions(specs, primary: dict[str, Fitted], train: list[RunSeries],
                     test: RunSeries, random_state: int, retune: bool,
                     prepare: Callable | None = None) -> dict[str, np.ndarray]:
    """Each compensator of ``specs`` fitted on one drawn unit's train windows, predicting its
    test windows [°/h]. ``prepare(spec, X, y) -> spec`` is the recipe's input selection."""
    X, y = stack(train)
    out: dict[str, np.ndarray] = {}
    tuned: dict = {}
    for spec in specs:
        f0 = primary[spec.name]
        if not retune and hasattr(f0.model, "best_params_") and hasattr(f0.model, "estimator_"):
            f = _refit_at_tuned_point(f0, X, y)
        else:
            f = fit(prepare(spec, X, y) if prepare else spec, X, y, random_state, tuned)
        out[spec.name] = predict(f, test)
    return out


def window_predictor(axes: list[tuple[np.ndarray, np.ndarray, int]], window_s: float
                     ) -> Callable[[np.ndarray], np.ndarray]:
    """f(t) → (m, 3) [rad/s]: per body axis, the prediction [°/h] of the window holding t
    (``axes``: window end times [s], predictions, body axis); 0 outside the windows."""
    from rlgsim.ground.units import DEG, HOUR
    prepared = [(np.asarray(e, float), np.asarray(p, float) * DEG / HOUR, m) for e, p, m in axes]

    def f(t: np.ndarray) -> np.ndarray:
        out = np.zeros((t.size, 3))
        for ends, vals, mount in prepared:
            j = np.searchsorted(ends, t, side="left")
            jj = np.minimum(j, ends.size - 1)
            ok = (j < ends.size) & (t > ends[jj] - window_s) & np.isfinite(vals[jj])
            out[:, mount] += np.where(ok, vals[jj], 0.0)
        return out
    return f


@dataclass
class ImuRun:
    """One study unit's experiment as the IMU sees it: the runs (RunSpec.key → LoadedRun), the
    train specs, the navigated test spec, the study's fits and their predictions on that test
    run (name → ŷ [°/h])."""

    runs: dict
    train: tuple
    test: Any
    fitted: list[Fitted]
    predictions: dict[str, np.ndarray]


def imu_navigation(study: Study, config, exp: ImuRun, *, unit: int,
                   prepare: Callable | None = None, note: str = "") -> tuple[Any, str] | None:
    """The navigation of the three-gyro IMU (module docstring) on ``exp``'s test run:
    (dataset of :func:`rlgsim.lab.navigation.navigate_source`, introduction), or None when a
    run is a recording or carries no truth."""
    from rlgsim.ground.units import HOUR
    from rlgsim.lab.navigation import navigate_source
    from rlgsim.lab.navigation_source import gyro_units_source
    from rlgsim.lab.studies.navigation_section import STUDY_SPAN_H
    rs0 = exp.runs[exp.test.key].series
    if rs0.path.suffix != ".h5" or not np.all(np.isfinite(rs0.true_bias)):
        return None
    plan = parse_navigation(study, [c.name for c in config.compensators])
    specs = [c for c in config.compensators if c.name in plan.compensators]
    primary = {f.spec.name: f for f in exp.fitted}
    axes = {name: [(rs0.time_s, exp.predictions[name], MOUNTS[0])] for name in plan.compensators}
    units = [(rs0.path, config.gyro, MOUNTS[0])]
    for j in (1, 2):
        uid = axis_unit(unit, j)
        series = unit_series(exp.train + (exp.test,), exp.runs, config, uid)
        if series is None:
            return None
        train = [series[s.key] for s in exp.train]
        test = series[exp.test.key]
        preds = axis_predictions(specs, primary, train, test, random_state_for(train[0].seed, uid),
                                 plan.retune, prepare)
        for name in plan.compensators:
            axes[name].append((test.time_s, preds[name], MOUNTS[j]))
        units.append((test.path, config.gyro, MOUNTS[j]))
    src = gyro_units_source(units)
    try:
        rest_h = (src.n - src.start) / src.rate_hz / HOUR
        span_h = min(STUDY_SPAN_H, rest_h - 0.25)
        models = {name: window_predictor(axes[name], config.window_s) for name in plan.compensators}
        ds = navigate_source(src, models=models, span_s=span_h * HOUR)
    finally:
        src.close()
    ds.attrs["compensation"] = ("each unit's own compensator (trained on its own train runs) "
                                "subtracted from its gyro")
    return ds, intro(plan, unit, exp.test.label, span_h, note)


def intro(plan: NavPlan, unit: int, test_label: str, span_h: float, note: str = "") -> str:
    """The navigation section's introduction for the three-gyro IMU (module docstring)."""
    u1, u2 = axis_unit(unit, 1), axis_unit(unit, 2)
    names = ", ".join(plan.compensators) if plan.compensators else "none"
    tuned = ("" if plan.retune else " A model whose fit tunes its hyper-parameters by an "
             "optimiser is refitted on each drawn unit's train windows at the study unit's tuned "
             "point and inputs (no second search).")
    return (f"The device has one gyro, so it navigates an IMU of three such gyros: this study's "
            f"unit on body y (North), and two more units drawn from the same preset (Monte Carlo "
            f"units {u1} and {u2}: another drawn device, its own run-to-run draws and noise, "
            f"the same chamber programme) on x (East) and z (up). Each unit's gyro error (its "
            f"pulses through the nominal weight minus the true increment along its input axis) "
            f"rides on the exact increments of the run's motion on its axis. Compensated variants "
            f"({names}): the same method trained per axis, each unit's model fitted on that "
            f"unit's own train runs and subtracted from its own test run {test_label}.{tuned} "
            f"Ideal accelerometers: the compensators model the gyro bias only, and an "
            f"accelerometer's temperature law would add one Schuler-bounded error (bias·R/g, "
            f"about 0.64 km per 100 µg) to every variant, hiding what the gyro compensation "
            f"buys; so no accelerometer oracle. {span_h:g} h after the alignment. "
            f"{note}").rstrip()
