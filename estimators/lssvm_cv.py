"""LS-SVM with ``(gamma, sigma2)`` tuned by closed-form leave-one-out or k-fold cross-validation.

Paper 001 §4.3 tunes its LS-SVM's ``(c, sigma**2)`` by leave-one-out and §2.3 step 1 by ten-fold
cross-validation; both are done here without refitting per fold, with the exact closed forms of
:mod:`rlgsim.estimators.lssvm` (Cawley & Talbot 2004 for LOO, An, Liu & Venkatesh 2007 for k-fold):
``r_i = alpha_i / (H^-1)_ii`` and ``r_F = [(H^-1)_FF]^-1 alpha_F``.

For each ``sigma2`` the kernel matrix is eigen-decomposed once, ``K = U diag(lambda) U'``; then for
every ``gamma``, ``A^-1 = U diag(1/(lambda + 1/gamma)) U'``, so ``alpha``, ``b`` and ``diag(A^-1)``
cost ``O(N**2)`` per ``gamma`` (a k-fold grid point ``O(N**3/k)``), instead of a factorisation per
grid point and fold. The chosen pair is refitted with the Cholesky solver of
:class:`rlgsim.estimators.lssvm.LSSVMRegressor`.

The inputs are standardised once with the statistics of all the training data (the kernel must
be fixed for the closed forms to hold), as LS-SVMlab does. Dense only: ``O(N**3)`` per ``sigma2``
and ``8 N**2`` bytes; for very large N tune on a subsample, then fit the Nyström solver.

Scores (unit of ``y``, squared for ``"mse"``): ``"mse"`` mean squared CV residual (the classical
criterion), ``"mae"`` mean absolute, ``"median_abs"`` median absolute CV residual (robust to gross
outliers in ``y``; De Brabanter et al., ICANN 2009, robust model selection).
"""

from __future__ import annotations

import numpy as np
from scipy import linalg
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.utils.validation import check_is_fitted, validate_data

from rlgsim.estimators._validation import (check_positive_grid, standardisation,
                                           validate_fit_input)
from rlgsim.estimators.kernels import rbf
from rlgsim.estimators.lssvm import LSSVMRegressor, blas_threads_for, cv_residuals, make_folds

SCORES = {
    "mse": lambda r: float(np.mean(r**2)),
    "mae": lambda r: float(np.mean(np.abs(r))),
    "median_abs": lambda r: float(np.median(np.abs(r))),
}

DEFAULT_GAMMAS = (1e-2, 1e-1, 1.0, 1e1, 1e2, 1e3, 1e4)
DEFAULT_SIGMA2S = (1e-2, 3e-2, 1e-1, 3e-1, 1.0, 3.0, 1e1, 3e1, 1e2)


def lssvm_grid_cv_residuals(Xs: np.ndarray, y: np.ndarray, gammas: np.ndarray,
                            sigma2s: np.ndarray, folds, fit_intercept: bool = True):
    """Yield ``(i_sigma2, j_gamma, residuals)`` of closed-form CV for every grid point.

    ``Xs`` are the (already standardised) inputs; ``folds`` is ``None`` for leave-one-out or a
    list of test-index arrays. One eigen-decomposition of ``K`` per ``sigma2``.
    """
    n = Xs.shape[0]
    ones = np.ones(n)
    for i, sigma2 in enumerate(sigma2s):
        lam, U = linalg.eigh(rbf(Xs, Xs, sigma2), overwrite_a=True, check_finite=False,
                             driver="evd")
        np.maximum(lam, 0.0, out=lam)  # K is PSD; clip round-off negatives
        uy, u1 = U.T @ y, U.T @ ones
        U2 = U**2 if folds is None else None
        for j, gamma in enumerate(gammas):
            d = 1.0 / (lam + 1.0 / gamma)
            nu = U @ (d * uy)
            if fit_intercept:
                eta = U @ (d * u1)
                alpha = nu - (nu.sum() / eta.sum()) * eta
            else:
                eta, alpha = None, nu
            r = cv_residuals(alpha, eta, folds,
                             lambda: U2 @ d,
                             lambda F: (U[F] * d) @ U[F].T)
            yield i, j, r


class LSSVMRegressorCV(RegressorMixin, BaseEstimator):
    """LS-SVM (:class:`rlgsim.estimators.lssvm.LSSVMRegressor`) with grid-searched ``gamma``
    and ``sigma2``.

    Parameters
    ----------
    gammas : sequence of float, default=(1e-2, ..., 1e4)
        Candidate regularisation constants (paper 001's ``c``), dimensionless, > 0.
    sigma2s : sequence of float, default=(1e-2, ..., 1e2)
        Candidate squared RBF widths in standardised-input units squared, > 0.
    cv : int or None, default=None
        ``None``: exact closed-form leave-one-out; ``k``: exact closed-form shuffled k-fold.
    scoring : {"mse", "mae", "median_abs"}, default="mse"
        Criterion on the CV residuals (smaller is better); ``"median_abs"`` is robust.
    fit_intercept, standardize : bool, default=True
        As in :class:`~rlgsim.estimators.lssvm.LSSVMRegressor`.
    random_state : int, RandomState instance or None, default=None
        Shuffles the k-fold split (unused for leave-one-out).

    Attributes
    ----------
    gamma_, sigma2_ : float
        The chosen pair (first minimum in grid order).
    cv_scores_ : ndarray of shape (len(sigma2s), len(gammas))
        The criterion at every grid point.
    best_score_ : float
        ``cv_scores_`` at the chosen pair.
    cv_residuals_ : ndarray of shape (n_samples,)
        CV residuals ``y_i - y^(-fold(i))(x_i)`` at the chosen pair (unit of ``y``).
    estimator_ : LSSVMRegressor
        The dense LS-SVM refitted on all the data with the chosen pair.
    """

    def __init__(self, gammas=DEFAULT_GAMMAS, sigma2s=DEFAULT_SIGMA2S, *, cv: int | None = None,
                 scoring: str = "mse", fit_intercept: bool = True, standardize: bool = True,
                 random_state=None):
        self.gammas = gammas
        self.sigma2s = sigma2s
        self.cv = cv
        self.scoring = scoring
        self.fit_intercept = fit_intercept
        self.standardize = standardize
        self.random_state = random_state

    def fit(self, X, y) -> "LSSVMRegressorCV":
        """Tune ``(gamma, sigma2)`` on ``X`` (n_samples, n_features), ``y`` (n_samples,), refit."""
        gammas = check_positive_grid(self.gammas, "gammas")
        sigma2s = check_positive_grid(self.sigma2s, "sigma2s")
        if self.scoring not in SCORES:
            raise ValueError(f"scoring must be one of {', '.join(SCORES)}, got {self.scoring!r}")
        X, y = validate_fit_input(self, X, y)
        folds = make_folds(X.shape[0], self.cv, self.random_state)
        mean, scale = standardisation(X, self.standardize)
        Xs = (X - mean) / scale
        score = SCORES[self.scoring]
        scores = np.full((sigma2s.size, gammas.size), np.nan)
        residuals = {}
        with blas_threads_for(X.shape[0]):
            for i, j, r in lssvm_grid_cv_residuals(Xs, y, gammas, sigma2s, folds,
                                                   self.fit_intercept):
                scores[i, j] = score(r)
                residuals[i, j] = r
        if not np.isfinite(scores).any():
            raise ValueError("cross-validation failed at every (gamma, sigma2) grid point")
        i, j = np.unravel_index(np.nanargmin(scores), scores.shape)
        self.cv_scores_ = scores
        self.gamma_, self.sigma2_ = float(gammas[j]), float(sigma2s[i])
        self.best_score_ = float(scores[i, j])
        self.cv_residuals_ = residuals[i, j]
        self.estimator_ = LSSVMRegressor(self.gamma_, self.sigma2_,
                                         fit_intercept=self.fit_intercept,
                                         standardize=self.standardize, solver="dense").fit(X, y)
        return self

    def predict(self, X) -> np.ndarray:
        """Predicted target (unit of ``y``) of the refitted LS-SVM."""
        check_is_fitted(self, "estimator_")
        X = validate_data(self, X, dtype=np.float64, reset=False)
        return self.estimator_.predict(X)
