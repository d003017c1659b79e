"""Compensator inputs from raw channels: window means, temperature rate, probe-pair gradients.

All papers smooth before modelling: gyro output and temperatures are averaged over
non-overlapping 100 s windows (paper 001 §3, paper 002 §4.1 "a simple averaging filter with
100 s", paper 003 step 1(3) "averaging each 100-data chunk").  Paper 001 also uses the slope of
the temperature (dT/dt) and the high-frequency-oscillator voltage UHFO; paper 003 uses the
temperature differences between all pairs of its eight thermometers A–H (28 pairs).

Conventions (docs/contributing.md): samples are equally spaced at ``rate_hz``; sample ``k``
covers ``[k/f, (k+1)/f)``.  Window ``j`` holds samples ``j·m … (j+1)·m − 1`` with
``m = window_s·rate_hz`` (a whole number), i.e. it covers ``[j·W, (j+1)·W)`` and its time
coordinate is the window's end ``(j+1)·W`` (:func:`window_end_times`).  **A partial window at
the end is dropped** — its mean would have a different variance and bias the statistics.
UHFO (V) and any other channel are simply window-averaged like the temperatures.

The per-window slope is the closed-form ordinary-least-squares slope (e.g. Montgomery, Peck &
Vining, *Introduction to Linear Regression Analysis*, eq. 2.11); it is written out here because
``scipy.stats.linregress`` fits one series per call and this needs thousands of windows at once.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import combinations

import numpy as np
from numpy.typing import ArrayLike
from sklearn.utils.validation import check_array

from rlgsim.estimators.columns import Columns

__all__ = [
    "Columns", "samples_per_window", "window_average", "window_end_times", "temperature_rate",
    "pairwise_gradients", "window_features",
]


def samples_per_window(rate_hz: float, window_s: float) -> int:
    """Whole number of samples ``m = window_s · rate_hz`` in one window.

    Raises ``ValueError`` if either is not positive and finite, or if the window is not a whole
    number of samples (to within 1e-6 sample).
    """
    for label, value in (("rate_hz", rate_hz), ("window_s", window_s)):
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{label} must be positive and finite, got {value}")
    m = window_s * rate_hz
    m_int = int(round(m))
    if m_int < 1 or abs(m - m_int) > 1e-6:
        raise ValueError(f"a {window_s} s window at {rate_hz} Hz is {m:g} samples; it must be a "
                         "whole number of samples (at least 1)")
    return m_int


def _as_samples(x: ArrayLike, what: str) -> np.ndarray:
    """Finite float64 1-D or 2-D array (samples along axis 0); ValueError naming ``what``."""
    arr = np.asarray(x)
    if arr.ndim not in (1, 2):
        raise ValueError(f"{what} must be 1-D (n_samples,) or 2-D (n_samples, n_channels), "
                         f"got shape {arr.shape}")
    if (arr.dtype == np.float64 and arr.size >= 1 and np.isfinite(arr).all()):
        return arr      # already what check_array would return; its checks cost more than a mean
    return check_array(arr, ensure_2d=False, dtype=np.float64, input_name=what,
                       ensure_min_samples=1)


def _windows(arr: np.ndarray, m: int, what: str, min_per_window: int = 1) -> np.ndarray:
    """View of ``arr`` as (n_windows, m, ...) with the partial last window dropped."""
    if m < min_per_window:
        raise ValueError(f"{what} needs at least {min_per_window} samples per window, got {m}")
    n_windows = arr.shape[0] // m
    if n_windows == 0:
        raise ValueError(f"{what} has {arr.shape[0]} samples, fewer than one window of {m}")
    return arr[: n_windows * m].reshape((n_windows, m) + arr.shape[1:])


def window_average(x: ArrayLike | Columns, rate_hz: float,
                   window_s: float = 100.0) -> np.ndarray | Columns:
    """Means over non-overlapping windows of ``window_s`` seconds (partial last window dropped).

    Parameters
    ----------
    x
        Samples at ``rate_hz``: shape (n,), (n, k), or a :class:`Columns` (every column is
        averaged, names kept).  Any unit; the means carry the same unit.
    rate_hz
        Sample rate (Hz).
    window_s
        Window length (s); 100 s in papers 001–003.  Must be a whole number of samples.

    Returns
    -------
    Window means, shape (n // m,) / (n // m, k) / :class:`Columns`, ``m = window_s·rate_hz``.
    """
    m = samples_per_window(rate_hz, window_s)
    if isinstance(x, Columns):
        means = window_average(x.values, rate_hz, window_s)
        return Columns.from_array(means, x.names)
    arr = _as_samples(x, "x")
    return _windows(arr, m, "window_average").mean(axis=1)


def window_end_times(n_samples: int, rate_hz: float, window_s: float = 100.0) -> np.ndarray:
    """Time coordinate (s from run start) of each complete window: its end ``(j+1)·window_s``."""
    m = samples_per_window(rate_hz, window_s)
    n_windows = n_samples // m
    return (np.arange(n_windows) + 1) * (m / rate_hz)


def temperature_rate(temperature: ArrayLike | Columns, rate_hz: float,
                     window_s: float = 100.0) -> np.ndarray | Columns:
    """Temperature rate dT/dt (K/s) per window: the least-squares slope of T against time.

    For each non-overlapping window of ``m = window_s·rate_hz`` samples (partial last window
    dropped) with times ``t_k = k/rate_hz``::

        dT/dt = Σ (t_k − t̄)(T_k − T̄) / Σ (t_k − t̄)²        [K/s]

    The slope uses every sample in the window, so it is much less noisy than the end-point
    difference (paper 001 §3 describes "the temperature difference per unit time, at intervals
    of 100 s").  Multiply by 60 for K/min (the chamber-rate unit in the scenarios).

    Parameters
    ----------
    temperature
        Temperatures (°C) at ``rate_hz``: (n,), (n, k), or :class:`Columns`; a table's
        column ``name`` becomes ``"d{name}/dt"`` (e.g. ``"T"`` → ``"dT/dt"``).
    rate_hz, window_s
        As for :func:`window_average`; a window needs at least 2 samples.
    """
    m = samples_per_window(rate_hz, window_s)
    if isinstance(temperature, Columns):
        slopes = temperature_rate(temperature.values, rate_hz, window_s)
        return Columns.from_array(slopes, [f"d{n}/dt" for n in temperature.names])
    arr = _as_samples(temperature, "temperature")
    win = _windows(arr, m, "temperature_rate", min_per_window=2)
    t = (np.arange(m) - (m - 1) / 2.0) / rate_hz           # centred times, s
    t = t.reshape((1, m) + (1,) * (arr.ndim - 1))
    dev = win - win.mean(axis=1, keepdims=True)
    return (t * dev).sum(axis=1) / (t * t).sum()


def pairwise_gradients(temperatures: Columns | Mapping[str, ArrayLike] | ArrayLike,
                       names: Sequence[str] | None = None) -> Columns:
    """Temperature differences between every pair of probes (K): ``T_a − T_b`` for a before b.

    Paper 003 (§3.3 step 1(2), §4.2, Table 3) correlates the bias with the gradients between
    all pairs of its eight thermometers A–H: ``8·7/2 = 28`` pairs.  Pair ``(a, b)`` is named
    ``"a-b"``; the order of the probes fixes the sign.

    Parameters
    ----------
    temperatures
        Probe temperatures (°C): a :class:`Columns`, a ``{name: values}`` mapping, or a 2-D
        array (n_samples, n_probes) with ``names``.  Raw samples or window means both work
        (the difference of means equals the mean of differences).
    names
        Probes to use, in order; default all columns of a table/mapping.  Required for arrays.
    """
    if isinstance(temperatures, Columns):
        table = temperatures if names is None else temperatures.select(names)
    elif isinstance(temperatures, Mapping):
        table = Columns(temperatures)
        if names is not None:
            table = table.select(names)
    else:
        if names is None:
            raise ValueError("pairwise_gradients needs names for an array of probe temperatures")
        table = Columns.from_array(temperatures, names)
    if len(table) < 2:
        raise ValueError(f"pairwise gradients need at least 2 probes, got {len(table)}")
    values = check_array(table.values, dtype=np.float64, input_name="temperatures")
    idx = {n: i for i, n in enumerate(table.names)}
    return Columns((f"{a}-{b}", values[:, idx[a]] - values[:, idx[b]])
                   for a, b in combinations(table.names, 2))


def window_features(raw: Columns, rate_hz: float, window_s: float = 100.0, *,
                    rate_of: Sequence[str] = (),
                    gradients_of: Sequence[str] = ()) -> Columns:
    """The model table of papers 001–003 from raw channels sampled at ``rate_hz``.

    Returns the window means of every column of ``raw`` (temperatures, UHFO, the gyro bias ...),
    then ``d{name}/dt`` (K/s, :func:`temperature_rate`) for each name in ``rate_of``, then the
    pairwise gradients (K, :func:`pairwise_gradients` of the window means) among
    ``gradients_of``.  Paper 001: ``rate_of=("T",)`` with columns T, UHFO, B; paper 003:
    ``gradients_of=("A", ..., "H")``.
    """
    means = window_average(raw, rate_hz, window_s)
    table = means
    if rate_of:
        table = table.with_columns(temperature_rate(raw.select(rate_of), rate_hz, window_s))
    if gradients_of:
        table = table.with_columns(pairwise_gradients(means, gradients_of))
    return table
