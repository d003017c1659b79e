"""Covariance of a gyro's window-mean bias noise from its Allan noise model, for a generalised
least-squares (GLS) fit of the bias law.

The bias of a window of length ``T`` is the mean rate over it. The law fit's residual carries
the gyro's noise, whose four Allan terms (:mod:`rlgsim.estimators.identify.allan_noise`; IEEE
Std 952-1997 Annex C, two-sided PSDs) give the covariance of the window means exactly:

- white rate noise N (ARW), PSD N²: ``Var = N²/T``, independent windows;
- quantisation Q (angle error e of variance Q², the window mean ``(e_end − e_start)/T``):
  ``Var = 2Q²/T²``, ``Cov = −Q²/T²`` between adjacent windows (σ²_A = 3Q²/τ²);
- rate random walk K (the rate a Brownian motion from 0 at the record's start s = 0, the
  turn-on bias belonging to the law's intercept): for windows starting at ``s_i ≤ s_j``,
  ``Cov = K²·(s_i + T/2)`` if disjoint, ``K²·(s_i + T/3)`` for the same window (the mean of
  ``min(t, t')`` over the two windows);
- flicker (bias instability) B, PSD B²/(2πf) between 1/(2πτ_max) and 1/(2πτ_min): the bank
  of first-order Gauss–Markov processes of correlation times spaced evenly in ln τ with
  variances ``q_j² = w_j·B²·Δ/π`` (Δ the ln τ spacing, ``w_j`` ½ at the two ends, 1 inside;
  Keshner, Proc. IEEE 70(3), 1982; Kasdin, Proc. IEEE 83(5), 1995, §IV — the construction the
  simulator's generator uses). A Gauss–Markov process of variance q² and correlation time τ
  averaged over windows a distance d ≥ T apart (start to start) has
  ``Cov = q²·(τ/T)²·e^{−d/τ}·(2 cosh(T/τ) − 2)`` and ``Var = 2q²·(τ/T)²·(T/τ − 1 + e^{−T/τ})``
  (integrate ``q² e^{−|t−t'|/τ}`` over both windows).

The flicker's long memory is what white-residual formulas miss: its processes slower than the
record shift every window alike, so they are an offset of unknown sign in the intercept and a
slow drift that mimics a temperature term. Beyond the record the band is not observable: it is
taken from the device template (``flicker_tau_min_s``, ``flicker_tau_max_s``,
``flicker_per_decade``; the simulator's defaults 2 s, 10⁵ s, 2), and the intercept's standard
error then counts the offset those slow processes add to one recording.

Units: rate in °/h, time in s; N in (°/h)·√s, B in °/h, K in (°/h)/√s, Q in (°/h)·s (arcsec).
"""

from __future__ import annotations

import math

import numpy as np

from rlgsim.estimators.identify.allan_noise import NoiseFit

__all__ = ["window_mean_covariance", "covariance_from_fit", "gauss_markov_window_covariance"]


def gauss_markov_window_covariance(starts_s: np.ndarray, window_s: float, var: float,
                                   tau_s: float) -> np.ndarray:
    """Covariance of the means over windows ``[s, s + T)`` of a stationary Gauss–Markov
    process of variance ``var`` and correlation time ``tau_s`` (module docstring)."""
    s = np.asarray(starts_s, dtype=float)
    T = float(window_s)
    x = T / tau_s
    d = np.abs(s[:, None] - s[None, :])
    if x < 1e-6:                                   # much slower than a window: plain samples
        return var * np.exp(-d / tau_s)
    # 2 cosh(x) − 2 written without cancellation; e^{−d/τ}·(…) for d ≥ T
    off = var * (2.0 * np.sinh(x / 2.0) / x) ** 2 * np.exp(-d / tau_s)
    same = 2.0 * var * (x - 1.0 + math.exp(-x)) / x ** 2 if x > 1e-3 else var * (1 - x / 3)
    out = np.where(d >= T, off, 0.0)
    # overlapping windows (d < T) do not occur for a window table; the same window does
    np.fill_diagonal(out, same)
    return out


def window_mean_covariance(starts_s: np.ndarray, window_s: float, *, n: float = 0.0,
                           b: float = 0.0, k: float = 0.0, q: float = 0.0,
                           tau_min_s: float = 2.0, tau_max_s: float = 1.0e5,
                           per_decade: int = 8) -> np.ndarray:
    """(m, m) covariance [(°/h)²] of the window means of white (``n``), flicker (``b``),
    rate random walk (``k``) and quantisation (``q``) noise for windows of ``window_s`` s
    starting at ``starts_s`` (a window table's rows, possibly with gaps)."""
    s = np.asarray(starts_s, dtype=float)
    T = float(window_s)
    m = s.size
    cov = np.zeros((m, m))
    cov[np.diag_indices(m)] += n ** 2 / T + 2.0 * q ** 2 / T ** 2
    if q > 0 and m > 1:
        adj = np.isclose(np.abs(s[:, None] - s[None, :]), T, rtol=0, atol=1e-6 * T)
        cov[adj] -= q ** 2 / T ** 2
    if k > 0:
        lo = np.minimum(s[:, None], s[None, :])
        cov += k ** 2 * (lo + T / 2.0)
        cov[np.diag_indices(m)] -= k ** 2 * T / 6.0
    for var, tau in flicker_bank(b, tau_min_s, tau_max_s, per_decade):
        cov += gauss_markov_window_covariance(s, T, var, tau)
    return cov


def flicker_bank(b: float, tau_min_s: float, tau_max_s: float,
                 per_decade: int) -> list[tuple[float, float]]:
    """The Gauss–Markov processes (variance [(°/h)²], correlation time [s]) whose sum stands
    for flicker of bias instability ``b`` [°/h] between ``tau_min_s`` and ``tau_max_s``:
    correlation times evenly spaced in log, ``per_decade`` per decade, each of variance
    ``b² Δ/π`` (Δ the log spacing; trapezoid weights at the ends) — the 1/f spectrum as a
    superposition of Lorentzians (Keshner 1982). Empty without flicker."""
    if not (b > 0 and tau_max_s > tau_min_s):
        return []
    j = max(2, int(round(math.log10(tau_max_s / tau_min_s) * per_decade)) + 1)
    taus = np.geomspace(tau_min_s, tau_max_s, j)
    delta = math.log(taus[1] / taus[0])
    w = np.ones(j)
    w[0] = w[-1] = 0.5
    return [(float(wj * b ** 2 * delta / math.pi), float(tau)) for tau, wj in zip(taus, w)]


def covariance_from_fit(noise: NoiseFit, starts_s: np.ndarray, window_s: float, *,
                        tau_min_s: float = 2.0, tau_max_s: float = 1.0e5,
                        per_decade: int = 2) -> np.ndarray:
    """:func:`window_mean_covariance` with the levels of an Allan fit (preset units converted
    to (°/h)·√s, °/h, (°/h)/√s, arcsec).

    The quantisation enters as independent window noise of the same variance 2Q²/T², without
    the negative covariance of neighbouring windows: with it, the mean of all windows is known
    to (two end errors)/record, and a law fit weighted by it treats every slow systematic error
    of the twin (a thermal state a few 10⁻⁴ off) as significant and adds terms to follow it
    (seen on a noise-free recording: a knee chosen besides the true three terms).

    For a pulse-counting gyro the fit's Q is the counter's, fixed from the pulse weight, and
    its N the white rate noise alone (:func:`~rlgsim.estimators.identify.allan_noise.fit_allan`
    with ``quantum_arcsec``): a fit with Q free over the short τ, where the counter's reading
    errors are still correlated, had given trplg_001 unit 1 a white window variance 2.6 × the
    true one (ARW 0.0013 against 0.0008 °/√h), weakening every standard error and the hop
    scan."""
    v = noise.values
    T = float(window_s)
    cov = window_mean_covariance(starts_s, T, n=60.0 * v["arw_deg_per_sqrt_h"],
                                 b=v["bi_deg_per_h"], k=v["rrw_deg_per_h_per_sqrt_h"] / 60.0,
                                 tau_min_s=tau_min_s, tau_max_s=tau_max_s,
                                 per_decade=per_decade)
    cov[np.diag_indices(cov.shape[0])] += 2.0 * v["q_arcsec"] ** 2 / T ** 2
    return cov
