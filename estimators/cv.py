"""Validation splits for drift data: contiguous-in-time k-fold and hold-out tail.

Rows are taken to be in time order (a temperature ramp, a calibration sequence). Shuffled folds
leak on drift data: a validation point then always has training neighbours a few minutes away on
both sides, so the fitness rewards interpolation of the noise and picks over-flexible models.
The default is therefore contiguous blocks — scikit-learn's ``KFold(shuffle=False)`` — with
shuffling (``KFold(shuffle=True)``) as an option (paper 000 §3.2 step 2 splits "randomly").
A hold-out is the last ``fraction`` of the rows (or a random subset when shuffled).
"""

from __future__ import annotations

from numbers import Integral, Real

import numpy as np
from sklearn.model_selection import KFold
from sklearn.utils import check_random_state

from rlgsim.estimators._validation import check_folds, check_min_samples

Split = tuple[np.ndarray, np.ndarray]


def time_kfold(n_samples: int, n_folds: int = 5, shuffle: bool = False,
               random_state=None) -> list[Split]:
    """``(train, test)`` index pairs of k-fold CV; contiguous blocks unless ``shuffle``."""
    check_folds(n_samples, n_folds)
    rs = check_random_state(random_state) if shuffle else None
    splitter = KFold(n_splits=int(n_folds), shuffle=bool(shuffle), random_state=rs)
    return list(splitter.split(np.zeros((n_samples, 1))))


def holdout(n_samples: int, fraction: float = 0.2, shuffle: bool = False,
            random_state=None) -> list[Split]:
    """One ``(train, test)`` pair: the last ``fraction`` of the rows are the test set (a random
    subset of that size when ``shuffle``). Both sets are non-empty."""
    n_test = int(round(fraction * n_samples))
    check_min_samples(n_samples, 2, "a hold-out split")
    if not 1 <= n_test <= n_samples - 1:
        raise ValueError(f"hold-out fraction {fraction} of {n_samples} samples leaves an empty "
                         "training or validation set")
    if shuffle:
        perm = check_random_state(random_state).permutation(n_samples)
        test, train = np.sort(perm[:n_test]), np.sort(perm[n_test:])
    else:
        train, test = np.arange(n_samples - n_test), np.arange(n_samples - n_test, n_samples)
    return [(train, test)]


def validation_splits(n_samples: int, validation, shuffle: bool = False,
                      random_state=None) -> list[Split]:
    """``validation`` an integer k >= 2 -> k-fold (:func:`time_kfold`); a float in (0, 1) ->
    hold-out of that fraction (:func:`holdout`)."""
    if isinstance(validation, Integral) and not isinstance(validation, bool):
        return time_kfold(n_samples, int(validation), shuffle, random_state)
    if isinstance(validation, Real) and not isinstance(validation, bool) and 0 < validation < 1:
        return holdout(n_samples, float(validation), shuffle, random_state)
    raise ValueError(f"validation must be an integer number of folds >= 2 or a hold-out fraction "
                     f"in (0, 1), got {validation!r}")
