"""Noise levels of a gyro from the Allan deviation of its rate residual (IEEE Std 952-1997,
Annex C; the conventions of docs/sensors.md).

The overlapping Allan variance of the rate (``allantools.oadev``, ``data_type="freq"``, octave
τ; its sum compiled in :mod:`rlgsim.estimators._allan_kernel`) is fitted by the sum of the
independent IEEE 952 terms

    σ²(τ) = 3Q²/τ² + N²/τ + (2 ln 2/π)·B² + K²τ/3

(quantisation Q, angle random walk N, bias instability B read at its flat floor 0.664·B, rate
random walk K), linear in the coefficients, by non-negative weighted least squares
(:func:`scipy.optimize.nnls`). The weight of each τ is 1/(σ²_model(τ)·√(2/edf)): the relative
standard deviation of an Allan variance estimate is √(2/edf), with the equivalent degrees of
freedom of ``allantools.edf_simple`` (white-FM, Howe, Allan & Barnes 1981) capped at the number
of non-overlapping τ intervals, iterated with the model in place of the noisy estimate.
Confidence intervals (95 %) come from the weighted covariance of the coefficients, mapped
through the square root and clipped at zero; an interval whose lower end is zero means the
recording does not resolve that term (e.g. a rate random walk in a short run). Correlations
between the overlapping estimates at neighbouring τ are neglected, so the intervals are
approximate.

Quantisation of a pulse counter (``quantum_arcsec`` given: the angle of one pulse, 1/K for a
scale factor of K pulses/arcsec). A counter that carries its fractional remainder reads the
angle ``φ`` with the error ``e = frac(φ)`` (in pulses), so the rate per sample carries
``(e_k − e_{k−1})/Δt``; for ``e`` uniform and independent between the ends of the τ intervals
this is IEEE 952's Q term with ``Q = quantum/√12`` exactly — the quantum is known, so Q is
*fixed*, not fitted. But the errors are independent only at lags where the angle's own random
walk has smeared ``φ`` over a whole pulse: with the mean rate ``r`` pulses per sample and white
rate noise of σ_p pulses per sample, the sawtooth's Fourier series gives the autocovariance of
``e`` at a lag of m samples

    C(m) = Σ_k cos(2πk·m·r)·exp(−2π²k²·m·σ_p²) / (2π²k²),   C(0) = 1/12,

so at short τ the quantisation's Allan variance swings around 3Q²/τ² with the fractional part
of ``m·r`` (a rate near a whole number of pulses per sample holds ``e`` nearly constant and the
τ = 1 s Allan variance falls to 0.37 × 3Q²/τ²; over τ = 1–8 s it spans 0.37–1.7 × 3Q²/τ² at
trplg_001's 2.14 pulses/arcsec and 1 Hz, and is within 5 % of it from 16 s). A fit through
those τ trades the missing quantisation for white noise (a trplg_001 recording, 2.14 pulses/arcsec at 1 Hz: Q fitted
0.083 arcsec instead of 0.135, ARW 0.0013 instead of 0.0008 °/√h). With the quantum known the
fit therefore starts at the first octave τ = m/f with ``exp(−2π²·m·σ_p²) ≤`` :data:`DECORRELATED`
(the k = 1 term, the largest), σ_p = N/(√f·quantum) from the white level N of the previous
iteration (starting from the fit with Q free). Without a quantum (a rate that is not a pulse
count) Q is fitted with the other terms over every τ.

Units: rate in °/h and τ in s, so N comes out in (°/h)·√s (= 60 × ARW in °/√h), B in °/h,
K in (°/h)/√s (= RRW in °/h/√h ÷ 60), Q in (°/h)·s = arcsec.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import allantools
import numpy as np
from scipy.optimize import nnls

from rlgsim.estimators._allan_kernel import oadev_octave

__all__ = ["NoiseFit", "fit_allan", "DECORRELATED"]

_B_FACTOR = 2.0 * math.log(2.0) / math.pi
_Z95 = 1.959963984540054
#: the largest correlation (k = 1 term) of the counter's reading errors at the two ends of a τ
#: interval for that τ to enter a fit with Q fixed at quantum/√12
DECORRELATED = 0.05


@dataclass(frozen=True)
class NoiseFit:
    """Fitted noise levels with 95 % intervals ``(low, high)`` in preset units:
    ``arw_deg_per_sqrt_h``, ``bi_deg_per_h``, ``rrw_deg_per_h_per_sqrt_h``, ``q_arcsec``; the
    Allan curve (``taus_s``, ``adev_deg_per_h``, ``model_deg_per_h``) over the τ fitted;
    ``q_fixed``: Q set from the pulse quantum (its interval is then that value)."""

    values: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    taus_s: np.ndarray
    adev_deg_per_h: np.ndarray
    model_deg_per_h: np.ndarray
    q_fixed: bool = False

    def rows(self) -> list[dict]:
        """One row per term; Q says when it is the pulse quantum/√12, not a fitted value."""
        return [{"term": k, "estimate": v, "ci95_low": self.intervals[k][0],
                 "ci95_high": self.intervals[k][1],
                 "how": ("fixed: pulse quantum/√12" if k == "q_arcsec" and self.q_fixed
                         else "Allan fit")} for k, v in self.values.items()]


_SCALE = {"q_arcsec": 1.0, "arw_deg_per_sqrt_h": 1.0 / 60.0, "bi_deg_per_h": 1.0,
          "rrw_deg_per_h_per_sqrt_h": 60.0}
_KEYS = ("q_arcsec", "arw_deg_per_sqrt_h", "bi_deg_per_h", "rrw_deg_per_h_per_sqrt_h")


def _wnnls(X: np.ndarray, avar: np.ndarray, edf: np.ndarray, fixed: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Non-negative weighted least squares of ``avar − fixed`` on ``X`` (weights iterated with
    the model, module docstring): coefficients, their standard errors, the model (fixed
    part included)."""
    model = avar.copy()
    for _ in range(3):
        w = 1.0 / (model * np.sqrt(2.0 / edf))
        coef, _ = nnls(X * w[:, None], (avar - fixed) * w)
        model = np.maximum(X @ coef + fixed, 1e-30)
    Xw = X * w[:, None]
    p = X.shape[1]
    active = coef > 0
    cov = np.zeros((p, p))
    if active.any():
        sub = Xw[:, active]
        idx = np.flatnonzero(active)
        cov[np.ix_(idx, idx)] = np.linalg.pinv(sub.T @ sub)
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # a term held at zero by the constraint: its upper bound from the unconstrained SE
    if (~active).any():
        full = np.linalg.pinv(Xw.T @ Xw)
        se = np.where(active, se, np.sqrt(np.clip(np.diag(full), 0, None)))
    return coef, se, model


def fit_allan(rate_deg_per_h: np.ndarray, rate_hz: float, *, max_tau_fraction: float = 0.1,
              quantum_arcsec: float | None = None) -> NoiseFit:
    """Fit the noise terms to the Allan deviation of ``rate_deg_per_h`` sampled at ``rate_hz``
    (τ up to ``max_tau_fraction`` of the record). ``quantum_arcsec``: the angle of one counter
    pulse [arcsec] when the rate is a pulse count per sample — Q is then fixed at
    quantum/√12 and the τ at which the counter's errors are still correlated are left out
    (module docstring); None: Q fitted over every τ from one sample."""
    y = np.asarray(rate_deg_per_h, dtype=float)
    if y.ndim != 1 or y.size < 64 or not np.all(np.isfinite(y)):
        raise ValueError("fit_allan needs at least 64 finite rate samples")
    if quantum_arcsec is not None and not (quantum_arcsec > 0 and math.isfinite(quantum_arcsec)):
        raise ValueError(f"quantum_arcsec must be a positive angle, not {quantum_arcsec!r}")
    max_tau = max_tau_fraction * y.size / rate_hz
    taus, adev, ns = oadev_octave(y - y.mean(), rate_hz, max_tau)   # allantools' oadev, compiled
    keep = (taus <= max_tau) & (adev > 0)
    taus, adev = taus[keep], adev[keep]
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
    coef, se, model = _wnnls(X, avar, edf, np.zeros_like(avar))
    use = np.ones(taus.size, dtype=bool)
    if quantum_arcsec is not None:
        q2 = quantum_arcsec ** 2 / 12.0
        for _ in range(4):
            sigma_p = math.sqrt(max(coef[1], 0.0) / rate_hz) / quantum_arcsec
            m_min = (math.log(1.0 / DECORRELATED) / (2.0 * math.pi ** 2 * sigma_p ** 2)
                     if sigma_p > 0 else math.inf)
            new = m >= m_min
            if new.sum() < 4:                      # keep the four longest τ at least
                new = np.zeros_like(new)
                new[-4:] = True
            if coef[0] == q2 and np.array_equal(new, use):
                break                              # the same τ as the previous iteration
            use = new
            sub, se_sub, model_u = _wnnls(X[use][:, 1:], avar[use], edf[use],
                                          3.0 * q2 / taus[use] ** 2)
            coef = np.concatenate([[q2], sub])
            se = np.concatenate([[0.0], se_sub])
            model = np.full_like(avar, np.nan)
            model[use] = model_u
    values, intervals = {}, {}
    for i, key in enumerate(_KEYS):
        lo = max(coef[i] - _Z95 * se[i], 0.0)
        hi = coef[i] + _Z95 * se[i]
        values[key] = math.sqrt(coef[i]) * _SCALE[key]
        intervals[key] = (math.sqrt(lo) * _SCALE[key], math.sqrt(hi) * _SCALE[key])
    return NoiseFit(values=values, intervals=intervals, taus_s=taus[use], adev_deg_per_h=adev[use],
                    model_deg_per_h=np.sqrt(model[use]), q_fixed=quantum_arcsec is not None)
