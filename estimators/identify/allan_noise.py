"""Noise levels of a gyro from the Allan deviation of its rate residual (IEEE Std 952-1997,
Annex C; the conventions of docs/sensors.md).

The overlapping Allan variance of the rate (``allantools.oadev``, ``data_type="freq"``, octave
τ) is fitted by the sum of the four independent terms

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln 2/π)·B² + K²τ/3

(quantisation Q, angle random walk N, bias instability B read at its flat floor 0.664·B, rate
random walk K), linear in the four coefficients, by non-negative weighted least squares
(:func:`scipy.optimize.nnls`). The weight of each τ is 1/(σ²_model(τ)·√(2/edf)): the relative
standard deviation of an Allan variance estimate is √(2/edf), with the equivalent degrees of
freedom of ``allantools.edf_simple`` (white-FM, Howe, Allan & Barnes 1981) capped at the number
of non-overlapping τ intervals, iterated with the model in place of the noisy estimate. Confidence intervals (95 %) come from the weighted
covariance of the coefficients, mapped through the square root and clipped at zero; an interval
whose lower end is zero means the recording does not resolve that term (e.g. a rate random
walk in a short run). Correlations between the overlapping estimates at neighbouring τ are
neglected, so the intervals are approximate.

Units: rate in °/h and τ in s, so N comes out in (°/h)·√s (= 60 × ARW in °/√h), B in °/h,
K in (°/h)/√s (= RRW in °/h/√h ÷ 60), Q in (°/h)·s = arcsec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import allantools
import numpy as np
from scipy.optimize import nnls

__all__ = ["NoiseFit", "fit_allan"]

_B_FACTOR = 2.0 * math.log(2.0) / math.pi
_Z95 = 1.959963984540054


@dataclass(frozen=True)
class NoiseFit:
    """Fitted noise levels with 95 % intervals ``(low, high)`` in preset units:
    ``arw_deg_per_sqrt_h``, ``bi_deg_per_h``, ``rrw_deg_per_h_per_sqrt_h``, ``q_arcsec``; the
    Allan curve (``taus_s``, ``adev_deg_per_h``, ``model_deg_per_h``)."""

    values: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    taus_s: np.ndarray
    adev_deg_per_h: np.ndarray
    model_deg_per_h: np.ndarray

    def rows(self) -> list[dict]:
        return [{"term": k, "estimate": v, "ci95_low": self.intervals[k][0],
                 "ci95_high": self.intervals[k][1]} for k, v in self.values.items()]


_SCALE = {"q_arcsec": 1.0, "arw_deg_per_sqrt_h": 1.0 / 60.0, "bi_deg_per_h": 1.0,
          "rrw_deg_per_h_per_sqrt_h": 60.0}


def fit_allan(rate_deg_per_h: np.ndarray, rate_hz: float, *, max_tau_fraction: float = 0.1
              ) -> NoiseFit:
    """Fit the four noise terms to the Allan deviation of ``rate_deg_per_h`` sampled at
    ``rate_hz`` (τ from one sample to ``max_tau_fraction`` of the record)."""
    y = np.asarray(rate_deg_per_h, dtype=float)
    if y.ndim != 1 or y.size < 64 or not np.all(np.isfinite(y)):
        raise ValueError("fit_allan needs at least 64 finite rate samples")
    taus, adev, _, ns = allantools.oadev(y - y.mean(), rate=rate_hz, data_type="freq",
                                         taus="octave")
    keep = (taus <= max_tau_fraction * y.size / rate_hz) & (adev > 0)
    taus, adev, ns = taus[keep], adev[keep], ns[keep]
    if taus.size < 5:
        raise ValueError("the record is too short for an Allan fit (fewer than 5 τ values)")
    m = np.rint(taus * rate_hz).astype(int)
    # conservative degrees of freedom: the number of non-overlapping τ intervals (the overlapping
    # estimator's extra ones are strongly correlated between neighbouring τ, which the weighted
    # fit does not model), never more than the white-FM value of allantools.edf_simple
    edf = np.array([max(min(float(allantools.edf_simple(y.size, int(mi), 0)),
                            y.size / mi - 1.0), 1.0) for mi in m])
    avar = adev ** 2
    X = np.column_stack([3.0 / taus ** 2, 1.0 / taus, np.full_like(taus, _B_FACTOR),
                         taus / 3.0])
    model = avar.copy()
    for _ in range(3):
        w = 1.0 / (model * np.sqrt(2.0 / edf))
        coef, _ = nnls(X * w[:, None], avar * w)
        model = np.maximum(X @ coef, 1e-30)
    Xw = X * w[:, None]
    active = coef > 0
    cov = np.zeros((4, 4))
    if active.any():
        sub = Xw[:, active]
        cov_a = np.linalg.pinv(sub.T @ sub)
        idx = np.flatnonzero(active)
        cov[np.ix_(idx, idx)] = cov_a
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # a term held at zero by the constraint: its upper bound from the unconstrained SE
    if (~active).any():
        full = np.linalg.pinv(Xw.T @ Xw)
        se = np.where(active, se, np.sqrt(np.clip(np.diag(full), 0, None)))
    keys = ("q_arcsec", "arw_deg_per_sqrt_h", "bi_deg_per_h", "rrw_deg_per_h_per_sqrt_h")
    values, intervals = {}, {}
    for i, key in enumerate(keys):
        lo = max(coef[i] - _Z95 * se[i], 0.0)
        hi = coef[i] + _Z95 * se[i]
        values[key] = math.sqrt(coef[i]) * _SCALE[key]
        intervals[key] = (math.sqrt(lo) * _SCALE[key], math.sqrt(hi) * _SCALE[key])
    return NoiseFit(values=values, intervals=intervals, taus_s=taus, adev_deg_per_h=adev,
                    model_deg_per_h=np.sqrt(model))
