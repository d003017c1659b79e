"""The configuration of the ``bias_compensation`` recipe (papers 001 and demo; its study tables
are described in :mod:`rlgsim.lab.studies.bias_compensation`) and the outcome its run hands to
its report (:mod:`rlgsim.lab.studies.bias_compensation_report`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rlgsim.lab.studies.compensators import RAW, CompensatorSpec
from rlgsim.lab.studies.fitting import Fitted
from rlgsim.lab.studies.runs import LoadedRun, RunSeries
from rlgsim.lab.studies.study_tables import FeatureSpec, RunSpec


TOP_KEYS = ("study", "data", "features", "compensator", "metrics", "published", "navigation")
DATA_KEYS = ("train", "test", "window_s", "gyro")


PUBLISHED_COMP_KEYS = ("stability_deg_per_h", "improvement_pct", "c", "sigma2", "equation")
METRIC_KEYS = ("cluster_s", "ddof", "baseline")


PUBLISHED_KEYS = ("stability_before_deg_per_h", "correlation")


@dataclass(frozen=True)
class Config(FeatureSpec):
    """A validated bias_compensation study: its runs, features, compensators and metrics."""

    train: tuple[RunSpec, ...] = ()
    test: tuple[RunSpec, ...] = ()
    compensators: tuple[CompensatorSpec, ...] = ()
    cluster_s: float = 100.0
    ddof: int = 1
    baseline: str = RAW
    published: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------ the run
@dataclass
class Outcome:
    """What :func:`run` hands to :func:`report` (in ``StudyResult.details``)."""

    runs: dict[tuple[str, float], LoadedRun]
    train: list[RunSeries]
    fitted: list[Fitted]
    per_test: dict[str, dict[str, dict[str, float]]]   # test label → compensator → scores
    predictions: dict[str, dict[str, np.ndarray]]      # test label → compensator → ŷ [°/h]
    Xtr: Any                    # the train windows' inputs (Columns)
    ytr: np.ndarray             # their measured bias [°/h]
    unit: int
    t_data: float               # wall time of simulating/reading the runs [s]
    t_total: float              # wall time of the run [s]
