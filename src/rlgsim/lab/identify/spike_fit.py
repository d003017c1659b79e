"""Read-out spikes of a recording: single samples whose pulse count jumps by several pulses
above its neighbours (the simulator's ``[anomalies] pulse_spikes``: one sample of one gyro
channel gets ±1…``max_pulses`` extra counts, sizes uniform, Poisson in time; sim/sensors/anomalies.py).

Found at the gyro's own sample rate, not in the 100 s windows: the pulse count per sample
(``rate × scale factor / sample rate``) minus its running median over 31 samples is the
quantisation (at most about ±1 pulse for a counter that carries its phase) plus the white
rate noise; a sample at least :data:`MIN_PULSES` pulses (and 8 robust standard deviations)
away is a spike. Only powered samples count. Spikes of 1–2 pulses hide in the quantisation,
so the rate is the count divided by the powered hours and by the fraction of the size
distribution that can be seen, ``(M − s_min + 1)/M`` with ``M`` the largest size seen (the
maximum-likelihood ``max_pulses`` of a uniform size) and ``s_min`` the smallest visible size;
the 95 % interval is Garwood's exact Poisson interval of the count (Garwood 1936) scaled the
same way. The 100 s windows the law fit leaves out as outliers (5.5σ innovations) are the
largest of these; the report gives both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["SpikeFit", "find_spikes", "MIN_PULSES"]

#: smallest |count − running median| [pulses] taken as a spike: a counter's quantisation moves
#: a count by at most about one pulse from its neighbours, two with noise on top
MIN_PULSES = 3


@dataclass(frozen=True)
class SpikeFit:
    """Spikes found: their times [s] and sizes [pulses], the powered hours searched, the
    threshold [pulses], the estimated ``max_pulses`` and rate [1/h] with its 95 % interval
    (None when none was found: the rate's upper bound is then ``rate_ci95_per_h[1]``)."""

    times_s: tuple[float, ...]
    sizes: tuple[int, ...]
    powered_h: float
    threshold_pulses: int
    max_pulses: int | None
    rate_per_h: float
    rate_ci95_per_h: tuple[float, float]


def _garwood(k: int) -> tuple[float, float]:
    from scipy.stats import chi2
    lo = 0.0 if k == 0 else float(chi2.ppf(0.025, 2 * k) / 2.0)
    return lo, float(chi2.ppf(0.975, 2 * k + 2) / 2.0)


def find_spikes(rate_deg_per_h: np.ndarray, sample_rate_hz: float, pulses_per_arcsec: float,
                powered: np.ndarray) -> SpikeFit:
    """Spikes of a gyro rate series (°/h = arcsec/s per sample) with ``powered`` (N,) bool
    (module docstring)."""
    from rlgsim.lab.identify._median_kernel import rolling_median   # pandas' rolling median
    rate = np.asarray(rate_deg_per_h, dtype=float)
    ok = np.asarray(powered, dtype=bool) & np.isfinite(rate)
    counts = rate * pulses_per_arcsec / float(sample_rate_hz)
    med = rolling_median(np.where(ok, counts, np.nan), 31, 5)
    r = counts - med
    good = ok & np.isfinite(r)
    mad = float(np.median(np.abs(r[good] - np.median(r[good])))) if good.any() else 0.0
    thr = max(float(MIN_PULSES), 8.0 * 1.4826 * mad)
    # a spike is a whole number of pulses: the smallest counted size, and the same rule for
    # the selection and the reported threshold (sizes below smin are never counted)
    smin = int(math.ceil(thr - 0.5))
    whole = np.rint(np.where(good, r, 0.0))
    hits = np.flatnonzero(good & (np.abs(whole) >= smin))
    sizes = tuple(int(v) for v in whole[hits])
    times = tuple(float((i + 1) / sample_rate_hz) for i in hits)
    hours = float(ok.sum() / sample_rate_hz / 3600.0)
    k = len(hits)
    lo, hi = _garwood(k)
    if k:
        M = max(abs(s) for s in sizes)
        frac = max(M - smin + 1, 1) / M
        return SpikeFit(times, sizes, hours, smin, M, k / hours / frac,
                        (lo / hours / frac, hi / hours / frac))
    return SpikeFit((), (), hours, smin, None, 0.0, (0.0, hi / max(hours, 1e-9)))
