"""Covariance of a gyro's mean rate noise over segments of *different* lengths (the constant-rate
segments of a turntable programme), from its Allan noise model — the generalisation of
:mod:`rlgsim.estimators.identify.window_noise` (equal windows) that the scale-factor fit needs.

Segments ``[s_i, s_i + T_i)`` do not overlap. Terms (IEEE Std 952-1997 Annex C conventions,
two-sided PSDs; units: rate in °/h, time in s, N in (°/h)·√s, B in °/h, K in (°/h)/√s, Q in
arcsec):

- white rate noise N: ``Var = N²/T_i``, independent segments;
- quantisation Q: ``Var = 2Q²/T_i²`` (the mean is ``(e_end − e_start)/T`` of an angle error
  of variance Q²), independent — as :func:`~rlgsim.estimators.identify.window_noise.
  covariance_from_fit` treats it (segments are rarely adjacent);
- rate random walk K from the record's start: ``Cov = K²·(s_i + T_i/2)`` for segment i wholly
  before j, ``K²·(s_i + T_i/3)`` for the same segment (the mean of ``min(t, t')``);
- flicker B as the bank of first-order Gauss–Markov processes (variances
  ``q_j² = w_j·B²·Δ/π`` over correlation times evenly spaced in ln τ between ``tau_min_s`` and
  ``tau_max_s``; Keshner 1982, Kasdin 1995 §IV — the simulator's construction). For one process
  of variance q² and correlation time τ, integrating ``q² e^{−|t−t'|/τ}`` over the two segments
  gives, with the gap ``g = s_j − (s_i + T_i) ≥ 0``,
  ``Cov = q²·τ²/(T_i T_j)·e^{−g/τ}·(1 − e^{−T_i/τ})·(1 − e^{−T_j/τ})`` and
  ``Var = 2q²·(τ/T)²·(T/τ − 1 + e^{−T/τ})``; for equal lengths these are window_noise's
  formulas.
"""

from __future__ import annotations

import numpy as np

from rlgsim.estimators.identify.allan_noise import NoiseFit
from rlgsim.estimators.identify.window_noise import flicker_bank

__all__ = ["segment_mean_covariance", "segment_covariance_from_fit",
           "gauss_markov_segment_covariance"]


def _gm_same(var: float, T: np.ndarray, tau: float) -> np.ndarray:
    x = T / tau
    small = x < 1e-4
    xs = np.where(small, 1.0, x)
    full = 2.0 * var * (xs - 1.0 + np.exp(-xs)) / xs ** 2
    return np.where(small, var * (1.0 - x / 3.0), full)


def gauss_markov_segment_covariance(starts_s: np.ndarray, lengths_s: np.ndarray, var: float,
                                    tau_s: float) -> np.ndarray:
    """Covariance of the means over non-overlapping segments of a stationary Gauss–Markov
    process of variance ``var`` and correlation time ``tau_s`` (module docstring)."""
    s = np.asarray(starts_s, dtype=float)
    T = np.asarray(lengths_s, dtype=float)
    first = s[:, None] <= s[None, :]
    gap = np.maximum(np.where(first, s[None, :] - (s[:, None] + T[:, None]),
                              s[:, None] - (s[None, :] + T[None, :])), 0.0)
    f = -np.expm1(-T / tau_s) * tau_s / T                    # (1 − e^{−T/τ})·τ/T
    out = var * np.exp(-gap / tau_s) * f[:, None] * f[None, :]
    np.fill_diagonal(out, _gm_same(var, T, tau_s))
    return out


def segment_mean_covariance(starts_s: np.ndarray, lengths_s: np.ndarray, *, n: float = 0.0,
                            b: float = 0.0, k: float = 0.0, q: float = 0.0,
                            tau_min_s: float = 2.0, tau_max_s: float = 1.0e5,
                            per_decade: int = 2) -> np.ndarray:
    """(m, m) covariance [(°/h)²] of the mean rate noise over non-overlapping segments
    ``[starts_s, starts_s + lengths_s)`` (module docstring)."""
    s = np.asarray(starts_s, dtype=float)
    T = np.asarray(lengths_s, dtype=float)
    if s.shape != T.shape or s.ndim != 1:
        raise ValueError("starts_s and lengths_s must be 1-D of the same length")
    if np.any(T <= 0):
        raise ValueError("segment lengths must be positive")
    m = s.size
    cov = np.zeros((m, m))
    cov[np.diag_indices(m)] += n ** 2 / T + 2.0 * q ** 2 / T ** 2
    first = s[:, None] <= s[None, :]                         # i starts first
    s_e = np.where(first, s[:, None], s[None, :])            # earlier segment's start, length
    T_e = np.where(first, T[:, None], T[None, :])
    s_l = np.where(first, s[None, :], s[:, None])            # later segment's start
    gap = s_l - (s_e + T_e)
    if np.any(gap[~np.eye(m, dtype=bool)] < -1e-9 * (1.0 + np.abs(s_l[~np.eye(m, dtype=bool)]))):
        raise ValueError("segments must not overlap")
    gap = np.maximum(gap, 0.0)
    if k > 0:
        cov += k ** 2 * (s_e + T_e / 2.0)
        cov[np.diag_indices(m)] -= k ** 2 * T / 6.0
    for var, tau in flicker_bank(b, tau_min_s, tau_max_s, per_decade):
        cov += gauss_markov_segment_covariance(s, T, var, tau)
    return cov


def segment_covariance_from_fit(noise: NoiseFit, starts_s: np.ndarray, lengths_s: np.ndarray,
                                *, tau_min_s: float = 2.0, tau_max_s: float = 1.0e5,
                                per_decade: int = 2) -> np.ndarray:
    """:func:`segment_mean_covariance` with the levels of an Allan fit (preset units converted
    as :func:`rlgsim.estimators.identify.window_noise.covariance_from_fit` does)."""
    v = noise.values
    return segment_mean_covariance(starts_s, lengths_s, n=60.0 * v["arw_deg_per_sqrt_h"],
                                   b=v["bi_deg_per_h"], k=v["rrw_deg_per_h_per_sqrt_h"] / 60.0,
                                   q=v["q_arcsec"], tau_min_s=tau_min_s, tau_max_s=tau_max_s,
                                   per_decade=per_decade)
