"""Bad inputs shared by the term-selecting regressors' tests (MLR-BIC, stepwise): each case is
``(X, y, regex the ValueError message must match)``."""

from __future__ import annotations

import numpy as np

BAD_INPUTS = [
    (np.array([[1.0, 2.0], [np.nan, 1.0], [3.0, 4.0], [5.0, 1.0]]), np.arange(4.0), "NaN"),
    (np.array([[1.0, 2.0], [np.inf, 1.0], [3.0, 4.0], [5.0, 1.0]]), np.arange(4.0), "infinity"),
    (np.arange(8.0).reshape(4, 2), np.arange(3.0), "inconsistent numbers of samples"),
    (np.arange(2.0)[:, None], np.arange(2.0), "needs at least 3 samples, got 2"),
    (np.column_stack([np.arange(9.0), np.full(9, 2.0)]), np.arange(9.0), r"constant input \(x1\)"),
    (np.arange(4.0)[:, None], np.array([0.0, 1.0, np.nan, 2.0]), "y contains NaN"),
]
