"""The study-file tables that the single-gyro recipes share: run lists, ``[data]``,
``[features]`` and ``[metrics]``, validated before anything is simulated.

Used by :mod:`rlgsim.lab.studies.bias_compensation`, :mod:`rlgsim.lab.studies.environments`
and :mod:`rlgsim.lab.studies.gradient_selection`; the ``[[compensator]]`` tables are in
:mod:`rlgsim.lab.studies.compensators`. Study-file pieces parsed here::

    train = ["paper001_train"]        # scenario names or paths (relative to the study file), or
    test = [{scenario = "demo_cycle", seed = 7, skip_h = 1}]   # tables: seed replaces the
                                      # scenario's noise seed; skip_h drops the first hours;
                                      # run_seed replaces its run_seed (another day: the
                                      # run-to-run draws of sim/run/run_to_run.py)
    [data]
    window_s = 100                    # averaging window [s]
    gyro = "z"                        # gyro axis (default: the device's only gyro)

    [features]                        # the compensator inputs, computed per window
    temperature = "g.A"               # probe giving input "T" (window mean) and "dT/dt" (K/s)
    uhfo = true                       # input "U": the gyro's UHFO voltage [V] (window mean)
    probes = ["housing"]              # further probes as inputs named by the probe [°C]
    gradients = ["g.A", "g.B"]        # pairwise differences "g.A-g.B" [K] (paper 003)

    [metrics]
    cluster_s = 100                   # bias-stability cluster [s], a multiple of window_s
    ddof = 1                          # of the bias-stability std
"""

from __future__ import annotations

import itertools
import pathlib
from dataclasses import dataclass

from rlgsim.sim.config import (Ctx, check_known_keys, get_bool, get_float, get_int, get_list,
                               get_section, get_str)
from rlgsim.lab.study import Study, scenario_for

RUN_KEYS = ("scenario", "seed", "skip_h", "run_seed")
FEATURE_KEYS = ("temperature", "uhfo", "probes", "gradients")


@dataclass(frozen=True)
class RunSpec:
    """One run of a study: a scenario, optionally with another noise seed; windows that start
    before ``skip_s`` (from the start of the run) are dropped (paper 002's 1 h warm-up)."""

    ref: str
    seed: int | None
    ctx: Ctx
    skip_s: float = 0.0
    run_seed: int | None = None     # replaces the scenario's run_seed (None: keep it)

    @property
    def key(self) -> tuple[str, float]:
        """Identifies the loaded series: the dataset (label) and the windows kept (skip)."""
        return (self.label, self.skip_s)

    @property
    def label(self) -> str:
        stem = pathlib.Path(self.ref).name
        stem = stem[:-5] if stem.endswith(".toml") else stem
        label = stem if self.seed is None else f"{stem}-seed{self.seed}"
        return label if self.run_seed is None or self.seed is not None else \
            f"{label}-run{self.run_seed}"


@dataclass(frozen=True)
class FeatureSpec:
    """How a run becomes window series: window length, gyro axis and the inputs."""

    window_s: float
    gyro: str | None
    temperature: str | None
    uhfo: bool
    probes: tuple[str, ...]
    gradients: tuple[str, ...]

    def feature_names(self) -> list[str]:
        names = []
        if self.temperature:
            names += ["T", "dT/dt"]
        if self.uhfo:
            names.append("U")
        names += list(self.probes)
        names += [f"{a}-{b}" for a, b in itertools.combinations(self.gradients, 2)]
        return names

    def columns(self, w: dict) -> dict:
        """The input columns of a run's windows, named as :meth:`feature_names` lists them,
        from the window series ``w`` of :mod:`rlgsim.lab.windows` (``mean:<probe>`` [°C],
        ``slope:<probe>`` [K/s], ``uhfo`` [V]); gradients are differences of probe means."""
        from rlgsim.estimators.columns import Columns
        from rlgsim.estimators.features import pairwise_gradients
        cols = {}
        if self.temperature:
            cols["T"] = w[f"mean:{self.temperature}"]
            cols["dT/dt"] = w[f"slope:{self.temperature}"]
        if self.uhfo:
            cols["U"] = w["uhfo"]
        for name in self.probes:
            cols[name] = w[f"mean:{name}"]
        if self.gradients:
            cols.update(pairwise_gradients(Columns({g: w[f"mean:{g}"]
                                                    for g in self.gradients})).items())
        return cols


def parse_runs(table: dict, key: str, ctx: Ctx) -> tuple[RunSpec, ...]:
    items = get_list(table, key, ctx, min_len=1)
    out = []
    for i, item in enumerate(items):
        ictx = ctx.child(key).item(i)
        if isinstance(item, str):
            if not item.strip():
                raise ctx.error(f"{key}[{i}]", "expected a scenario name or path, got an "
                                               "empty string")
            out.append(RunSpec(item, None, ictx))
        elif isinstance(item, dict):
            check_known_keys(item, RUN_KEYS, ictx)
            out.append(RunSpec(get_str(item, "scenario", ictx),
                               get_int(item, "seed", ictx, None, min=0, max=2**63 - 1), ictx,
                               3600.0 * get_float(item, "skip_h", ictx, 0.0, min=0.0),
                               get_int(item, "run_seed", ictx, None, min=0, max=2**63 - 1)))
        else:
            raise ctx.error(f"{key}[{i}]", f"expected a scenario name or a table "
                                           f"{{scenario = ..., seed = ..., skip_h = ..., run_seed = ...}}, "
                                           f"got {item!r}")
    labels = [r.label for r in out]
    dup = {x for x in labels if labels.count(x) > 1}
    if dup:
        raise ctx.error(key, f"run {sorted(dup)[0]!r} is listed twice")
    return tuple(out)


def str_list(table: dict, key: str, ctx: Ctx, min_len: int = 0) -> tuple[str, ...]:
    values = get_list(table, key, ctx, [], min_len=min_len)
    for v in values:
        if not isinstance(v, str) or not v:
            raise ctx.error(key, f"expected an array of non-empty strings, got {v!r}")
    if len(set(values)) != len(values):
        raise ctx.error(key, f"value {values!r} not allowed; names must be distinct")
    return tuple(values)


@dataclass(frozen=True)
class DataTable:
    """The ``[data]`` table: train and test runs (if the recipe has them there), the
    averaging window [s] and the gyro axis."""

    train: tuple[RunSpec, ...]
    test: tuple[RunSpec, ...]
    window_s: float
    gyro: str | None


def parse_data(study: Study, keys: tuple[str, ...], *, runs: bool = True) -> DataTable:
    """``[data]`` with ``keys`` allowed; with ``runs``, its train/test lists (every scenario
    must exist and parse) and the table is required, else it may be left out."""
    ctx = study.ctx()
    dtable, dctx = (get_section(study.tables, "data", ctx, keys) if runs
                    else get_section(study.tables, "data", ctx, keys, {}))
    train = parse_runs(dtable, "train", dctx) if runs else ()
    test = parse_runs(dtable, "test", dctx) if runs else ()
    check_scenarios(study, train + test)
    return DataTable(train=train, test=test,
                     window_s=get_float(dtable, "window_s", dctx, 100.0, min=0.0,
                                        min_exclusive=True),
                     gyro=get_str(dtable, "gyro", dctx, None, choices=("x", "y", "z")))


def parse_experiment(study: Study, top_keys: tuple[str, ...], data_keys: tuple[str, ...]
                     ) -> tuple[DataTable, FeatureSpec]:
    """The common head of a train/test recipe: the file's top-level keys, ``[data]`` with its
    runs, ``[features]``, and the features checked against every run's device."""
    check_known_keys(study.tables, top_keys, study.ctx())
    d = parse_data(study, data_keys)
    features = parse_features(study.tables, study.ctx(), d.window_s, d.gyro)
    check_features_on_devices(study, d.train + d.test, features)
    return d, features


def parse_metrics(data: dict, ctx: Ctx, window_s: float, keys: tuple[str, ...]
                  ) -> tuple[dict, Ctx, float, int]:
    """``[metrics]`` with ``keys`` allowed: (table, its Ctx, cluster_s [s] — a whole multiple
    of ``window_s``, default one window —, ddof of the bias-stability std, default 1)."""
    mtable, mctx = get_section(data, "metrics", ctx, keys, {})
    cluster_s = get_float(mtable, "cluster_s", mctx, window_s, min=0.0, min_exclusive=True)
    ratio = cluster_s / window_s
    if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
        raise mctx.error("cluster_s", f"value {cluster_s:g} not allowed; must be a whole "
                                      f"multiple of data.window_s = {window_s:g}")
    return mtable, mctx, cluster_s, get_int(mtable, "ddof", mctx, 1, min=0, max=1)


def parse_features(data: dict, ctx: Ctx, window_s: float, gyro: str | None) -> FeatureSpec:
    """The ``[features]`` table (``ctx``: the file's root) into a :class:`FeatureSpec`."""
    ftable, fctx = get_section(data, "features", ctx, FEATURE_KEYS, {})
    gradients = str_list(ftable, "gradients", fctx)
    if len(gradients) == 1:
        raise fctx.error("gradients", "give at least 2 probes (or none)")
    spec = FeatureSpec(window_s=window_s, gyro=gyro,
                       temperature=get_str(ftable, "temperature", fctx, None),
                       uhfo=get_bool(ftable, "uhfo", fctx, False),
                       probes=str_list(ftable, "probes", fctx), gradients=gradients)
    if not spec.feature_names():
        raise fctx.error("temperature", "no inputs: give at least one of temperature, uhfo, "
                                        "probes, gradients")
    return spec


def check_features_on_devices(study: Study, runs: tuple[RunSpec, ...], spec: FeatureSpec
                               ) -> None:
    """Before anything is simulated: the window must hold a whole number of samples and thermal
    steps of every run, and every probe the features name, the gyro axis and the UHFO must
    exist on its device (messages name the study key and list what the device has)."""
    from rlgsim.estimators.features import samples_per_window

    fctx, dctx = study.ctx("features"), study.ctx("data")
    seen: set[str] = set()
    for run in runs:
        from rlgsim.lab.recordings import recording_path
        rec = recording_path(run.ref, study.base_dir, str(study.source))
        if rec is not None:                       # a recording (docs/recordings.md)
            from rlgsim.lab.studies.recording_runs import check_recording_run
            check_recording_run(study, rec, spec)
            continue
        scenario = scenario_for(study, run.ref, ctx=run.ctx)
        acq = scenario.acquisition
        for rate in (acq.sample_rate_hz, 1.0 / acq.thermal_step_s):
            try:
                samples_per_window(rate, spec.window_s)
            except ValueError as exc:
                raise dctx.error("window_s", f"{exc} (scenario {scenario.name!r})") from None
        device = scenario.device
        if device.name in seen:
            continue
        seen.add(device.name)
        probes = tuple(device.thermal.probes.names)
        for key, names in (("temperature", (spec.temperature,) if spec.temperature else ()),
                           ("probes", spec.probes), ("gradients", spec.gradients)):
            for n in names:
                if n not in probes:
                    raise fctx.error(key, f"unknown probe {n!r}; device {device.name!r} has "
                                          f"{', '.join(probes) or 'no probes'}")
        gyro = device.parts.get("gyro")
        axes = tuple(getattr(gyro, "axes", ()) or ())
        if spec.gyro and spec.gyro not in axes:
            raise dctx.error("gyro", f"value {spec.gyro!r} not allowed; device {device.name!r} "
                                     f"has gyro axes {', '.join(axes) or '(none)'}")
        if not spec.gyro and len(axes) > 1:
            raise dctx.error("gyro", f"missing: device {device.name!r} has several gyros "
                                     f"({', '.join(axes)}); say which one")
        if spec.uhfo and device.parts.get("uhfo") is None:
            raise fctx.error("uhfo", f"device {device.name!r} logs no UHFO")


#: The recipes whose train/test runs may be recordings (docs/recordings.md): they read only
#: window series (:mod:`rlgsim.lab.studies.recording_runs`). paper000_system needs a simulated
#: turntable campaign and refuses a recording in its own check.
RECORDING_RECIPES = ("bias_compensation", "gradient_selection", "environments")


def check_scenarios(study: Study, runs: tuple[RunSpec, ...]) -> None:
    """Every run's scenario must exist and parse (message names the study key); a recording
    (docs/recordings.md) is a run of the recipes in :data:`RECORDING_RECIPES` only."""
    from rlgsim.lab.recordings import recording_path
    for spec in runs:
        if recording_path(spec.ref, study.base_dir, str(study.source)) is not None:
            if study.recipe not in RECORDING_RECIPES:
                raise spec.ctx.error("", f"run {spec.ref!r} is a recording; recordings are runs "
                                         f"of the {', '.join(RECORDING_RECIPES)} recipes, not "
                                         f"of {study.recipe}")
            continue
        scenario_for(study, spec.ref, ctx=spec.ctx)
