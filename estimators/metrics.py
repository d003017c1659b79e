"""Scores of a compensation: bias stability, Allan deviation, RMSE, MAE, R², residual variance,
improvement %.

Units: every score except R² and the improvement carries the unit of its input (e.g. °/h for a
gyro bias; the residual variance the square of it).  R² is dimensionless, improvement in %.

* Bias stability (papers 001 Tables 2–5, 002 §4.1, 003 Tables 4–5): standard deviation of the
  means of non-overlapping clusters of ``cluster_s`` seconds (100 s in all three papers); the
  partial last cluster is dropped.  ``ddof=1`` (sample std) by default — the papers do not
  state theirs; pass ``ddof=0`` for the population form.  The value used is recorded by the
  caller's report.
* Allan deviation: overlapping ADEV from ``allantools.oadev(..., data_type="freq")`` (NIST
  SP 1065 eq. 11).  For white noise the ADEV at τ equals the std of τ-cluster means, so the two
  agree (tested).
* RMSE, MAE, R²: ``sklearn.metrics`` (``root_mean_squared_error``, ``mean_absolute_error``,
  ``r2_score``) after the project's input checks; paper 000 Table 2 uses the same definitions.
* Residual variance (paper 000 Table 3): variance of ``y_true − y_pred`` with ``ddof``
  (default 1).  It ignores a constant offset, unlike the mean squared error.
* Improvement (paper 001 Tables 2–5): ``100·(before − after)/before`` %.
"""

from __future__ import annotations

from typing import NamedTuple

import allantools
import numpy as np
from numpy.typing import ArrayLike
from sklearn.metrics import mean_absolute_error, r2_score, root_mean_squared_error
from sklearn.utils.validation import check_array, check_consistent_length

from rlgsim.estimators._validation import check_min_samples
from rlgsim.estimators.features import window_average


__all__ = ["bias_stability", "AllanDeviation", "allan_deviation", "rmse", "mae", "r2",
           "residual_variance", "improvement_percent"]

def _series(x: ArrayLike, what: str, min_samples: int = 1) -> np.ndarray:
    """Finite float64 1-D series; ``ValueError`` naming ``what`` otherwise."""
    arr = check_array(x, ensure_2d=False, dtype=np.float64, input_name=what,
                      ensure_min_samples=min_samples)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be 1-D, got shape {arr.shape}")
    return arr


def _pair(y_true: ArrayLike, y_pred: ArrayLike,
          min_samples: int = 1) -> tuple[np.ndarray, np.ndarray]:
    a = _series(y_true, "y_true", min_samples)
    b = _series(y_pred, "y_pred", min_samples)
    if a.shape[0] != b.shape[0]:
        raise ValueError(f"mismatched lengths: y_true has {a.shape[0]} samples, y_pred has "
                         f"{b.shape[0]}")
    check_consistent_length(a, b)
    return a, b


def bias_stability(x: ArrayLike, rate_hz: float, cluster_s: float = 100.0,
                   ddof: int = 1) -> float:
    """Std of the means of non-overlapping ``cluster_s``-second clusters of ``x``.

    Parameters
    ----------
    x
        Gyro bias or compensated output (any unit, e.g. °/h) sampled at ``rate_hz``.
    rate_hz
        Sample rate (Hz); for 100 s means already computed pass ``rate_hz=0.01`` and
        ``cluster_s=100`` (each cluster is then one sample).
    cluster_s
        Cluster length (s), a whole number of samples.  The partial last cluster is dropped.
    ddof
        Delta degrees of freedom of the std (1: divide by K−1 for K clusters; 0: by K).

    Returns
    -------
    Bias stability in the unit of ``x``.  Needs at least 2 full clusters.
    """
    if ddof not in (0, 1):
        raise ValueError(f"ddof must be 0 or 1, got {ddof}")
    arr = _series(x, "x")
    means = window_average(arr, rate_hz, cluster_s)
    check_min_samples(means.shape[0], 2, f"bias stability over {cluster_s} s clusters "
                      "(counted in clusters)")
    return float(np.std(means, ddof=ddof))


class AllanDeviation(NamedTuple):
    """Overlapping Allan deviation: averaging times (s), ADEV (unit of the input), its
    1-sigma error estimate ``adev/√n`` (allantools), and the number of terms ``n`` used."""

    tau_s: np.ndarray
    adev: np.ndarray
    error: np.ndarray
    n: np.ndarray


def allan_deviation(x: ArrayLike, rate_hz: float,
                    taus_s: ArrayLike | str = "octave") -> AllanDeviation:
    """Overlapping Allan deviation of a rate series (``allantools.oadev``, ``data_type="freq"``).

    Parameters
    ----------
    x
        Rate samples (any unit, e.g. °/h) at ``rate_hz``; the ADEV has the same unit.
    rate_hz
        Sample rate (Hz).
    taus_s
        Averaging times (s), or ``"all"``, ``"octave"``, ``"decade"``.  allantools rounds each
        to a whole number of samples and drops those longer than half the record, so read the
        returned ``tau_s``.
    """
    arr = _series(x, "x", min_samples=3)
    if not np.isfinite(rate_hz) or rate_hz <= 0:
        raise ValueError(f"rate_hz must be positive and finite, got {rate_hz}")
    if isinstance(taus_s, str):
        taus: ArrayLike | str = taus_s
    else:
        taus = _series(taus_s, "taus_s")
        if np.any(taus <= 0):
            raise ValueError(f"taus_s must be positive, got {taus}")
        m = np.round(taus * rate_hz)
        taus = taus[(m >= 1) & (arr.shape[0] - 2 * m >= 1)]   # ≥ 2 overlapping differences
        if taus.size == 0:
            raise ValueError(f"no averaging time in {np.asarray(taus_s)} s fits in "
                             f"{arr.shape[0]} samples at {rate_hz} Hz (need 1 ≤ τ·rate < n/2)")
    from rlgsim.estimators._allan_kernel import oadev       # allantools' numbers, compiled
    tau, adev, err, n = oadev(arr, rate_hz, taus)
    return AllanDeviation(tau, adev, err, n)



def rmse(y_true: ArrayLike, y_pred: ArrayLike) -> float:
    """Root-mean-square error ``√(mean((y_true − y_pred)²))``, unit of y."""
    a, b = _pair(y_true, y_pred)
    return float(root_mean_squared_error(a, b))


def mae(y_true: ArrayLike, y_pred: ArrayLike) -> float:
    """Mean absolute error ``mean(|y_true − y_pred|)``, unit of y."""
    a, b = _pair(y_true, y_pred)
    return float(mean_absolute_error(a, b))


def r2(y_true: ArrayLike, y_pred: ArrayLike) -> float:
    """Coefficient of determination ``1 − SS_res/SS_tot`` (dimensionless).

    ``ValueError`` if ``y_true`` is constant (SS_tot = 0: R² undefined).
    """
    a, b = _pair(y_true, y_pred, min_samples=2)
    if np.ptp(a) == 0:
        raise ValueError("constant y_true: R² is undefined when y_true has no variance")
    return float(r2_score(a, b))


def residual_variance(y_true: ArrayLike, y_pred: ArrayLike, ddof: int = 1) -> float:
    """Variance of the residual ``y_true − y_pred`` (unit of y, squared), with ``ddof``."""
    if ddof not in (0, 1):
        raise ValueError(f"ddof must be 0 or 1, got {ddof}")
    a, b = _pair(y_true, y_pred, min_samples=ddof + 1)
    return float(np.var(a - b, ddof=ddof))


def improvement_percent(before: float, after: float) -> float:
    """Relative reduction ``100·(before − after)/before`` (%) of a positive score such as the
    bias stability (paper 001: 0.01850 → 0.01194 °/h is 35.46 %).  Negative if worse."""
    before, after = float(before), float(after)
    if not (np.isfinite(before) and np.isfinite(after)):
        raise ValueError(f"improvement needs finite scores, got before={before}, after={after}")
    if before <= 0:
        raise ValueError(f"improvement needs a positive 'before' score, got {before}")
    return 100.0 * (before - after) / before
