"""Weight functions and robust residual scale for iteratively re-weighted LS-SVM.

All functions act on *standardised* residuals ``r = e / s`` (dimensionless), where ``e`` are the
residuals of a fit (in the units of the target, e.g. rad/s for a gyro bias) and ``s`` is a robust
estimate of their standard deviation (same units) from :func:`robust_scale`.

Sources
-------
- Paper 001 (``shared/papers/001_*.txt``) §2.3, eqs. (15)-(20): the four weight functions and the
  two robust scales.
- J.A.K. Suykens, J. De Brabanter, L. Lukas, J. Vandewalle, "Weighted least squares support
  vector machines: robustness and sparse approximation", Neurocomputing 48 (2002) 85-105
  (paper 001 ref. [25]): Hampel weights with c1 = 2.5, c2 = 3.
- K. De Brabanter, K. Pelckmans, J. De Brabanter, M. Debruyne, J.A.K. Suykens, M. Hubert,
  B. De Moor, "Robustness of kernel based regression: a comparison of iterative weighting
  schemes", ICANN 2009, LNCS 5768, 100-110 ("robustified LS-SVM"): Huber, Hampel, Logistic and
  Myriad weights in the IRLS loop.

The weights are one-line closed forms of those papers; scipy supplies the order statistics
(``scipy.stats.iqr``, ``scipy.stats.median_abs_deviation``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy import stats

#: Normal consistency constant of the IQR scale, paper 001 eq. (19): s = IQR / (2 * 0.6745).
IQR_DIVISOR = 2.0 * 0.6745
#: Normal consistency constant of the MAD scale, paper 001 eq. (20): s = 1.483 * MAD.
MAD_FACTOR = 1.483

WEIGHT_FUNCTIONS = ("huber", "hampel", "logistic", "myriad")
SCALES = ("mad", "iqr")


def robust_scale(e: np.ndarray, method: str = "mad") -> float:
    """Robust standard deviation of residuals ``e`` (same unit as ``e``).

    ``"iqr"``: ``IQR / (2 * 0.6745)`` (paper 001 eq. 19); ``"mad"``: ``1.483 * MAD`` with the
    median absolute deviation about the median (paper 001 eq. 20). Both equal the standard
    deviation for Gaussian residuals and ignore up to 25 % (IQR) or 50 % (MAD) gross errors.
    """
    e = np.asarray(e, dtype=float).ravel()
    if method == "mad":
        return float(MAD_FACTOR * stats.median_abs_deviation(e, scale=1.0))
    if method == "iqr":
        return float(stats.iqr(e) / IQR_DIVISOR)
    raise ValueError(f"unknown robust scale {method!r}; allowed: {', '.join(SCALES)}")


def huber_weights(r: np.ndarray, beta: float) -> np.ndarray:
    """Huber weights, paper 001 eq. (15): ``1`` if ``|r| < beta`` else ``beta / |r|``.

    ``beta`` (dimensionless, > 0) is the corner of the Huber loss in robust-scale units; 1.345
    gives 95 % efficiency at the normal model.
    """
    if not beta > 0:
        raise ValueError(f"Huber parameter beta must be > 0, got {beta}")
    a = np.abs(np.asarray(r, dtype=float))
    return np.where(a < beta, 1.0, beta / np.maximum(a, beta))


def hampel_weights(r: np.ndarray, c1: float = 2.5, c2: float = 3.0) -> np.ndarray:
    """Hampel weights, paper 001 eq. (16) with Suykens et al. (2002) defaults c1 = 2.5, c2 = 3.

    ``1`` if ``|r| < c1``; ``(c2 - |r|) / (c2 - c1)`` if ``c1 <= |r| <= c2``; ``0`` if ``|r| > c2``.
    """
    if not 0 < c1 < c2:
        raise ValueError(f"Hampel parameters need 0 < c1 < c2, got c1={c1}, c2={c2}")
    a = np.abs(np.asarray(r, dtype=float))
    return np.clip((c2 - a) / (c2 - c1), 0.0, 1.0)


def logistic_weights(r: np.ndarray) -> np.ndarray:
    """Logistic weights, paper 001 eq. (17): ``tanh(r) / r`` (1 at ``r = 0``)."""
    r = np.asarray(r, dtype=float)
    small = np.abs(r) < 1e-8
    safe = np.where(small, 1.0, r)
    return np.where(small, 1.0, np.tanh(safe) / safe)


def myriad_weights(r: np.ndarray, delta: float) -> np.ndarray:
    """Myriad weights, paper 001 eq. (18): ``delta**2 / (delta**2 + r**2)``.

    ``delta`` (dimensionless, > 0) is the linearity parameter of the myriad (Cauchy) loss.
    """
    if not delta > 0:
        raise ValueError(f"Myriad parameter delta must be > 0, got {delta}")
    r = np.asarray(r, dtype=float)
    return delta**2 / (delta**2 + r**2)


def weight_function(name: str, param: float | None = None, c1: float = 2.5,
                    c2: float = 3.0) -> Callable[[np.ndarray], np.ndarray]:
    """The weight function ``name`` as a callable of standardised residuals.

    ``param`` is Huber's ``beta`` or Myriad's ``delta`` (required for those two, and must be
    ``None`` for the others); ``c1``, ``c2`` are Hampel's breakpoints.
    """
    if name not in WEIGHT_FUNCTIONS:
        raise ValueError(f"unknown weight function {name!r}; "
                         f"allowed: {', '.join(WEIGHT_FUNCTIONS)}")
    if name in ("huber", "myriad"):
        if param is None:
            raise ValueError(f"the {name} weight function needs its parameter")
        return (lambda r: huber_weights(r, param)) if name == "huber" else (
            lambda r: myriad_weights(r, param))
    if param is not None:
        raise ValueError(f"weight_param applies to the huber and myriad weights only, not to "
                         f"{name!r} (got weight_param={param})")
    if name == "hampel":
        hampel_weights(np.zeros(1), c1, c2)  # validates c1, c2 now
        return lambda r: hampel_weights(r, c1, c2)
    return logistic_weights
