"""Whitening by a modelled noise covariance, for the generalised least-squares fits of the
identification (:mod:`.term_selection`, :mod:`.step_detection`, the twin's hop scan and next
experiment): the Cholesky factor L of C, so that ``L⁻¹y = L⁻¹Xβ + L⁻¹e`` has independent
unit-variance errors when the model holds (Aitken 1935). scipy's ``cholesky`` and
``solve_triangular`` do the algebra; this module adds only the diagonal jitter for a
numerically singular C and the shape check.
"""

from __future__ import annotations

from typing import Callable

import numpy as np


def jittered_cholesky(C: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of the covariance ``C``, with a relative jitter (starting at
    1e-10 of the mean diagonal, ×100 per try, six tries) on the diagonal when ``C`` is
    numerically singular; ValueError when it is not positive definite even then."""
    from scipy.linalg import cholesky
    n = C.shape[0]
    jitter = 0.0
    for _ in range(6):
        try:
            return cholesky(C + jitter * np.eye(n), lower=True)
        except np.linalg.LinAlgError:
            jitter = max(jitter * 100.0, 1e-10 * float(np.mean(np.diag(C))))
    raise ValueError("the noise covariance is not positive definite")


def whitener(noise_cov: np.ndarray | None, n: int) -> Callable[[np.ndarray], np.ndarray]:
    """``v ↦ L⁻¹v`` with ``L`` the Cholesky factor of ``noise_cov`` (:func:`jittered_cholesky`);
    the identity without one."""
    if noise_cov is None:
        return lambda v: v
    from scipy.linalg import solve_triangular
    C = np.asarray(noise_cov, dtype=float)
    if C.shape != (n, n):
        raise ValueError(f"noise_cov must be ({n}, {n}), got {C.shape}")
    L = jittered_cholesky(C)
    # L is finite (a Cholesky factor): its check on every call would cost a pass over n²
    # values, more than the solve of a short vector; the vector is checked as before
    return lambda v: solve_triangular(L, np.asarray_chkfinite(np.asarray(v, dtype=float)),
                                      lower=True, check_finite=False)
