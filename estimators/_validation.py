"""Input checks shared by every estimator.

scikit-learn's ``validate_data``/``check_array`` already reject NaN/inf, ragged and mismatched
inputs with clear ``ValueError`` messages; these add what compensators need beyond that.
"""

from __future__ import annotations

import numpy as np


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


def check_not_constant(X: np.ndarray, names: list[str] | None = None) -> None:
    """Raise ``ValueError`` naming every input column that is constant (zero variance)."""
    X = np.asarray(X)
    if X.ndim == 1:
        X = X[:, None]
    constant = np.flatnonzero(np.ptp(X, axis=0) == 0)
    if constant.size:
        labels = [names[i] if names else f"column {i}" for i in constant]
        raise ValueError(f"constant input ({', '.join(labels)}): a constant input carries no "
                         "information; remove it")
