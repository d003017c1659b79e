"""The runs of a study: their datasets (simulated, or reused when the one dataset fingerprint
matches) and the window series read from them. Every study reads its datasets here, through the
one dataset reader :func:`rlgsim.ground.dataset_format.open_dataset` (the one derived dataset a
study makes, paper 000's compensated pulses, is written by
:func:`rlgsim.sim.writer.derived.rewrite_pulses`).

A dataset under ``DIR/data/`` is reused when it was made from the same scenario text, device
preset text, thermal preset text, noise seed, device seed, run seed and Monte Carlo unit
(:func:`dataset_matches`, used by every recipe including ``paper000_system``); otherwise it is
simulated again.

How the series are built (paper 001 §3 and §4.1; :mod:`rlgsim.lab.windows`, the one window
builder): the gyro's rate is its pulse count per window divided by the nominal scale factor
(truth group ``gyro.k0``) and the window length; the bias is that rate minus the Earth-rate
projection on the gyro axis (the table's known input rate, ``truth/dtheta_step``: Ω·sin L for
an up-pointing gyro on a static mount), in °/h.
Inputs are window means of the probe readings and the logged UHFO, and the least-squares slope
of the temperature in each window (:mod:`rlgsim.estimators.features`). Windows in which the
device was not powered over the whole window, or that start before a run's ``skip_h``, are
dropped. The truth series is the window mean of the true bias ``truth/gyro_bias`` (what the
simulator added to the rate), and ``truth/gyro_bias_random`` its flicker + random-walk part,
which no temperature model can predict.
"""

from __future__ import annotations

import dataclasses
import pathlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.ground.dataset_format import IMU, PROBES, THERMAL, TRUTH, open_dataset
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.lab.study import Study, scenario_for
from rlgsim.lab.studies.study_tables import FeatureSpec, RunSpec
from rlgsim.lab.windows import DEG_PER_H_PER_RAD_PER_S, Where, bias_deg_per_h, dataset_windows



# ------------------------------------------------------------------------------ datasets
def dataset_matches(path: pathlib.Path, scenario) -> bool:
    """Whether the dataset at ``path`` was simulated from ``scenario``: the same scenario,
    device preset and thermal preset texts, noise seed, Monte Carlo unit and device seed (the
    dataset fingerprint every study uses to reuse a dataset)."""
    try:
        with open_dataset(path) as ds:
            a = ds.attrs

            def text(key: str) -> str:
                return str(a.get(key, ""))
            return (text("scenario_text") == scenario.text
                    and int(a.get("seed", -1)) == scenario.seed
                    and int(a.get("unit", -1)) == scenario.unit
                    and int(a.get("device_seed", -1)) == scenario.realisation_seed
                    and int(a.get("run_seed", -1)) == (-1 if scenario.run_seed is None
                                                       else scenario.run_seed)
                    and text("device_text") == scenario.device.text
                    and text("thermal_preset_text") == scenario.device.thermal.text)
    except (UserInputError, OSError, KeyError, ValueError, TypeError):
        return False


def simulated_dataset(scenario, path: pathlib.Path, *, progress: bool
                      ) -> tuple[pathlib.Path, bool]:
    """The dataset of ``scenario`` at ``path``: reused if :func:`dataset_matches`, else
    simulated (written atomically). Returns (path, reused)."""
    from rlgsim.sim.run.simulate import simulate
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_file() and dataset_matches(path, scenario):
        return path, True
    simulate(scenario, path, progress=progress)
    return path, False


def dataset_for(study: Study, spec: RunSpec, workdir: pathlib.Path, *, unit: int,
                progress: bool) -> tuple[pathlib.Path, Any, bool]:
    """Simulate ``spec`` into ``workdir/data/<label>.h5`` unless a matching file is there.
    Returns (path, scenario, reused); a recording is returned as it is, without a scenario."""
    from rlgsim.lab.recordings import recording_path
    rec = recording_path(spec.ref, study.base_dir, str(study.source))
    if rec is not None:
        return rec, None, True
    scenario = run_scenario(study, spec, unit)
    path, reused = simulated_dataset(scenario, workdir / "data" / f"{spec.label}.h5",
                                     progress=progress)
    return path, scenario, reused


def run_scenario(study: Study, spec: RunSpec, unit: int):
    """The scenario :func:`dataset_for` simulates for ``spec`` (not a recording): the study's
    scenario for the unit with the spec's seed and run seed."""
    scenario = scenario_for(study, spec.ref, unit=unit, ctx=spec.ctx)
    if spec.seed is not None:
        scenario = dataclasses.replace(scenario, seed=spec.seed)
    if spec.run_seed is not None:
        scenario = dataclasses.replace(scenario, run_seed=spec.run_seed)
    return scenario


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


def read_run(path: pathlib.Path, config: FeatureSpec, label: str, ctx: Ctx,
             skip_s: float = 0.0) -> RunSeries:
    """Build the window series of one dataset (see the module docstring); windows that start
    before ``skip_s`` are dropped. The dataset is read a block of whole windows at a time
    (:func:`rlgsim.lab.windows.dataset_windows`), so memory does not grow with the run's
    duration; every window is computed from its own samples only, so the result does not depend
    on the block size."""
    from rlgsim.estimators.columns import Columns
    from rlgsim.estimators.features import samples_per_window

    W = config.window_s
    with open_dataset(path) as ds:
        dctx, fctx = Ctx(ctx.source, "data"), Ctx(ctx.source, "features")
        gyros = ds.strings(IMU, "gyro")
        axis = config.gyro or (gyros[0] if len(gyros) == 1 else None)
        if config.gyro and config.gyro not in gyros:
            raise dctx.error("gyro", f"value {config.gyro!r} not allowed; the device's gyro "
                                     f"axes are {', '.join(gyros)}")
        if axis is None:
            raise dctx.error("gyro", f"missing: the device has several gyros "
                                     f"({', '.join(gyros)}); say which one")
        if config.uhfo and not ds.has(IMU, "uhfo"):
            raise fctx.error("uhfo", "the device logs no UHFO")
        rate = float(ds.group_attrs(IMU)["sample_rate_hz"])
        step = float(ds.attrs["thermal_step_s"])
        try:
            m_s = samples_per_window(rate, W)
            m_t = samples_per_window(1.0 / step, W)
        except ValueError as exc:
            raise dctx.error("window_s", str(exc)) from None
        probes = ds.strings(PROBES, "probe")
        wanted = {}                      # probe → column of probes/temperature
        for key, names in (("temperature", (config.temperature,) if config.temperature else ()),
                           ("probes", config.probes), ("gradients", config.gradients)):
            for name in names:
                if name not in probes:
                    raise fctx.error(key, f"unknown probe {name!r}; the device's probes are "
                                          f"{', '.join(probes)}")
                wanted[name] = probes.index(name)
        coeff = ds.coefficients()
        n_win = min(ds.length(IMU, "gyro_pulses") // m_s, ds.length(THERMAL, "time") // m_t)
        where = Where(gyro=gyros.index(axis), body=ds.strings(TRUTH, "body").index(axis),
                      probes=wanted, uhfo=config.uhfo,
                      slopes=(config.temperature,) if config.temperature else ())
        if n_win == 0:
            raise dctx.error("window_s", f"run {label!r} is shorter than one {W:g} s window")
        w = dataset_windows(ds, where, n_win, m_s, m_t, W)
        seed = int(ds.attrs["seed"])
        device_seed = int(ds.attrs.get("device_seed", seed))

    k0 = coeff[f"gyro.k0[{axis}]"]
    earth = w["dtheta"] / W                                                    # rad/s
    y = bias_deg_per_h(w["counts"] / (k0 * W), earth)
    cols = config.columns(w)
    keep = w["power"] & (np.arange(n_win) * W >= skip_s - 1e-9)
    return RunSeries(label=label, path=path, seed=seed, device_seed=device_seed,
                     time_s=((np.arange(n_win) + 1) * W)[keep], y=y[keep],
                     true_bias=w["b"][keep] * DEG_PER_H_PER_RAD_PER_S,
                     true_random=w["r"][keep] * DEG_PER_H_PER_RAD_PER_S,
                     X=Columns({k: v[keep] for k, v in cols.items()}),
                     earth_deg_per_h=float(np.mean(earth) * DEG_PER_H_PER_RAD_PER_S),
                     coefficients=coeff)


@dataclass
class LoadedRun:
    """A run's window series, its scenario and whether its dataset was reused."""

    series: RunSeries
    scenario: Any
    reused: bool


def load_runs(study: Study, specs: tuple[RunSpec, ...], features: FeatureSpec,
              workdir: pathlib.Path, *, unit: int, progress: bool, done: dict | None = None
              ) -> dict[tuple[str, float], LoadedRun]:
    """Simulate (or reuse) and read every run once, keyed by :attr:`RunSpec.key`. ``done``:
    RunSpec.key → :func:`dataset_for`'s answer for runs already simulated (or found)."""
    out: dict[tuple[str, float], LoadedRun] = {}
    for spec in specs:
        if spec.key in out:
            continue
        path, scenario, reused = (done[spec.key] if done and spec.key in done else
                                  dataset_for(study, spec, workdir, unit=unit, progress=progress))
        if scenario is None:                      # a recording: no truth, NaN truth series
            from rlgsim.lab.studies.recording_runs import recording_series
            series = RunSeries(**recording_series(path, features, spec.label, spec.ctx,
                                                  spec.skip_s))
        else:
            series = read_run(path, features, spec.label, spec.ctx, spec.skip_s)
        out[spec.key] = LoadedRun(series, scenario, reused)
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
                    progress: bool, done: dict | None = None) -> Experiment:
    """Simulate (or reuse) and read the train and test runs; stack the train windows
    (``done``: as for :func:`load_runs`)."""
    import time
    t0 = time.perf_counter()
    runs = load_runs(study, train + test, features, pathlib.Path(workdir), unit=unit,
                     progress=progress, done=done)
    t_data = time.perf_counter() - t0
    series = [runs[s.key].series for s in train]
    X, y = stack(series)
    return Experiment(runs=runs, train=series, X=X, y=y, t_data=t_data,
                      random_state=random_state_for(runs[train[0].key].series.seed, unit))


def stack(runs: list[RunSeries]):
    """(X, y) of several runs' windows stacked in run order (the train set)."""
    from rlgsim.estimators.columns import Columns
    X = Columns({n: np.concatenate([r.X[n] for r in runs]) for n in runs[0].X.names})
    return X, np.concatenate([r.y for r in runs])


def random_state_for(seed: int, unit: int) -> int:
    """The estimators' random_state for a study run: from the first train run's noise seed and
    the Monte Carlo unit."""
    return int((seed * 1_000_003 + unit) % (2**32 - 1))


def worth_showing(name: str) -> bool:
    """Drawn device coefficients shown beside a unit's scores: non-zero bias/UHFO law terms."""
    return name.startswith(("gyro.bias.", "uhfo.", "noise.gyro"))


# ------------------------------------------------------------------------------ other reads
def gyro_white_sigma(path: pathlib.Path, gyro: str | None) -> tuple[str, float, float]:
    """(axis, white angle noise σ per sample [rad], IMU sample rate [Hz]) of gyro axis
    ``gyro`` (None: the device's first gyro) from a dataset's truth."""
    with open_dataset(path) as ds:
        gyros = ds.strings(IMU, "gyro")
        axis = gyro or gyros[0]
        sigma = float(ds.read(TRUTH, "gyro_white_sigma")[gyros.index(axis)])  # rad per sample
        rate = float(ds.group_attrs(IMU)["sample_rate_hz"])
    return axis, sigma, rate


def device_coefficients(path: pathlib.Path) -> dict[str, float]:
    """Every drawn device coefficient of a dataset's truth (name → value); empty if the file
    or its truth cannot be read."""
    try:
        with open_dataset(path) as ds:
            return ds.coefficients()
    except (UserInputError, OSError, KeyError):
        return {}


def probe_temperatures(path: pathlib.Path, names: list[str]
                       ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The probe log of a dataset: its time grid [s] and the readings [°C] of probes
    ``names`` (float64, NaN where the probe gave no reading)."""
    with open_dataset(path) as ds:
        time_s = ds.read(PROBES, "time")
        probes = ds.strings(PROBES, "probe")
        return time_s, {n: ds.read(PROBES, "temperature", None, probes.index(n)).astype(float)
                        for n in names}
