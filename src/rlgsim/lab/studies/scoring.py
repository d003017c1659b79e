"""Scores of a compensator's prediction on a test run, the paper's way and against the truth.

Scores of one prediction ŷ on a test run (:func:`scores`, all in °/h unless stated):

* ``stability_before`` / ``stability_after``: bias stability (std of ``cluster_s`` means,
  ``ddof``) of the baseline and of the compensated series ``y − ŷ``;
  ``improvement_pct`` = 100·(before − after)/before (paper 001 Tables 2-5, paper 003 Tables
  4-5); ``improvement_factor`` = before/after (paper 002 Table 1);
* ``rmse_true``, ``mae_true``, ``r2_true``: the predicted bias ``ŷ`` against the true bias
  ``b`` (window means); ``b`` excludes the constant the output adds through the scale-factor
  error and misalignment times the Earth rate, which the compensators fold into their constant;
* ``outside_range_pct``: the share of the run's windows in which an input of the compensator
  lies outside its training [min, max], ``outside_excess_pct`` the largest distance beyond, in
  % of the training span (:mod:`rlgsim.lab.studies.input_range`; 0 for the references);
* ``resid_std_true`` = std(ŷ − b): what is left of the true bias after compensation, offset-free
  (the bias stability a noise-free gyro would show after compensation);
* ``law_resid_std`` = std(ŷ − (b − r)), r the random part: the error of the learnt temperature
  law alone.

The oracle ``ŷ = b − r`` (:data:`~rlgsim.lab.studies.compensators.ORACLE`) is the best any
input-driven model can do; its ``stability_after`` is the floor the others approach.
"""

from __future__ import annotations

import numpy as np

from rlgsim.lab.studies.compensators import ORACLE, RAW
from rlgsim.lab.studies.fitting import Fitted, predict
from rlgsim.lab.studies.runs import RunSeries
from rlgsim.lab.studies.study_tables import FeatureSpec


def series_stability(x: np.ndarray, window_s: float, cluster_s: float, ddof: int) -> float:
    """Bias stability [°/h] of a window series [°/h]: std (``ddof``) of ``cluster_s`` means."""
    from rlgsim.estimators.metrics import bias_stability
    return bias_stability(x, 1.0 / window_s, cluster_s, ddof)


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
    out = {name: scores(rs.y, p, rs.true_bias, rs.true_random, features.window_s, cluster_s,
                        ddof, before) for name, p in preds.items() if name != ORACLE
           or has_truth(rs)}
    if not has_truth(rs):                # a recording: no oracle, every score NaN
        out[ORACLE] = {k: float("nan") for k in next(iter(out.values()))}
    from rlgsim.lab.studies.input_range import outside_range
    for name in out:                     # the references use no inputs: nothing to extrapolate
        out[name].update(outside_range_pct=0.0, outside_excess_pct=0.0)
    for f in fitted:
        if f.spec.name in out and f.X_train is not None and hasattr(f.X_train, "names"):
            share, excess, _ = outside_range(f.X_train, rs.X, f.X_train.names)
            out[f.spec.name].update(outside_range_pct=share, outside_excess_pct=excess)
    return preds, out


def has_truth(rs: RunSeries) -> bool:
    """Whether the run carries the truth (a simulated dataset; a recording does not)."""
    return bool(rs.true_bias.size) and bool(np.all(np.isfinite(rs.true_bias)))


# ------------------------------------------------------------------------------ scoring
def scores(y: np.ndarray, y_hat: np.ndarray, b: np.ndarray, r: np.ndarray, window_s: float,
           cluster_s: float, ddof: int, before: float) -> dict[str, float]:
    """Paper-style and truth-based scores of one prediction (definitions: module docstring)."""
    from rlgsim.estimators import metrics as M
    rate = 1.0 / window_s
    after = M.bias_stability(y - y_hat, rate, cluster_s, ddof)
    out = {"stability_before": before, "stability_after": after,
           "improvement_pct": M.improvement_percent(before, after),
           "improvement_factor": before / after if after > 0 else float("inf")}
    if not (b.size and np.all(np.isfinite(b))):      # a recording: truth-based scores absent
        return {**out, **{k: float("nan") for k in ("rmse_true", "mae_true", "r2_true",
                                                    "resid_std_true", "law_resid_std")}}
    out.update({"rmse_true": M.rmse(b, y_hat), "mae_true": M.mae(b, y_hat),
                "r2_true": M.r2(b, y_hat),
                "resid_std_true": float(np.std(y_hat - b, ddof=ddof)),
                "law_resid_std": float(np.std(y_hat - (b - r), ddof=ddof))})
    return out
