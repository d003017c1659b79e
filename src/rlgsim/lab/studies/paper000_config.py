"""The configuration of the ``paper000_system`` recipe (its study tables are described in
:mod:`rlgsim.lab.studies.paper000_system`), the paper's figures, and the outcome its run hands to
its report (:mod:`rlgsim.lab.studies.paper000_report`).

Paper figures beside ours: only the averages of Table 2 and Table 3 (and the maxima) survived
the text extraction of paper 000 (``PAPER_*`` below); its per-parameter values did not.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.sim.config import (Ctx, check_known_keys, get_bool, get_float, get_int, get_section,
                               get_str)

#: Paper 000 abstract and §4.2-4.3 (average and maximum improvement of HHO-RVR over LSM, %).
PAPER_AVG_IMPROVEMENT = {"rmse": 35.27, "mae": 39.29, "r2": 2.29, "residual_variance": 30.34}
PAPER_MAX_IMPROVEMENT = {"rmse": 80.12, "mae": 83.51, "r2": 9.15}

TOP_KEYS = ("study", "campaign", "models", "system")
CAMPAIGN_KEYS = ("scenario", "temperature", "workers")
MODELS_KEYS = ("hho_rvr", "lsm")
RVR_KEYS = ("hawks", "iterations", "folds", "shuffle", "width_resolution_decades", "seed")
LSM_KEYS = ("degree",)
SYSTEM_KEYS = ("desired_temperature_c", "compensate")
AXES = "xyz"
COMPENSATORS = ("hho_rvr", "lsm")
LABEL = {"hho_rvr": "HHO-RVR", "lsm": "cubic LSM", "raw": "raw"}


@dataclass(frozen=True)
class Config:
    """The validated study tables."""

    scenario: str
    temperature: str
    workers: int
    hawks: int
    iterations: int
    folds: int
    shuffle: bool
    width_resolution: float
    seed: int
    degree: int
    desired_c: float
    compensate: bool


def parse(study) -> Config:
    """Validate ``[campaign]``, ``[models]``, ``[system]``; UserInputError naming file/key/value."""
    data = study.tables
    ctx = Ctx(study.source)
    check_known_keys(data, TOP_KEYS, ctx)
    camp, cctx = get_section(data, "campaign", ctx, CAMPAIGN_KEYS, {})
    models, mctx = get_section(data, "models", ctx, MODELS_KEYS, {})
    rvr, rctx = get_section(models, "hho_rvr", mctx, RVR_KEYS, {})
    lsm, lctx = get_section(models, "lsm", mctx, LSM_KEYS, {})
    system, sctx = get_section(data, "system", ctx, SYSTEM_KEYS, {})
    temperature = get_str(camp, "temperature", cctx, "sensor")
    if not temperature.strip():
        raise cctx.error("temperature", "value '' not allowed; give \"sensor\" or a probe name")
    cfg = Config(
        scenario=get_str(camp, "scenario", cctx, "paper000_campaign"),
        temperature=temperature,
        workers=get_int(camp, "workers", cctx, 0, min=0, max=64),
        hawks=get_int(rvr, "hawks", rctx, 30, min=2, max=10_000),
        iterations=get_int(rvr, "iterations", rctx, 500, min=1, max=100_000),
        folds=get_int(rvr, "folds", rctx, 5, min=2, max=100),
        shuffle=get_bool(rvr, "shuffle", rctx, True),
        width_resolution=get_float(rvr, "width_resolution_decades", rctx, 1e-3, min=1e-9,
                                   max=0.1),
        seed=get_int(rvr, "seed", rctx, 0, min=0, max=2**32 - 1),
        degree=get_int(lsm, "degree", lctx, 3, min=1, max=9),
        desired_c=get_float(system, "desired_temperature_c", sctx, 50.0, min=-100.0, max=200.0),
        compensate=get_bool(system, "compensate", sctx, True))
    if not cfg.scenario.strip():
        raise cctx.error("scenario", "value '' not allowed; give a scenario name or path")
    from rlgsim.lab.recordings import recording_path
    if recording_path(cfg.scenario, study.base_dir, str(study.source)) is not None:
        raise cctx.error("scenario", f"{cfg.scenario!r} is a recording; the paper000_system "
                                     f"recipe needs a simulated turntable campaign (its "
                                     f"calibration windows and the truth), so it takes "
                                     f"scenarios only (docs/recordings.md)")
    return cfg


def probe_for(param: str, temperature: str) -> str:
    """The probe whose window mean is the model input of ``param``."""
    if temperature != "sensor":
        return temperature
    axis = param[-1]
    return f"g{axis}.A" if param.startswith("gyro_") else f"a{axis}"


def improvement(metric: str, lsm: float, rvr: float) -> float:
    """HHO-RVR over LSM in % as the paper counts it: error metrics 100·(LSM − RVR)/LSM,
    R² 100·(RVR − LSM)/|LSM|."""
    if metric == "r2":
        return 100.0 * (rvr - lsm) / abs(lsm) if lsm != 0 else float("nan")
    return 100.0 * (lsm - rvr) / lsm if lsm != 0 else float("nan")


@dataclass
class Outcome:
    """What :func:`run` hands to :func:`report` (in ``StudyResult.details``); parameters are
    keyed by name, models by "hho_rvr" / "lsm"."""

    scenario: Any
    data_path: pathlib.Path
    reused: bool                            # the dataset was reused, not simulated
    raw: Any                                # the calibration table of the raw dataset
    xs: dict[str, np.ndarray]               # model input: window-mean probe temperature [°C]
    ys: dict[str, np.ndarray]               # calibrated parameter per window
    pred: dict[str, dict[str, np.ndarray]]  # the models' fits
    fitted: dict[str, tuple]                # (HHO-RVR, LSM, CPU s) per parameter
    fit_scores: dict[str, dict[str, dict[str, float]]]     # vs the calibration estimates
    truth_scores: dict[str, dict[str, dict[str, float]]]   # vs the true window-mean parameter
    avg: dict[str, float]                   # average improvement of HHO-RVR over LSM [%]
    avg_truth: dict[str, float]
    resvar: dict[str, dict[str, float]]     # Table 3 residual variances
    resid: dict[str, dict[str, np.ndarray]]
    desired: dict[str, dict[str, float]]    # the models' values at the desired temperature
    comp_tables: dict                       # re-calibration table per model
    units: dict[str, str]
    clock: dict[str, float]                 # wall time per step [s]
    ok: np.ndarray                          # calibration windows that succeeded
    navigation: Any = None                  # (dataset, introduction) when run beside the
                                            #   re-calibration (paper000_report.navigation)
