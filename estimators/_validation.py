"""Input and parameter checks shared by every estimator.

scikit-learn's ``validate_data``/``check_array`` already reject NaN/inf, ragged and mismatched
inputs with clear ``ValueError`` messages; these add what compensators need beyond that:

* training data: :func:`validate_fit_input` (float64, matching lengths, enough samples, no
  constant input column), :func:`check_min_samples`, :func:`check_folds`,
  :func:`check_not_constant`, and the input :func:`standardisation` of the kernel models;
* parameters: :func:`check_positive` (a positive number, a number in ``(0, upper)``, or an
  integer ``>= minimum``, optionally ``None``), :func:`check_positive_grid` (a grid of them),
  :func:`check_positive_range` (a ``(low, high)`` search range with ``0 < low < high``) and
  :func:`check_bounds` (box bounds of an optimiser).

Every check raises ``ValueError`` with one line that names the parameter or input, the value and
what is allowed.
"""

from __future__ import annotations

import math
from numbers import Integral
from typing import Any, Callable, Sequence

import numpy as np
from sklearn.utils.validation import validate_data

# --------------------------------------------------------------------------------------------
# training data
# --------------------------------------------------------------------------------------------


def check_min_samples(n_samples: int, needed: int, what: str) -> None:
    """Raise ``ValueError`` if there are fewer than ``needed`` samples for ``what``."""
    if n_samples < needed:
        noun = "sample" if n_samples == 1 else "samples"
        raise ValueError(f"{what} needs at least {needed} samples, got {n_samples} {noun}")


def check_folds(n_samples: int, n_folds: int) -> None:
    """Raise ``ValueError`` if ``n_samples`` cannot be split into ``n_folds`` non-empty folds."""
    if n_folds < 2:
        raise ValueError(f"cross-validation needs at least 2 folds, got {n_folds}")
    if n_samples < n_folds:
        raise ValueError(f"too few samples for {n_folds}-fold cross-validation: {n_samples} "
                         f"samples, need at least {n_folds}")


def check_not_constant(X: np.ndarray, names: Sequence[str] | None = None) -> None:
    """Raise ``ValueError`` naming every input column that is constant (zero variance)."""
    X = np.asarray(X)
    if X.ndim == 1:
        X = X[:, None]
    constant = np.flatnonzero(np.ptp(X, axis=0) == 0)
    if constant.size:
        labels = [names[i] if names else f"column {i}" for i in constant]
        raise ValueError(f"constant input ({', '.join(labels)}): a constant input carries no "
                         "information; remove it")


def validate_fit_input(estimator: Any, X: Any, y: Any, *, model: str | None = None,
                       input_names: Callable[[int], Sequence[str]] | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Training data of ``estimator.fit``: finite float64 ``X`` (n, d) and ``y`` (n,), matching
    lengths, at least 2 samples, no constant input column.

    Builds on scikit-learn's ``validate_data`` (NaN/inf, shapes, lengths; sets
    ``n_features_in_`` and, for a DataFrame, ``feature_names_in_``), then
    :func:`check_not_constant`. ``model`` names the estimator in the too-few-samples message
    ("RVR needs at least 2 samples, got 1 sample"; default: scikit-learn's message).
    ``input_names(n_features)`` names the columns in the constant-input message (default: the
    DataFrame's column names, else "column i").
    """
    X, y = validate_data(estimator, X, y, dtype=np.float64, y_numeric=True,
                         ensure_min_samples=2 if model is None else 1)
    if model is not None:
        check_min_samples(X.shape[0], 2, model)
    y = np.asarray(y, dtype=np.float64)  # integer targets: residuals must not be truncated
    if input_names is not None:
        names = list(input_names(X.shape[1]))
    else:
        names = list(map(str, getattr(estimator, "feature_names_in_", []))) or None
    check_not_constant(X, names)
    return X, y


def standardisation(X: np.ndarray, standardize: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Column means and standard deviations (``ddof=0``) of the training inputs ``X``, or
    ``0``/``1`` when ``standardize`` is false; ``z = (x - mean) / scale``.

    A column that is not constant but whose standard deviation underflows (it would divide by
    ~0) raises ``ValueError`` like a constant one.
    """
    if not standardize:
        return np.zeros(X.shape[1]), np.ones(X.shape[1])
    mean = X.mean(axis=0)
    scale = X.std(axis=0)
    tiny = scale <= np.finfo(float).tiny * np.maximum(1.0, np.abs(mean))
    if np.any(tiny):
        raise ValueError(f"constant input (column {', '.join(map(str, np.flatnonzero(tiny)))}): "
                         "a constant input carries no information; remove it")
    return mean, scale


# --------------------------------------------------------------------------------------------
# parameters
# --------------------------------------------------------------------------------------------

def check_positive(value: Any, name: str, *, integer: bool = False, minimum: int = 1,
                   upper: float | None = None, allow_none: bool = False) -> Any:
    """``value`` checked and converted, else ``ValueError`` naming ``name``.

    By default a finite number > 0 (and < ``upper`` when given), returned as ``float``; anything
    ``float()`` reads except a bool is accepted. With ``integer``: an integer (Python or numpy,
    not a bool) >= ``minimum``, returned as ``int``. ``None`` is returned as is when
    ``allow_none``.
    """
    if value is None and allow_none:
        return None
    if integer:
        if isinstance(value, bool) or not isinstance(value, Integral) or value < minimum:
            either = "None or " if allow_none else ""
            raise ValueError(f"{name} must be {either}an integer >= {minimum}, got {value!r}")
        return int(value)
    try:
        if isinstance(value, bool):
            raise TypeError("a bool is not a number here")
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0 and (upper is None or v < upper)):
        below = "" if upper is None else f" and < {upper}"
        raise ValueError(f"{name} must be a finite number > 0{below}, got {value!r}")
    return v


def check_positive_grid(values: Any, name: str) -> np.ndarray:
    """A non-empty 1-D grid of finite positive numbers (float array), else ``ValueError``."""
    arr = np.atleast_1d(np.asarray(values, dtype=object))
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence of numbers > 0, got {values!r}")
    return np.array([check_positive(v, f"each value of {name}") for v in arr])


def check_positive_range(value: Any, name: str) -> tuple[float, float]:
    """A ``(low, high)`` pair with ``0 < low < high``, both finite (a log-uniform search range),
    returned as floats, else ``ValueError`` naming ``name``."""
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a (low, high) pair of positive numbers, "
                         f"got {value!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo < hi):
        raise ValueError(f"{name} must satisfy 0 < low < high (finite), got {value!r}")
    return lo, hi


def check_bounds(bounds: Any) -> tuple[np.ndarray, np.ndarray]:
    """Box bounds given as a sequence of ``(low, high)`` pairs, one per dimension.

    Returns ``(lower, upper)`` float arrays of shape ``(d,)``; raises ``ValueError`` naming the
    offending dimension for non-finite values or ``low >= high``.
    """
    b = np.asarray(bounds, dtype=float)
    if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] < 1:
        raise ValueError(f"bounds must be a sequence of (low, high) pairs, one per dimension; "
                         f"got an array of shape {b.shape}")
    for i, (lo, hi) in enumerate(b):
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ValueError(f"bounds of dimension {i} must be finite, got ({lo}, {hi})")
        if not lo < hi:
            raise ValueError(f"bounds of dimension {i} need low < high, got ({lo}, {hi})")
    return b[:, 0].copy(), b[:, 1].copy()
