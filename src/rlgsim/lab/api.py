"""The public Python API (docs/api.md is its tutorial): the few functions a notebook needs, on
top of the simulator (:mod:`rlgsim.sim`) and the estimators (:mod:`rlgsim.estimators`).

- :func:`load_scenario`, :func:`with_changes` — a scenario and a changed copy whose embedded
  TOML says what was run;
- :func:`run` — simulate to a file or into memory, as an :class:`xarray.DataTree`;
- :func:`open_tree` — any dataset or recording as an :class:`xarray.DataTree` with a time
  coordinate on every group;
- :func:`window_table` — the 100 s window series of a run (measured bias with the Earth rate
  removed, window means of every probe, temperature rates, UHFO; the truth for simulated runs)
  as a :class:`pandas.DataFrame` whose column names carry their units — what the compensators
  (:mod:`rlgsim.estimators`) fit on, their equations printing those names;
- :func:`score` — RMSE, MAE and R² of a prediction against the truth;
- :func:`calibrate` — the turntable calibration of a dataset, or of a recording with its
  commanded programme, with the same filter settings as ``rlgsim calibrate``;
- :func:`load_study`, :func:`run_study` — a study object and its report folder.

Everything is imported lazily: ``import rlgsim`` stays light.
"""

from __future__ import annotations

import os
import pathlib
import tempfile
from typing import Any

import numpy as np

__all__ = ["load_scenario", "with_changes", "run", "open_tree", "window_table", "score",
           "calibrate", "load_study", "run_study", "navigate"]

def load_scenario(ref: str):
    """A scenario by shipped name (``rlgsim list``) or path (:class:`rlgsim.Scenario`)."""
    from rlgsim.sim.run.scenario import load_scenario as _load
    return _load(ref)


def with_changes(scenario, changes: dict | None = None, /, **keys):
    """``scenario`` with TOML keys changed (dotted paths, ``[i]`` for list elements; top-level
    keywords), validated again; its ``text`` is the changed TOML."""
    from rlgsim.sim.run.scenario_changes import with_changes as _with
    return _with(scenario, changes, **keys)


def run(scenario, out: str | os.PathLike | None = None, *, progress: bool = False):
    """Simulate ``scenario`` (a :class:`~rlgsim.Scenario`, a shipped name or a path).

    With ``out`` the dataset is written there and opened lazily; without it the run goes to a
    temporary file that is read into memory and deleted (mind the size: ``rlgsim run`` streams
    runs of any length to disk). Returns an :class:`xarray.DataTree` (:func:`open_tree`)."""
    from rlgsim.sim.run.simulate import simulate
    if isinstance(scenario, (str, os.PathLike)):
        scenario = load_scenario(os.fspath(scenario))
    if out is not None:
        path = simulate(scenario, out, progress=progress)
        return open_tree(path)
    with tempfile.TemporaryDirectory(prefix="rlgsim-run-") as tmp:
        path = simulate(scenario, pathlib.Path(tmp) / f"{scenario.name}.h5", progress=progress)
        return open_tree(path, load=True)


def open_tree(path: str | os.PathLike, *, load: bool = False):
    """A dataset or a recording as an :class:`xarray.DataTree` (time coordinates on every group;
    :mod:`rlgsim.ground.datatree`)."""
    from rlgsim.ground.datatree import open_tree as _open
    return _open(path, load=load)


# ---------------------------------------------------------------------------- windows

def window_table(source, window_s: float = 100.0, *, gyro: str | None = None):
    """The window series of one run as a :class:`pandas.DataFrame` (one row per complete
    window, columns named with their units):

    ``time_s`` (window end), ``bias_deg_per_h`` (pulses / (K·W) minus the Earth rate on the
    gyro axis), ``probe_<name>_c`` (window mean), ``dTdt_<name>_k_per_s`` (least-squares slope
    in the window), ``uhfo_v`` (when logged), and for a simulated dataset
    ``true_bias_deg_per_h`` and ``true_random_deg_per_h`` (the truth's window mean and its
    flicker + random-walk part). Windows that are not powered throughout, or whose gyro
    output holds a dropout, are left out; a probe, UHFO or power reading missing inside a
    window (a dropout row) is left out of that window's mean and slope, and a window missing
    more than half of a channel's readings is left out.

    ``source``: a dataset or recording path. K is the nominal scale factor (the truth's drawn
    ``gyro.k0`` for a dataset, the sidecar's for a recording); the Earth rate is the exact
    projection the truth stores for a dataset, and for a recording the site latitude and the
    sidecar's ``[orientation]`` (a static mount)."""
    from rlgsim.lab.windows import window_table as _table
    return _table(source, window_s, gyro=gyro)


# ---------------------------------------------------------------------------- scores

def score(y_true, y_pred) -> dict[str, float]:
    """``rmse``, ``mae`` and ``r2`` of ``y_pred`` against ``y_true`` (same units)."""
    from rlgsim.estimators.metrics import mae, r2, rmse
    yt, yp = np.asarray(y_true, dtype=float), np.asarray(y_pred, dtype=float)
    return {"rmse": rmse(yt, yp), "mae": mae(yt, yp), "r2": r2(yt, yp)}


# ---------------------------------------------------------------------------- calibration

def calibrate(source: str | os.PathLike, programme: str | os.PathLike | None = None, *,
              workers: int = 1):
    """The turntable Kalman calibration of every calibration window, as a
    :class:`pandas.DataFrame` (the columns of ``rlgsim calibrate``'s table). ``source``: a
    dataset, or a recording with its ``programme`` (a programme CSV or the scenario it ran).
    The filter settings come from the device's noise levels exactly as on the command line
    (:func:`rlgsim.estimators.calibration.filter_settings`)."""
    import pandas as pd

    from rlgsim.estimators.calibration import CampaignSettings, run_campaign
    from rlgsim.ground.recording import is_recording
    src: Any = pathlib.Path(source)
    if programme is not None or is_recording(source):
        from rlgsim.lab.recordings import calibration_source
        src = calibration_source(source, programme)
    result = run_campaign(src, CampaignSettings(workers=workers))
    pairs = result.table_columns()
    return pd.DataFrame([{h: r.get(c, np.nan) for h, c in pairs} for r in result.rows],
                        columns=[h for h, _ in pairs])


# ---------------------------------------------------------------------------- studies

def load_study(ref: str):
    """A study by shipped name (``rlgsim study --list``) or path."""
    from rlgsim.lab.study import load_study as _load
    return _load(ref)


def run_study(study, out_dir: str | os.PathLike, *, progress: bool = False) -> pathlib.Path:
    """Run a study (object or name/path) into ``out_dir``; returns the path of report.md."""
    from rlgsim.lab.study import run_study as _run
    if isinstance(study, (str, os.PathLike)):
        study = load_study(os.fspath(study))
    return _run(study, out_dir, progress=progress)


def navigate(source: str | os.PathLike, *, models=None, span_s: float | None = None,
             align_s: float = 600.0, output_s: float = 1.0):
    """Align on the first static segment and navigate free-inertially (docs/navigation.md).

    ``source``: a dataset or a recording (whose sidecar names the site). ``models``: variant
    name → gyro-bias prediction [rad/s] — an array (steps, 3) on the dataset's thermal grid or
    a function of time [s] returning (m, 3); exported compensator JSON files become such
    functions with :func:`rlgsim.lab.navigation_models.load_models`. Returns an
    :class:`xarray.Dataset`: error series (dims ``variant``, ``time``: position North/East and
    horizontal [m], velocity [m/s], heading [′]) and the scores per variant (error at 1 h and at
    the end [m], radial error rate [nmi/h], velocity RMS [m/s], heading after alignment, its
    bound and at the end [′])."""
    from rlgsim.lab.navigation import navigate as _navigate
    return _navigate(source, models=models, span_s=span_s, align_s=align_s, output_s=output_s)
