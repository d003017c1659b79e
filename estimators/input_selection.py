"""Correlation-based choice of compensator inputs: rank by |Pearson r| with the target, keep the
strong ones.

Paper 001 Table 1 ranks T, dT/dt and UHFO by their correlation with the gyro output
(0.71, −0.43, −0.82); paper 003 §4.3 keeps the probe-pair gradients whose correlation with the
bias exceeds 0.90.  Pearson's r comes from ``sklearn.feature_selection.r_regression``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from sklearn.base import BaseEstimator
from sklearn.feature_selection import SelectorMixin, r_regression
from sklearn.utils.validation import check_array, check_consistent_length, check_is_fitted, \
    validate_data

from rlgsim.estimators._validation import check_not_constant
from rlgsim.estimators.columns import Columns, resolve_input_names


class RankedInput(NamedTuple):
    """One candidate input: its name and Pearson correlation with the target (−1 … 1)."""

    name: str
    r: float


def _correlations(X: np.ndarray, y: np.ndarray, names: Sequence[str]) -> np.ndarray:
    check_not_constant(X, list(names))
    if np.ptp(y) == 0:
        raise ValueError("constant target y: its correlation with any input is undefined")
    return r_regression(X, y)


def correlation_ranking(X: Columns | ArrayLike, y: ArrayLike,
                        feature_names: Sequence[str] | None = None) -> list[RankedInput]:
    """Candidate inputs sorted by decreasing |r| with ``y`` (ties keep the input order).

    ``X`` is a :class:`Columns` (names taken from it) or a 2-D array (n_samples, n_inputs)
    with optional ``feature_names``.  Raises ``ValueError`` for NaN/inf, mismatched lengths,
    fewer than 3 samples, or a constant input/target (r undefined).
    """
    Xa = check_array(X, dtype=np.float64, input_name="X", ensure_min_samples=3)
    names = resolve_input_names(X, feature_names, Xa.shape[1])
    ya = check_array(y, ensure_2d=False, dtype=np.float64, input_name="y")
    if ya.ndim != 1:
        raise ValueError(f"y must be 1-D, got shape {ya.shape}")
    check_consistent_length(Xa, ya)
    r = _correlations(Xa, ya, names)
    order = np.argsort(-np.abs(r), kind="stable")
    return [RankedInput(names[i], float(r[i])) for i in order]


def select_by_correlation(X: Columns | ArrayLike, y: ArrayLike, threshold: float,
                          feature_names: Sequence[str] | None = None) -> list[RankedInput]:
    """The inputs with ``|r| ≥ threshold``, strongest first (paper 003 uses 0.90)."""
    if not 0.0 <= threshold <= 1.0:
        raise ValueError(f"threshold must be in [0, 1], got {threshold}")
    return [c for c in correlation_ranking(X, y, feature_names) if abs(c.r) >= threshold]


class CorrelationSelector(SelectorMixin, BaseEstimator):
    """scikit-learn selector keeping the inputs with ``|Pearson r| ≥ threshold`` with ``y``.

    Use it in a ``Pipeline`` so the inputs chosen on the training run are the ones applied to
    the test run.  ``max_features`` additionally caps the count (strongest kept).

    Attributes
    ----------
    correlations_ : ndarray (n_features_in_,)  Pearson r of each input with y.
    ranking_ : list[RankedInput]  All inputs, strongest first.
    selected_names_ : tuple[str, ...]  Names of the kept inputs, strongest first.
    input_names_ : tuple[str, ...]  Names of all inputs (``feature_names``, a
        :class:`Columns`' names, or ``x0, x1, ...``).
    """

    def __init__(self, threshold: float = 0.5, max_features: int | None = None,
                 feature_names: Sequence[str] | None = None):
        self.threshold = threshold
        self.max_features = max_features
        self.feature_names = feature_names

    def fit(self, X: Any, y: Any) -> CorrelationSelector:
        """Compute the correlations and the kept set; returns self."""
        if not 0.0 <= self.threshold <= 1.0:
            raise ValueError(f"threshold must be in [0, 1], got {self.threshold}")
        if self.max_features is not None and self.max_features < 1:
            raise ValueError(f"max_features must be >= 1 or None, got {self.max_features}")
        names_source = X
        X, y = validate_data(self, X, y, dtype=np.float64, y_numeric=True, ensure_min_samples=3)
        self.input_names_ = resolve_input_names(names_source, self.feature_names, X.shape[1])
        self.correlations_ = _correlations(X, y, self.input_names_)
        order = np.argsort(-np.abs(self.correlations_), kind="stable")
        self.ranking_ = [RankedInput(self.input_names_[i], float(self.correlations_[i]))
                         for i in order]
        kept = [i for i in order if abs(self.correlations_[i]) >= self.threshold]
        if self.max_features is not None:
            kept = kept[: self.max_features]
        mask = np.zeros(X.shape[1], dtype=bool)
        mask[kept] = True
        self.support_ = mask
        self.selected_names_ = tuple(self.input_names_[i] for i in kept)
        return self

    def transform(self, X: Any) -> Any:
        """The kept inputs (in their original order); a :class:`Columns` stays a
        :class:`Columns` so the next estimator in a pipeline still knows their names."""
        out = super().transform(X)
        if isinstance(X, Columns) and isinstance(out, np.ndarray):
            return Columns.from_array(out, [n for n, keep in zip(self.input_names_,
                                                                 self.support_) if keep])
        return out

    def _get_support_mask(self) -> np.ndarray:
        check_is_fitted(self, "support_")
        return self.support_

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.required = True
        return tags
