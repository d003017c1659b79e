"""Gaussian kernels and the kernel expansion that every kernel regressor predicts with.

The LS-SVM and IR-LSSVM (paper 001 eq. 10), the two RBF networks (paper 002 eq. 1) and the RVR
(Tipping 2001 eq. 21; paper 000 eq. 1) all predict

    y(x) = sum_j c_j k(x, z_j) + b,      k(x, z) = exp(-s ||x - z||**2),

and differ only in their centres ``z_j`` (training inputs, landmarks, chosen centres, relevance
vectors), their coefficients and in how the scale ``s`` is written: ``1 / (2 sigma2)`` (paper 001
eq. 11), ``ln 2 / spread**2`` (MATLAB ``newrb``, paper 002 eq. 2) and ``1 / width**2`` (Tipping's
SparseBayes "gauss" basis). :func:`kernel_expansion` forms the sum a block of rows at a time,
so predicting ``N`` points costs ``CHUNK_ROWS x m`` memory, not ``N x m``.

Two ways to get the squared distances, both kept on purpose:

* :func:`rbf` (the LS-SVM kernel) is scikit-learn's ``rbf_kernel``: ``||a||**2 - 2 a.b +
  ||b||**2`` through one matrix product, the fast way to form the ``N x N`` kernel matrix of an
  LS-SVM fit (a few 1e-16 of absolute error in the squared distance of nearby points);
* :func:`squared_distances` is ``scipy.spatial.distance.cdist``: exact differences, for the
  matrices the RVR caches across many widths and for the RBF networks' design matrices, whose
  least-squares output weights can be large enough to amplify rounding in the kernel.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.spatial.distance import cdist
from sklearn.metrics.pairwise import rbf_kernel

#: Rows per block when kernel blocks against the centres are formed.
CHUNK_ROWS = 4096

#: ``kernel(A, B)`` -> the (len(A), len(B)) kernel matrix.
Kernel = Callable[[np.ndarray, np.ndarray], np.ndarray]


def squared_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances between the rows of ``A`` and ``B`` (units of X squared)."""
    return cdist(A, B, "sqeuclidean")


def gaussian(D2: np.ndarray, scale: float) -> np.ndarray:
    """``exp(-scale * D2)`` from squared distances ``D2`` (``scale`` in 1 / units of ``D2``)."""
    return np.exp(D2 * -scale)


def rbf_gamma(sigma2: float) -> float:
    """scikit-learn's RBF ``gamma`` for paper 001's width: ``exp(-d**2/(2 sigma2))`` (eq. 11)."""
    return 1.0 / (2.0 * sigma2)


def rbf(A: np.ndarray, B: np.ndarray, sigma2: float) -> np.ndarray:
    """LS-SVM kernel matrix ``exp(-||a_i - b_j||**2 / (2 sigma2))`` (paper 001 eq. 11), float64."""
    return rbf_kernel(A, B, gamma=rbf_gamma(sigma2))


def kernel_expansion(X: np.ndarray, centres: np.ndarray, coef: np.ndarray, intercept: float,
                     kernel: Kernel, chunk_rows: int = CHUNK_ROWS) -> np.ndarray:
    """``sum_j coef_j kernel(x, centre_j) + intercept`` for each row of ``X``, in blocks of
    ``chunk_rows`` rows (unit of ``coef`` and ``intercept``)."""
    out = np.empty(X.shape[0])
    for start in range(0, X.shape[0], chunk_rows):
        stop = start + chunk_rows
        out[start:stop] = kernel(X[start:stop], centres) @ coef
    out += intercept
    return out
