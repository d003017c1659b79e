"""Single-gyro study building blocks shared by the recipes of papers 001-003.

A run is one simulated dataset of a single-gyro device; this module turns it into the window
series the papers model, fits compensators on train runs and scores them on test runs. The
recipes (:mod:`rlgsim.sim.studies.bias_compensation`, :mod:`rlgsim.sim.studies.environments`,
:mod:`rlgsim.sim.studies.gradient_selection`) differ in how they group runs and what tables they
re-create; the series, the fitting and the scores are the same and live here.

Study-file pieces parsed here::

    train = ["paper001_train"]        # scenario names or paths (relative to the study file), or
    test = [{scenario = "demo_cycle", seed = 7, skip_h = 1}]   # tables: seed replaces the
                                      # scenario's noise seed; skip_h drops the first hours
    [features]                        # the compensator inputs, computed per window
    temperature = "g.A"               # probe giving input "T" (window mean) and "dT/dt" (K/s)
    uhfo = true                       # input "U": the gyro's UHFO voltage [V] (window mean)
    probes = ["housing"]              # further probes as inputs named by the probe [°C]
    gradients = ["g.A", "g.B"]        # pairwise differences "g.A-g.B" [K] (paper 003)

    [[compensator]]
    name = "LS cubic T"               # unique label in the report
    kind = "polynomial"               # see KINDS
    inputs = ["T"]                    # feature names
    params = { degree = 3 }           # estimator constructor keywords

How the series are built (paper 001 §3 and §4.1): the gyro's rate is its pulse count per window
divided by the nominal scale factor (truth group ``gyro.k0``) and the window length; the
bias is that rate minus the Earth-rate projection on the gyro axis (the table's known
input rate, ``truth/dtheta_step``: Ω·sin L for an up-pointing gyro on a static mount), in °/h.
Inputs are window means of the probe readings and the logged UHFO, and the least-squares slope
of the temperature in each window (:mod:`rlgsim.estimators.features`). Windows in which the device was
not powered over the whole window, or that start before a run's ``skip_h``, are dropped. The
truth series is the window mean of the true bias ``truth/gyro_bias`` (what the simulator added
to the rate), and ``truth/gyro_bias_random`` its flicker + random-walk part, which no
temperature model can predict.

Scores of one prediction ŷ on a test run (:func:`scores`, all in °/h unless stated):

* ``stability_before`` / ``stability_after``: bias stability (std of ``cluster_s`` means,
  ``ddof``) of the baseline and of the compensated series ``y − ŷ``;
  ``improvement_pct`` = 100·(before − after)/before (paper 001 Tables 2-5, paper 003 Tables
  4-5); ``improvement_factor`` = before/after (paper 002 Table 1);
* ``rmse_true``, ``mae_true``, ``r2_true``: the predicted bias ``ŷ`` against the true bias
  ``b`` (window means); ``b`` excludes the constant the output adds through the scale-factor
  error and misalignment times the Earth rate, which the compensators fold into their constant;
* ``resid_std_true`` = std(ŷ − b): what is left of the true bias after compensation, offset-free
  (the bias stability a noise-free gyro would show after compensation);
* ``law_resid_std`` = std(ŷ − (b − r)), r the random part: the error of the learnt temperature
  law alone.

The oracle ``ŷ = b − r`` (:data:`ORACLE`) is the best any input-driven model can do; its
``stability_after`` is the floor the others approach.
"""

from __future__ import annotations

import dataclasses
import importlib
import itertools
import math
import pathlib
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.sim.config import (Ctx, check_known_keys, get_bool, get_float, get_int, get_list, get_section,
                        get_str, get_table)
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.study import Study, scenario_for

RUN_KEYS = ("scenario", "seed", "skip_h")
FEATURE_KEYS = ("temperature", "uhfo", "probes", "gradients")
COMPENSATOR_KEYS = ("name", "kind", "inputs", "params", "table", "published", "estimator")
CUSTOM = "custom"   # kind of a user's own scikit-learn regressor (key ``estimator``)

#: Compensator kinds: (module, class, extra keys the recipe itself understands).
KINDS: dict[str, tuple[str, str, tuple[str, ...]]] = {
    "polynomial": ("rlgsim.estimators.polynomial", "PolynomialRegressor", ()),
    "stepwise": ("rlgsim.estimators.stepwise", "StepwiseRegressor", ()),
    "mlr_bic": ("rlgsim.estimators.mlr", "MLRBICRegressor", ()),
    "lssvm": ("rlgsim.estimators.lssvm_cv", "LSSVMRegressorCV", ()),
    "ir_lssvm": ("rlgsim.estimators.robust_lssvm", "RobustLSSVMRegressor",
                 ("gammas", "sigma2s", "tune_cv", "tune_scoring")),
    "rvr": ("rlgsim.estimators.rvr", "RVR", ()),
    "hho_rvr": ("rlgsim.estimators.tuned", "HHORVR", ()),
    "pso_svr": ("rlgsim.estimators.tuned", "PSOSVR", ()),
    "rbf": ("rlgsim.estimators.rbf_network", "RBFNetwork", ()),
    "rbf_modified": ("rlgsim.estimators.rbf_modified", "ModifiedRBFNetwork", ()),
}

#: Kinds whose fitted model prints an equation (rlgsim.estimators.term_model).
EQUATION_KINDS = ("polynomial", "stepwise", "mlr_bic")

ORACLE = "truth: temperature law"
RAW = "raw"
DEG_PER_H_PER_RAD_PER_S = 180.0 / math.pi * 3600.0

# ------------------------------------------------------------------------------ configuration
@dataclass(frozen=True)
class RunSpec:
    """One run of a study: a scenario, optionally with another noise seed; windows that start
    before ``skip_s`` (from the start of the run) are dropped (paper 002's 1 h warm-up)."""

    ref: str
    seed: int | None
    ctx: Ctx
    skip_s: float = 0.0

    @property
    def key(self) -> tuple[str, float]:
        """Identifies the loaded series: the dataset (label) and the windows kept (skip)."""
        return (self.label, self.skip_s)

    @property
    def label(self) -> str:
        stem = pathlib.Path(self.ref).name
        stem = stem[:-5] if stem.endswith(".toml") else stem
        return stem if self.seed is None else f"{stem}-seed{self.seed}"


@dataclass(frozen=True)
class CompensatorSpec:
    name: str
    kind: str
    inputs: tuple[str, ...]
    params: dict
    table: str
    published: dict
    ctx: Ctx
    estimator: str = ""                       # kind "custom": "module:Class" or "file.py:Class"
    base_dir: pathlib.Path | None = None      # where a "file.py" estimator is looked up


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

def estimator_class(kind: str):
    module, cls, _ = KINDS[kind]
    return getattr(importlib.import_module(module), cls)


def spec_class(spec: CompensatorSpec):
    """The estimator class of a compensator: a built-in kind, or the user's own."""
    if spec.kind == CUSTOM:
        return load_custom_estimator(spec.estimator, spec.base_dir, spec.ctx)
    return estimator_class(spec.kind)


def load_custom_estimator(ref: str, base_dir: pathlib.Path | None, ctx: Ctx):
    """Import a user's regressor class from ``"package.module:Class"`` (importable) or
    ``"path/to/file.py:Class"`` (relative to the study file). It must follow the scikit-learn
    regressor contract: constructible without arguments, ``get_params``, ``fit(X, y)`` and
    ``predict(X)``; X is a 2-D float array of the inputs in the order the study lists them
    (an :class:`rlgsim.estimators.columns.Columns`, which also carries their names)."""
    import importlib.util
    import sys

    where, sep, name = ref.rpartition(":")
    if not sep or not where or not name.isidentifier():
        raise ctx.error("estimator", f"value {ref!r} not allowed; give 'package.module:Class' "
                                     "or 'file.py:Class' (relative to the study file)")
    try:
        if where.endswith(".py"):
            path = pathlib.Path(where)
            if not path.is_absolute() and base_dir is not None:
                path = base_dir / path
            if not path.is_file():
                raise ctx.error("estimator", f"file {str(path)!r} not found (value {ref!r})")
            mod_name = f"rlgsim_custom_{abs(hash(str(path.resolve())))}"
            module = sys.modules.get(mod_name)
            if module is None:
                spec = importlib.util.spec_from_file_location(mod_name, path)
                module = importlib.util.module_from_spec(spec)
                sys.modules[mod_name] = module
                try:
                    spec.loader.exec_module(module)
                except BaseException:
                    del sys.modules[mod_name]
                    raise
        else:
            module = importlib.import_module(where)
    except UserInputError:
        raise
    except Exception as exc:          # the user's module failed to import: say which and why
        raise ctx.error("estimator", f"cannot import {where!r} (value {ref!r}): "
                                     f"{type(exc).__name__}: {' '.join(str(exc).split())}"
                        ) from None
    cls = getattr(module, name, None)
    if cls is None or not isinstance(cls, type):
        raise ctx.error("estimator", f"{where!r} has no class {name!r} (value {ref!r})")
    missing = [m for m in ("fit", "predict", "get_params") if not callable(getattr(cls, m, None))]
    if missing:
        raise ctx.error("estimator", f"class {name!r} lacks {', '.join(missing)}; a compensator "
                                     "must be a scikit-learn regressor (derive from "
                                     "sklearn.base.BaseEstimator and RegressorMixin)")
    return cls


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
                               3600.0 * get_float(item, "skip_h", ictx, 0.0, min=0.0)))
        else:
            raise ctx.error(f"{key}[{i}]", f"expected a scenario name or a table "
                                           f"{{scenario = ..., seed = ..., skip_h = ...}}, "
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


def parse_compensator(item: Any, i: int, ctx: Ctx, features: list[str],
                      published_keys: tuple[str, ...], *, min_inputs: int = 1,
                      base_dir: pathlib.Path | None = None) -> CompensatorSpec:
    """One ``[[compensator]]`` table (``ctx`` names the array); ``published_keys``: what its
    ``published`` table may hold (numbers, or ``equation``: text); ``min_inputs``: 0 where the
    recipe adds inputs itself; ``base_dir``: the study file's folder (custom estimators)."""
    cctx = ctx.item(i)
    if not isinstance(item, dict):
        raise Ctx(ctx.source).error(cctx.path, f"expected a table, got {item!r}")
    check_known_keys(item, COMPENSATOR_KEYS, cctx)
    name = get_str(item, "name", cctx)
    if not name.strip() or name in (RAW, ORACLE):
        raise cctx.error("name", f"value {name!r} not allowed (empty or reserved)")
    kind = get_str(item, "kind", cctx, choices=[*KINDS, CUSTOM])
    estimator = get_str(item, "estimator", cctx, "")
    if kind == CUSTOM and not estimator:
        raise cctx.error("estimator", "missing: kind = \"custom\" needs estimator = "
                                      "'package.module:Class' or 'file.py:Class'")
    if kind != CUSTOM and estimator:
        raise cctx.error("estimator", f"only with kind = \"custom\" (this one is {kind!r})")
    inputs = str_list(item, "inputs", cctx, min_len=min_inputs)
    for x in inputs:
        if x not in features:
            raise cctx.error("inputs", f"unknown input {x!r}; the [features] table gives: "
                                       f"{', '.join(features) or '(none)'}")
    params = get_table(item, "params", cctx, {})
    spec = CompensatorSpec(name=name, kind=kind, inputs=inputs, params=params, table="",
                           published={}, ctx=cctx, estimator=estimator, base_dir=base_dir)
    cls = spec_class(spec)
    try:
        allowed = set(cls().get_params()) | set(KINDS.get(kind, ("", "", ()))[2])
    except Exception as exc:
        raise cctx.error("estimator", f"{cls.__name__}() failed: {type(exc).__name__}: "
                                      f"{' '.join(str(exc).split())} (a scikit-learn "
                                      "regressor must be constructible without arguments)"
                         ) from None
    allowed.discard("feature_names")
    check_known_keys(params, sorted(allowed), cctx.child("params"))
    published = get_table(item, "published", cctx, {})
    pctx = cctx.child("published")
    check_known_keys(published, published_keys, pctx)
    for k in published:
        if k == "equation":
            get_str(published, k, pctx)
        else:
            get_float(published, k, pctx)
    return dataclasses.replace(spec, table=get_str(item, "table", cctx, ""),
                               published=published)


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


def parse_compensators(data: dict, ctx: Ctx, features: list[str],
                       published_keys: tuple[str, ...], *, min_inputs: int = 1,
                       base_dir: pathlib.Path | None = None) -> tuple[CompensatorSpec, ...]:
    """Every ``[[compensator]]`` table (at least one; names unique)."""
    items = data.get("compensator")
    if not isinstance(items, list) or not items:
        raise ctx.error("compensator", "missing: give at least one [[compensator]] table")
    comps = tuple(parse_compensator(item, i, ctx.child("compensator"), features, published_keys,
                                    min_inputs=min_inputs, base_dir=base_dir)
                  for i, item in enumerate(items))
    names = [c.name for c in comps]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ctx.error("compensator", f"name {sorted(dup)[0]!r} is used twice")
    return comps


def check_scenarios(study: Study, runs: tuple[RunSpec, ...]) -> None:
    """Every run's scenario must exist and parse (message names the study key)."""
    for spec in runs:
        scenario_for(study, spec.ref, ctx=spec.ctx)


# ------------------------------------------------------------------------------ datasets
def _dataset_matches(path: pathlib.Path, scenario) -> bool:
    import h5py
    try:
        with h5py.File(path, "r") as f:
            a = f.attrs

            def text(key: str) -> str:
                v = a.get(key, "")
                return v.decode() if isinstance(v, bytes) else str(v)
            return (text("scenario_text") == scenario.text
                    and int(a.get("seed", -1)) == scenario.seed
                    and int(a.get("unit", -1)) == scenario.unit
                    and int(a.get("device_seed", -1)) == scenario.realisation_seed
                    and text("device_text") == scenario.device.text
                    and text("thermal_preset_text") == scenario.device.thermal.text)
    except (OSError, KeyError, ValueError, TypeError):
        return False


def dataset_for(study: Study, spec: RunSpec, workdir: pathlib.Path, *, unit: int,
                progress: bool) -> tuple[pathlib.Path, Any, bool]:
    """Simulate ``spec`` into ``workdir/data/<label>.h5`` unless a matching file is there.
    Returns (path, scenario, reused)."""
    from rlgsim.sim.simulate import simulate
    scenario = scenario_for(study, spec.ref, unit=unit, ctx=spec.ctx)
    if spec.seed is not None:
        scenario = dataclasses.replace(scenario, seed=spec.seed)
    folder = workdir / "data"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{spec.label}.h5"
    if path.is_file() and _dataset_matches(path, scenario):
        return path, scenario, True
    simulate(scenario, path, progress=progress)
    return path, scenario, False


def _strings(values) -> list[str]:
    return [v.decode() if isinstance(v, bytes) else str(v) for v in values]


@dataclass
class RunSeries:
    """The 100 s window series of one run (°/h for rates, °C, K/s, V)."""

    label: str
    path: pathlib.Path
    seed: int
    device_seed: int
    time_s: np.ndarray          # window end times
    y: np.ndarray               # measured bias: output − Earth projection [°/h]
    true_bias: np.ndarray       # b: window mean of truth/gyro_bias [°/h]
    true_random: np.ndarray     # r: its flicker + random-walk part [°/h]
    X: Any                      # rlgsim.estimators.columns.Columns of the inputs
    earth_deg_per_h: float
    coefficients: dict[str, float]


#: Samples read at a time from a dataset (memory stays bounded whatever the run's duration).
READ_BLOCK_SAMPLES = 1 << 22


def read_run(path: pathlib.Path, config: FeatureSpec, label: str, ctx: Ctx,
             skip_s: float = 0.0) -> RunSeries:
    """Build the window series of one dataset (see the module docstring); windows that start
    before ``skip_s`` are dropped. The dataset is read a block of whole windows at a time
    (:data:`READ_BLOCK_SAMPLES`), so memory does not grow with the run's duration; every window
    is computed from its own samples only, so the result does not depend on the block size."""
    import h5py

    from rlgsim.estimators.columns import Columns
    from rlgsim.estimators.features import pairwise_gradients, samples_per_window

    W = config.window_s
    with h5py.File(path, "r") as f:
        dctx, fctx = Ctx(ctx.source, "data"), Ctx(ctx.source, "features")
        gyros = _strings(f["imu/gyro"][:])
        axis = config.gyro or (gyros[0] if len(gyros) == 1 else None)
        if config.gyro and config.gyro not in gyros:
            raise dctx.error("gyro", f"value {config.gyro!r} not allowed; the device's gyro "
                                     f"axes are {', '.join(gyros)}")
        if axis is None:
            raise dctx.error("gyro", f"missing: the device has several gyros "
                                     f"({', '.join(gyros)}); say which one")
        if config.uhfo and "imu/uhfo" not in f:
            raise fctx.error("uhfo", "the device logs no UHFO")
        rate = float(f["imu"].attrs["sample_rate_hz"])
        step = float(f.attrs["thermal_step_s"])
        try:
            m_s = samples_per_window(rate, W)
            m_t = samples_per_window(1.0 / step, W)
        except ValueError as exc:
            raise dctx.error("window_s", str(exc)) from None
        probes = _strings(f["probes/probe"][:])
        wanted = {}                      # probe → column of probes/temperature
        for key, names in (("temperature", (config.temperature,) if config.temperature else ()),
                           ("probes", config.probes), ("gradients", config.gradients)):
            for name in names:
                if name not in probes:
                    raise fctx.error(key, f"unknown probe {name!r}; the device's probes are "
                                          f"{', '.join(probes)}")
                wanted[name] = probes.index(name)
        coeff = dict(zip(_strings(f["truth/coefficient"][:]),
                         map(float, f["truth/coefficient_value"][:])))
        n_win = min(f["imu/gyro_pulses"].shape[0] // m_s, f["thermal/time"].shape[0] // m_t)
        where = _Where(gyro=gyros.index(axis), body=_strings(f["truth/body"][:]).index(axis),
                       probes=wanted, uhfo=config.uhfo, temperature=config.temperature)
        per_block = max(1, READ_BLOCK_SAMPLES // max(m_s, m_t))
        if n_win == 0:
            raise dctx.error("window_s", f"run {label!r} is shorter than one {W:g} s window")
        blocks = [_window_block(f, i, min(n_win, i + per_block), m_s, m_t, step, W, where)
                  for i in range(0, n_win, per_block)]
        seed = int(f.attrs["seed"])
        device_seed = int(f.attrs.get("device_seed", seed))
    w = {k: np.concatenate([blk[k] for blk in blocks]) for k in blocks[0]}

    k0 = coeff[f"gyro.k0[{axis}]"]
    earth = w["dtheta"] / W                                                    # rad/s
    y = (w["counts"] / (k0 * W) - earth) * DEG_PER_H_PER_RAD_PER_S
    cols: dict[str, np.ndarray] = {}
    if config.temperature:
        cols["T"] = w[f"mean:{config.temperature}"]
        cols["dT/dt"] = w["slope"]
    if config.uhfo:
        cols["U"] = w["uhfo"]
    for name in config.probes:
        cols[name] = w[f"mean:{name}"]
    if config.gradients:
        cols.update(pairwise_gradients(Columns({g: w[f"mean:{g}"]
                                                for g in config.gradients})).items())
    keep = w["power"] & (np.arange(n_win) * W >= skip_s - 1e-9)
    return RunSeries(label=label, path=path, seed=seed, device_seed=device_seed,
                     time_s=((np.arange(n_win) + 1) * W)[keep], y=y[keep],
                     true_bias=w["b"][keep] * DEG_PER_H_PER_RAD_PER_S,
                     true_random=w["r"][keep] * DEG_PER_H_PER_RAD_PER_S,
                     X=Columns({k: v[keep] for k, v in cols.items()}),
                     earth_deg_per_h=float(np.mean(earth) * DEG_PER_H_PER_RAD_PER_S),
                     coefficients=coeff)


@dataclass(frozen=True)
class _Where:
    """Which columns of a dataset a run's series needs."""

    gyro: int                       # column of the gyro in imu/* and truth/gyro_*
    body: int                       # column of its axis in truth/dtheta_step
    probes: dict[str, int]          # probe name → column of probes/temperature
    uhfo: bool
    temperature: str | None         # the probe whose window slope is dT/dt


def _window_block(f, i: int, j: int, m_s: int, m_t: int, step: float, W: float,
                  where: _Where) -> dict[str, np.ndarray]:
    """Per-window sums and means of windows ``i … j−1`` (rad for dtheta, rad/s for b and r,
    °C, K/s, V): only these windows' samples are read."""
    from rlgsim.estimators.features import temperature_rate, window_average
    n = j - i
    t0, t1 = i * m_t, j * m_t
    thermal_rate = 1.0 / step
    out = {"counts": f["imu/gyro_pulses"][i * m_s: j * m_s, where.gyro].astype(np.int64)
           .reshape(n, m_s).sum(axis=1),
           "dtheta": f["truth/dtheta_step"][t0:t1, where.body].reshape(n, m_t).sum(axis=1),
           "b": window_average(f["truth/gyro_bias"][t0:t1, where.gyro], thermal_rate, W),
           "r": window_average(f["truth/gyro_bias_random"][t0:t1, where.gyro], thermal_rate, W),
           "power": f["thermal/power_on"][t0:t1].reshape(n, m_t).min(axis=1) > 0}
    if where.probes:
        cols = sorted(set(where.probes.values()))
        temps = f["probes/temperature"][t0:t1, cols].astype(np.float64)
        for name, c in where.probes.items():
            out[f"mean:{name}"] = window_average(temps[:, cols.index(c)], thermal_rate, W)
        if where.temperature:
            T = temps[:, cols.index(where.probes[where.temperature])]
            out["slope"] = temperature_rate(T, thermal_rate, W)
    if where.uhfo:
        out["uhfo"] = window_average(f["imu/uhfo"][t0:t1, where.gyro].astype(np.float64),
                                     thermal_rate, W)
    return out


@dataclass
class LoadedRun:
    """A run's window series, its scenario and whether its dataset was reused."""

    series: RunSeries
    scenario: Any
    reused: bool


def load_runs(study: Study, specs: tuple[RunSpec, ...], features: FeatureSpec,
              workdir: pathlib.Path, *, unit: int, progress: bool
              ) -> dict[tuple[str, float], LoadedRun]:
    """Simulate (or reuse) and read every run once, keyed by :attr:`RunSpec.key`."""
    out: dict[tuple[str, float], LoadedRun] = {}
    for spec in specs:
        if spec.key in out:
            continue
        path, scenario, reused = dataset_for(study, spec, workdir, unit=unit, progress=progress)
        out[spec.key] = LoadedRun(read_run(path, features, spec.label, spec.ctx, spec.skip_s),
                                  scenario, reused)
    return out


@dataclass
class Experiment:
    """The loaded runs of a train/test experiment and its stacked train windows."""

    runs: dict[tuple[str, float], LoadedRun]
    train: list[RunSeries]
    X: Any                      # the train windows' inputs (Columns), runs stacked
    y: np.ndarray               # their measured bias [°/h]
    random_state: int           # the estimators' (from the first train run's seed and unit)
    t_data: float               # wall time of simulating/reading the runs [s]


def load_experiment(study: Study, train: tuple[RunSpec, ...], test: tuple[RunSpec, ...],
                    features: FeatureSpec, workdir: pathlib.Path, *, unit: int,
                    progress: bool) -> Experiment:
    """Simulate (or reuse) and read the train and test runs; stack the train windows."""
    import time
    t0 = time.perf_counter()
    runs = load_runs(study, train + test, features, pathlib.Path(workdir), unit=unit,
                     progress=progress)
    t_data = time.perf_counter() - t0
    series = [runs[s.key].series for s in train]
    X, y = stack(series)
    return Experiment(runs=runs, train=series, X=X, y=y, t_data=t_data,
                      random_state=random_state_for(runs[train[0].key].scenario.seed, unit))


# ------------------------------------------------------------------------------ fitting
def make_estimator(spec: CompensatorSpec, random_state: int):
    """The estimator of ``spec`` (ir_lssvm: its (gamma, sigma2) are tuned in :func:`fit`)."""
    cls = spec_class(spec)
    extra = KINDS[spec.kind][2] if spec.kind in KINDS else ()
    params = {k: v for k, v in spec.params.items() if k not in extra}
    if "random_state" in cls().get_params() and "random_state" not in params:
        params["random_state"] = random_state
    return cls(**params)


@dataclass
class Fitted:
    spec: CompensatorSpec
    model: Any
    fit_s: float
    hyper: dict[str, float]


def fit(spec: CompensatorSpec, X, y: np.ndarray, random_state: int,
        tuned: dict | None = None) -> Fitted:
    """Fit ``spec`` on the train windows. A ValueError from the estimator (a bad parameter
    value in the study file) becomes a UserInputError naming the compensator. ``tuned`` caches
    the (gamma, sigma2) of IR-LSSVM's unweighted tuning per inputs and tuning settings, so the
    four weight functions of one input set share one cross-validation (as in paper 001 §2.3,
    where the weights are applied to the one tuned LS-SVM)."""
    import warnings

    from sklearn.exceptions import ConvergenceWarning
    t0 = time.perf_counter()
    Xi = X.select(spec.inputs)
    hyper: dict[str, float] = {}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            model = make_estimator(spec, random_state)
            if spec.kind == "ir_lssvm" and not ("gamma" in spec.params and "sigma2" in spec.params):
                from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV
                p = spec.params
                kw = {k: p[k] for k in ("gammas", "sigma2s") if k in p}
                key = (spec.inputs, repr(sorted(kw.items())), repr(p.get("tune_cv", 10)),
                       repr(p.get("tune_scoring", "mse")))
                if tuned is None or key not in tuned:
                    tuner = LSSVMRegressorCV(cv=p.get("tune_cv", 10),
                                             scoring=p.get("tune_scoring", "mse"),
                                             random_state=random_state, **kw).fit(Xi, y)
                    pair = (tuner.gamma_, tuner.sigma2_)
                    if tuned is not None:
                        tuned[key] = pair
                else:
                    pair = tuned[key]
                model.set_params(gamma=pair[0], sigma2=pair[1])
            model.fit(Xi, y)
    except Exception as exc:        # built-in kinds: a bad value; custom: the user's code
        if spec.kind != CUSTOM and not isinstance(exc, (ValueError, TypeError)):
            raise
        what = "" if spec.kind != CUSTOM else f"{type(exc).__name__}: "
        raise spec.ctx.error("params", f"compensator {spec.name!r} ({spec.kind}) could not be "
                                       f"fitted: {what}{' '.join(str(exc).split())}") from None
    for attr, key in (("gamma_", "c"), ("sigma2_", "sigma2"), ("weight_param_", "weight_param"),
                      ("width_", "width"), ("n_centers_", "centres")):
        v = getattr(model, attr, None)
        if isinstance(v, (int, float, np.floating, np.integer)) and v is not None:
            hyper[key] = float(v)
    if spec.kind == "ir_lssvm":
        hyper["c"], hyper["sigma2"] = float(model.gamma), float(model.sigma2)
    if hasattr(model, "best_params_"):
        hyper.update({k: float(v) for k, v in model.best_params_.items()})
    return Fitted(spec, model, time.perf_counter() - t0, hyper)


def fit_all(specs, X, y: np.ndarray, random_state: int, *, progress: bool,
            desc: str = "fitting", prepare=None) -> list[Fitted]:
    """Fit every compensator on the train windows (a progress bar unless ``progress`` is
    false). ``prepare(spec) -> spec`` may change a spec first (e.g. add selected inputs); the
    IR-LSSVM tuning is shared between the specs of one call (see :func:`fit`)."""
    from tqdm import tqdm
    fitted: list[Fitted] = []
    tuned: dict = {}
    bar = tqdm(specs, desc=desc, unit="model", disable=not progress, leave=False)
    for spec in bar:
        bar.set_postfix_str(spec.name[:30])
        fitted.append(fit(prepare(spec) if prepare else spec, X, y, random_state, tuned))
    bar.close()
    return fitted


def predict(f: Fitted, rs: RunSeries) -> np.ndarray:
    """A fitted compensator's prediction ŷ on a run's windows [°/h]."""
    return np.asarray(f.model.predict(rs.X.select(f.spec.inputs)), dtype=float)


def score_run(rs: RunSeries, fitted: list[Fitted], y_train: np.ndarray, features: FeatureSpec,
              cluster_s: float, ddof: int, baseline: str = RAW
              ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, float]]]:
    """Predictions and :func:`scores` on one test run of every compensator and of the
    references: ``raw`` (ŷ = the train mean) and the oracle (ŷ = b − r). "Before" is the raw
    bias stability, or that left by the compensator named ``baseline``."""
    from rlgsim.estimators.metrics import bias_stability
    rate = 1.0 / features.window_s
    preds = {RAW: np.full_like(rs.y, np.mean(y_train)),
             **{f.spec.name: predict(f, rs) for f in fitted},
             ORACLE: rs.true_bias - rs.true_random}
    before = bias_stability(rs.y - (0.0 if baseline == RAW else preds[baseline]), rate,
                            cluster_s, ddof)
    return preds, {name: scores(rs.y, p, rs.true_bias, rs.true_random, features.window_s,
                                cluster_s, ddof, before) for name, p in preds.items()}


# ------------------------------------------------------------------------------ scoring
def scores(y: np.ndarray, y_hat: np.ndarray, b: np.ndarray, r: np.ndarray, window_s: float,
           cluster_s: float, ddof: int, before: float) -> dict[str, float]:
    """Paper-style and truth-based scores of one prediction (definitions: module docstring)."""
    from rlgsim.estimators import metrics as M
    rate = 1.0 / window_s
    after = M.bias_stability(y - y_hat, rate, cluster_s, ddof)
    out = {"stability_before": before, "stability_after": after,
           "improvement_pct": M.improvement_percent(before, after),
           "improvement_factor": before / after if after > 0 else float("inf"),
           "rmse_true": M.rmse(b, y_hat), "mae_true": M.mae(b, y_hat),
           "r2_true": M.r2(b, y_hat),
           "resid_std_true": float(np.std(y_hat - b, ddof=ddof)),
           "law_resid_std": float(np.std(y_hat - (b - r), ddof=ddof))}
    return out




def worth_showing(name: str) -> bool:
    """Drawn device coefficients shown beside a unit's scores: non-zero bias/UHFO law terms."""
    return name.startswith(("gyro.bias.", "uhfo.", "noise.gyro"))


def fmt(x: float | None) -> float | None:
    """A table cell: ``None`` (shown as —) for a missing or non-finite number."""
    return None if x is None or not np.isfinite(x) else float(x)


def stack(runs: list[RunSeries]):
    """(X, y) of several runs' windows stacked in run order (the train set)."""
    from rlgsim.estimators.columns import Columns
    X = Columns({n: np.concatenate([r.X[n] for r in runs]) for n in runs[0].X.names})
    return X, np.concatenate([r.y for r in runs])


def random_state_for(seed: int, unit: int) -> int:
    """The estimators' random_state for a study run: from the first train run's noise seed and
    the Monte Carlo unit."""
    return int((seed * 1_000_003 + unit) % (2**32 - 1))


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
    from rlgsim.sim.report import Table, slug
    rep.heading("Truth-based scores (what no paper could measure)", 2)
    for label, table in per_test.items():
        recs = [{"compensator": name, **{k: fmt(v) for k, v in s.items()}}
                for name, s in table.items()]
        rep.table(Table.from_records(f"All scores, test run {label}", recs,
                                     csv_name=f"scores_{slug(label)}.csv",
                                     note="°/h except r2_true (1), improvement_pct (%) and "
                                          "improvement_factor (1)."))
