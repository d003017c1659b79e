"""Least-squares support vector machine regression (LS-SVM), dense and fixed-size (Nyström).

Model (paper 001 §2.2, eqs. 5-10; Suykens et al., *Least Squares Support Vector Machines*,
World Scientific 2002, ch. 3, paper 001 ref. [22])::

    min_{w,b,e}  1/2 w'w + gamma/2 * sum_k v_k e_k**2   s.t.  y_k = w' phi(x_k) + b + e_k

whose dual is the bordered (KKT) linear system, paper 001 eq. (8) (``v_k = 1``) and eq. (14)::

    [ 0    1'                    ] [ b     ]   [ 0 ]
    [ 1    K + diag(1/(gamma v)) ] [ alpha ] = [ y ]

with the RBF kernel of paper 001 eq. (11), ``K(x, x') = exp(-||x - x'||**2 / (2 sigma2))``, and
predictions ``y(x) = sum_k alpha_k K(x, x_k) + b`` (eq. 10). ``gamma`` is the regularisation
constant (paper 001 calls it ``c``), ``sigma2`` the squared kernel width.

Units and conventions
---------------------
- Inputs are standardised inside (``standardize=True``, the default): each column of ``X`` is
  shifted by its training mean and divided by its training standard deviation (``ddof=0``), so
  ``sigma2`` is dimensionless and one value fits inputs as different as a temperature in °C,
  a rate in K/s and a voltage (paper 001's T, dT/dt, U_HFO). ``alpha`` and ``b`` are in the
  unit of ``y``. ``gamma`` is dimensionless.
- Mapping to scikit-learn: with ``fit_intercept=False`` the model equals
  ``sklearn.kernel_ridge.KernelRidge(alpha=1/gamma, kernel="rbf", gamma=1/(2*sigma2))`` fitted on
  the standardised inputs (``(K + I/gamma) alpha = y``).

Solution method
---------------
``b`` is unpenalised. The system is solved with one Cholesky factorisation of
``A = K + diag(1/(gamma v))`` (in place, lower, float64) and the Schur complement of ``A``
(Suykens et al. 2002, §3.2): ``eta = A^-1 1``, ``nu = A^-1 y``, ``b = 1'nu / 1'eta``,
``alpha = nu - b eta``. No general inverse is formed.

Closed-form cross-validation residuals (Cawley & Talbot, "Fast exact leave-one-out
cross-validation of sparse least-squares support vector machines", Neural Networks 17 (2004)
1467-1475; block form: An, Liu & Venkatesh, "Fast cross-validation algorithms for least squares
support vector machine and kernel ridge regression", Pattern Recognition 40 (2007) 2154-2162)::

    r_i = y_i - y^(-i)(x_i) = alpha_i / (H^-1)_ii,      r_F = [(H^-1)_FF]^-1 alpha_F

where ``H`` is the bordered matrix; its alpha block is ``H^-1 = A^-1 - eta eta' / 1'eta``. These
are exact (not approximations) for a fixed kernel and fixed weights ``v``.

Fixed-size LS-SVM (``solver="nystroem"``; Suykens et al. 2002 ch. 6; De Brabanter et al.,
"Optimized fixed-size kernel models for large data sets", CSDA 54 (2010) 1484-1504): ``m``
landmark points ``z_j``, drawn without replacement from the training inputs by ``random_state``,
define the Nyström feature map ``phi(x) = F' k_m(x)`` with ``F = U_r diag(lambda_r)^-1/2`` from
the eigen-decomposition of ``K_mm`` truncated to its numerical rank ``r`` (Williams & Seeger,
"Using the Nyström method to speed up kernel machines", NIPS 2001), so ``phi(x)'phi(x')``
approximates ``K(x, x')``. The same objective is then solved in the primal, ridge on ``phi``
with unpenalised bias, through the ``(r+1)``-bordered normal equations
``[[N, s'], [s, Phi'Phi + I/gamma]] [b; w] = [1'y; Phi'y]`` (``s = Phi'1``), again by Cholesky
and Schur complement. ``Phi'Phi`` is accumulated over row chunks, so memory is
``O(m**2 + chunk*m)`` and time ``O(N m**2)``. The fitted model is the kernel expansion on the
landmarks ``y(x) = sum_j beta_j K(x, z_j) + b`` with ``beta = F w``.

Why hand-written: scikit-learn has no LS-SVM (``KernelRidge`` has no unpenalised bias and no
closed-form cross-validation residuals). The Nyström map is five lines here rather than
``sklearn.kernel_approximation.Nystroem`` because that one keeps all ``m`` directions, clipping
the eigenvalues of ``K_mm`` at an absolute 1e-12, while the directions below the numerical rank
carry only round-off: truncating them gives fewer features for wide kernels (rank 168 of 300
landmarks at ``sigma2 = 10`` on 3 standardised inputs, a 1.7x faster fit at N = 1e5), and with
``m = N`` landmarks it reproduces the dense solution to ~1e-14 instead of ~1e-8.

Why this file is long: the bordered LS-SVM system, its Cholesky and Nyström solvers and the
closed-form cross-validation residuals are the regressor's own numerics, shared by its
cross-validated and robust variants (:mod:`rlgsim.estimators.lssvm_cv`,
:mod:`rlgsim.estimators.robust_lssvm`).
"""

from __future__ import annotations

from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from scipy import linalg
from scipy.linalg import lapack
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.model_selection import KFold
from sklearn.utils import check_random_state
from sklearn.utils.validation import check_is_fitted, validate_data
from threadpoolctl import threadpool_limits  # a scikit-learn dependency

from rlgsim.estimators._validation import (check_folds, check_positive, standardisation,
                                           validate_fit_input)
from rlgsim.estimators.kernels import CHUNK_ROWS, kernel_expansion, rbf

__all__ = ["blas_threads_for", "BorderedSolution", "cholesky_lower", "solve_bordered",
           "inverse_cholesky_factor", "nystroem_map", "cv_residuals", "cholesky_cv_residuals",
           "make_folds", "LSSVMOutput", "LSSVMRegressor"]

#: ``solver="auto"`` uses the dense solver up to this many samples (an 8e8-byte kernel matrix),
#: the Nyström (fixed-size) solver above it.
MAX_DENSE_SAMPLES = 10_000
SOLVERS = ("auto", "dense", "nystroem")
#: Below this many samples fits, CV grids and re-weighting loops run on one BLAS thread. Their
#: factorisations are too small for threads to pay off, and when the cores are shared with other
#: jobs OpenBLAS threads lose far more than they gain: measured on the 2-core machine under load,
#: 15 Cholesky solves at N = 1000 took 0.3 s on one thread and 2.1 s on two.
SMALL_PROBLEM = 2000


def blas_threads_for(n_samples: int) -> AbstractContextManager:
    """Context limiting BLAS to one thread for problems of fewer than ``SMALL_PROBLEM`` samples."""
    if n_samples < SMALL_PROBLEM:
        return threadpool_limits(limits=1, user_api="blas")
    return nullcontext()


# --------------------------------------------------------------------------------------------
# linear algebra
# --------------------------------------------------------------------------------------------

@dataclass
class BorderedSolution:
    """Solution of ``[[0, 1'], [1, A]] [b; alpha] = [0; y]`` (or ``A alpha = y`` without ``b``).

    ``eta = A^-1 1`` (``None`` without intercept) and the lower Cholesky factor ``chol`` of
    ``A`` are kept for closed-form cross-validation residuals.
    """

    alpha: np.ndarray
    intercept: float
    eta: np.ndarray | None
    chol: np.ndarray


def cholesky_lower(A: np.ndarray, overwrite: bool, what: str) -> np.ndarray:
    """Lower Cholesky factor of SPD ``A`` (in place if ``overwrite``); ``ValueError`` if not PD.

    Only the lower triangle of the result is meaningful. ``A`` must be symmetric: a C-ordered
    ``A`` is factored through its F-ordered transpose view (the same matrix), which LAPACK can
    overwrite without a copy.
    """
    if overwrite and A.flags.c_contiguous and not A.flags.f_contiguous:
        A = A.T
    try:
        L, _ = linalg.cho_factor(A, lower=True, overwrite_a=overwrite, check_finite=False)
    except linalg.LinAlgError as exc:
        raise ValueError(f"{what} is not numerically positive definite ({exc}); lower the "
                         "regularisation constant gamma or the kernel width sigma2") from exc
    return L


def solve_bordered(A: np.ndarray, y: np.ndarray, fit_intercept: bool = True,
                   overwrite_a: bool = False) -> BorderedSolution:
    """Solve the LS-SVM KKT system (paper 001 eqs. 8 and 14) for SPD ``A = K + diag(1/(gamma v))``.

    Cholesky of ``A`` then the Schur complement for the unpenalised bias ``b`` (Suykens et al.
    2002 §3.2): ``eta = A^-1 1``, ``nu = A^-1 y``, ``b = 1'nu / 1'eta``, ``alpha = nu - b eta``.
    With ``fit_intercept=False``: ``alpha = A^-1 y``, ``b = 0``. ``A`` is overwritten by its
    factor when ``overwrite_a``.
    """
    L = cholesky_lower(A, overwrite_a, "the kernel matrix K + diag(1/(gamma v))")
    rhs = np.column_stack([y, np.ones_like(y)]) if fit_intercept else y[:, None].copy()
    sol = linalg.cho_solve((L, True), rhs, overwrite_b=True, check_finite=False)
    nu = sol[:, 0]
    if not fit_intercept:
        return BorderedSolution(alpha=nu, intercept=0.0, eta=None, chol=L)
    eta = sol[:, 1]
    b = float(nu.sum() / eta.sum())
    return BorderedSolution(alpha=nu - b * eta, intercept=b, eta=eta, chol=L)


def inverse_cholesky_factor(L: np.ndarray) -> np.ndarray:
    """``L^-1`` in place of the lower factor ``L`` (``A^-1 = L^-T L^-1``), upper triangle zeroed.

    Costs ``N**3/3`` flops (LAPACK ``dtrtri``); ``diag(A^-1)`` is then the column sums of squares.
    """
    Linv, info = lapack.dtrtri(L, lower=1, overwrite_c=1)
    if info != 0:
        raise ValueError(f"singular Cholesky factor (dtrtri info={info})")
    n = Linv.shape[0]
    for j in range(0, n, 1024):  # zero the strict upper triangle block-wise, no N**2 index arrays
        block = Linv[:j + 1024, j:j + 1024]
        block[:j] = 0.0
        block[j:] = np.tril(block[j:])
    return Linv


def nystroem_map(Kmm: np.ndarray) -> np.ndarray:
    """``F = U_r diag(lambda_r)^-1/2`` of the landmark kernel ``K_mm``, truncated to numerical rank.

    Eigenvalues below ``m * eps * lambda_max`` (the usual numerical-rank tolerance) are dropped, so
    ``F' K_mm F = I_r`` and ``K_nm F F' K_mn`` is the Nyström approximation of ``K`` (Williams &
    Seeger 2001).
    """
    lam, U = linalg.eigh(Kmm, overwrite_a=True, check_finite=False)
    keep = lam > Kmm.shape[0] * np.finfo(float).eps * lam[-1]
    return U[:, keep] / np.sqrt(lam[keep])


def cv_residuals(alpha: np.ndarray, eta: np.ndarray | None,
                 folds: Sequence[np.ndarray] | None,
                 ainv_diag: Callable[[], np.ndarray],
                 ainv_block: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """Closed-form cross-validation residuals ``y_i - y^(-fold(i))(x_i)`` of a solved LS-SVM.

    Leave-one-out (``folds=None``): ``r_i = alpha_i / (H^-1)_ii`` (Cawley & Talbot 2004);
    k-fold: ``r_F = [(H^-1)_FF]^-1 alpha_F`` (An et al. 2007), with the alpha block of the
    bordered inverse ``H^-1 = A^-1 - eta eta'/1'eta`` (``A^-1`` alone without intercept).
    ``ainv_diag()`` returns ``diag(A^-1)``; ``ainv_block(F)`` returns ``A^-1[F, F]``.
    Exact for the fixed kernel and weights of ``A``.
    """
    if folds is None:
        g = ainv_diag()
        if eta is not None:
            g = g - eta**2 / eta.sum()
        return alpha / g
    r = np.empty_like(alpha)
    for F in folds:
        G = ainv_block(F)
        if eta is not None:
            G -= np.outer(eta[F], eta[F]) / eta.sum()
        r[F] = linalg.solve(G, alpha[F], assume_a="pos", check_finite=False)
    return r


def cholesky_cv_residuals(sol: BorderedSolution,
                          folds: Sequence[np.ndarray] | None) -> np.ndarray:
    """:func:`cv_residuals` from the Cholesky factor of a :func:`solve_bordered` solution.

    Overwrites ``sol.chol`` with its inverse (``N**3/3`` flops, no extra ``N**2`` memory).
    """
    Linv = inverse_cholesky_factor(sol.chol)
    sol.chol = Linv
    return cv_residuals(sol.alpha, sol.eta, folds,
                        lambda: np.einsum("ij,ij->j", Linv, Linv),
                        lambda F: Linv[:, F].T @ Linv[:, F])


def make_folds(n_samples: int, cv: int | None, random_state) -> list[np.ndarray] | None:
    """``None`` for leave-one-out (``cv=None``), else the test indices of a shuffled ``KFold``."""
    if cv is None:
        check_folds(n_samples, n_samples)
        return None
    if isinstance(cv, bool) or not isinstance(cv, (int, np.integer)):
        raise ValueError(f"cv must be None (closed-form leave-one-out) or an integer number of "
                         f"folds, got {cv!r}")
    check_folds(n_samples, int(cv))
    splitter = KFold(n_splits=int(cv), shuffle=True, random_state=random_state)
    return [test for _, test in splitter.split(np.zeros((n_samples, 1)))]


# --------------------------------------------------------------------------------------------
# the estimator
# --------------------------------------------------------------------------------------------

class LSSVMOutput:
    """The prediction every LS-SVM shares (paper 001 eq. 10): inputs standardised with
    ``x_mean_``/``x_scale_`` through the RBF kernel expansion on ``support_`` with
    ``dual_coef_``, ``intercept_`` and ``sigma2``. Mixed into the estimators before
    ``RegressorMixin``."""

    def predict(self, X) -> np.ndarray:
        """Predicted target (unit of ``y``) for inputs ``X`` (n_samples, n_features)."""
        check_is_fitted(self, "dual_coef_")
        X = validate_data(self, X, dtype=np.float64, reset=False)
        Xs = (X - self.x_mean_) / self.x_scale_
        sigma2 = float(self.sigma2)
        return kernel_expansion(Xs, self.support_, self.dual_coef_, self.intercept_,
                                lambda A, B: rbf(A, B, sigma2))


class LSSVMRegressor(LSSVMOutput, RegressorMixin, BaseEstimator):
    """LS-SVM regression with an RBF kernel (paper 001 §2.2; Suykens et al. 2002).

    Parameters
    ----------
    gamma : float, default=10.0
        Regularisation constant (paper 001's ``c``), dimensionless, > 0. Larger = closer fit.
    sigma2 : float, default=1.0
        Squared RBF kernel width ``sigma**2`` of ``exp(-||x - x'||**2 / (2 sigma2))``, in units of
        the (standardised, hence dimensionless) inputs squared, > 0.
    fit_intercept : bool, default=True
        Fit the unpenalised bias ``b``. ``False`` fixes ``b = 0`` and then equals
        ``KernelRidge(alpha=1/gamma, kernel="rbf", gamma=1/(2*sigma2))`` on the standardised inputs.
    standardize : bool, default=True
        Standardise each input column with its training mean and standard deviation (ddof=0).
    solver : {"auto", "dense", "nystroem"}, default="auto"
        ``"dense"``: the full ``N x N`` bordered system (``8 N**2`` bytes, ``N**3/3`` flops).
        ``"nystroem"``: fixed-size LS-SVM on ``n_landmarks`` landmarks (``O(N m**2)``).
        ``"auto"``: dense up to ``MAX_DENSE_SAMPLES`` (10 000) samples, Nyström above.
    n_landmarks : int, default=300
        Number ``m`` of Nyström landmark points (capped at ``N``); about ``sqrt(N)`` at
        ``N = 1e5``, ample for the smooth few-input maps of temperature compensation.
    compute_loo : bool, default=False
        Also compute the closed-form leave-one-out residuals ``loo_residuals_`` (dense: one
        more ``N**3/3``; Nyström: ``O(N m**2)``, with the landmarks held fixed).
    random_state : int, RandomState instance or None, default=None
        Seeds the choice of the Nyström landmarks (unused by the dense solver).

    Attributes
    ----------
    x_mean_, x_scale_ : ndarray of shape (n_features,)
        Standardisation applied to the inputs (zeros/ones when ``standardize=False``).
    support_ : ndarray of shape (n_support, n_features)
        Standardised kernel centres: every training input (dense) or the landmarks (Nyström).
    dual_coef_ : ndarray of shape (n_support,)
        Expansion coefficients (unit of ``y``): ``alpha`` (dense) or ``beta = W' w`` (Nyström).
    intercept_ : float
        Bias ``b`` (unit of ``y``).
    solver_ : str
        The solver used (``"dense"`` or ``"nystroem"``).
    feature_map_ : ndarray of shape (n_landmarks, rank)
        Nyström map ``F`` with ``phi(x) = F' k_m(x)`` (Nyström solver only); ``primal_coef_``
        holds the primal weights ``w``.
    loo_residuals_ : ndarray of shape (n_samples,)
        ``y_i - y^(-i)(x_i)`` (only with ``compute_loo=True``).
    """

    def __init__(self, gamma: float = 10.0, sigma2: float = 1.0, *, fit_intercept: bool = True,
                 standardize: bool = True, solver: str = "auto", n_landmarks: int = 300,
                 compute_loo: bool = False, random_state=None):
        self.gamma = gamma
        self.sigma2 = sigma2
        self.fit_intercept = fit_intercept
        self.standardize = standardize
        self.solver = solver
        self.n_landmarks = n_landmarks
        self.compute_loo = compute_loo
        self.random_state = random_state

    def fit(self, X, y) -> "LSSVMRegressor":
        """Fit on inputs ``X`` (n_samples, n_features) and target ``y`` (n_samples,)."""
        gamma = check_positive(self.gamma, "gamma")
        sigma2 = check_positive(self.sigma2, "sigma2")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")
        n_landmarks = check_positive(self.n_landmarks, "n_landmarks", integer=True)
        X, y = validate_fit_input(self, X, y)
        self.x_mean_, self.x_scale_ = standardisation(X, self.standardize)
        Xs = (X - self.x_mean_) / self.x_scale_
        n = X.shape[0]
        solver = self.solver
        if solver == "auto":
            solver = "dense" if n <= MAX_DENSE_SAMPLES else "nystroem"
        self.solver_ = solver
        # the Nyström solver's matrices are m x m and chunk x m: their size is the landmarks'
        size = n if solver == "dense" else min(n_landmarks, n)
        with blas_threads_for(size):
            if solver == "dense":
                self._fit_dense(Xs, y, gamma, sigma2)
            else:
                self._fit_nystroem(Xs, y, gamma, sigma2, n_landmarks)
        return self

    def _fit_dense(self, Xs: np.ndarray, y: np.ndarray, gamma: float, sigma2: float) -> None:
        n = Xs.shape[0]
        A = rbf(Xs, Xs, sigma2)
        A.flat[:: n + 1] += 1.0 / gamma
        sol = solve_bordered(A, y, self.fit_intercept, overwrite_a=True)
        del A
        self.support_ = Xs
        self.dual_coef_ = sol.alpha
        self.intercept_ = sol.intercept
        if self.compute_loo:
            self.loo_residuals_ = cholesky_cv_residuals(sol, None)

    def _fit_nystroem(self, Xs: np.ndarray, y: np.ndarray, gamma: float, sigma2: float,
                      n_landmarks: int) -> None:
        n = Xs.shape[0]
        m = min(n_landmarks, n)
        rng = check_random_state(self.random_state)
        Z = Xs[np.sort(rng.choice(n, size=m, replace=False))]
        F = nystroem_map(rbf(Z, Z, sigma2))
        r = F.shape[1]
        # Bordered primal normal equations, accumulated over row chunks: Phi = K_nm F.
        S = np.zeros((r, r))
        s = np.zeros(r)
        t = np.zeros(r)
        for start in range(0, n, CHUNK_ROWS):
            Phi = rbf(Xs[start:start + CHUNK_ROWS], Z, sigma2) @ F
            S += Phi.T @ Phi
            s += Phi.sum(axis=0)
            t += Phi.T @ y[start:start + CHUNK_ROWS]
        S.flat[:: r + 1] += 1.0 / gamma
        L = cholesky_lower(S, True, "the Nyström normal matrix Phi'Phi + I/gamma")
        sol = linalg.cho_solve((L, True), np.column_stack([t, s]), check_finite=False)
        nu, eta = sol[:, 0], sol[:, 1]
        if self.fit_intercept:
            schur = n - s @ eta  # N - s'A^-1 s > 0: Schur complement of the bordered primal matrix
            b = float((y.sum() - s @ nu) / schur)
            w = nu - b * eta
        else:
            schur, b, w = np.nan, 0.0, nu
        self.support_ = Z
        self.feature_map_ = F
        self.primal_coef_ = w
        self.dual_coef_ = F @ w
        self.intercept_ = b
        if self.compute_loo:
            self.loo_residuals_ = self._nystroem_loo(Xs, y, L, eta, schur, sigma2)

    def _nystroem_loo(self, Xs, y, L, eta, schur, sigma2) -> np.ndarray:
        """LOO residuals ``e_i / (1 - h_ii)`` of the primal ridge with unpenalised bias.

        Leverage of the bordered primal matrix ``M = [[N, s'], [s, A]]``:
        ``h_ii = (1 - phi_i'eta)**2 / (N - s'eta) + ||L^-1 phi_i||**2`` (block inverse of ``M``).
        """
        r = np.empty(Xs.shape[0])
        for start in range(0, Xs.shape[0], CHUNK_ROWS):
            sl = slice(start, start + CHUNK_ROWS)
            Phi = rbf(Xs[sl], self.support_, sigma2) @ self.feature_map_
            e = y[sl] - Phi @ self.primal_coef_ - self.intercept_
            V = linalg.solve_triangular(L, Phi.T, lower=True, check_finite=False)
            h = np.einsum("ij,ij->j", V, V)
            if self.fit_intercept:
                h += (1.0 - Phi @ eta) ** 2 / schur
            r[sl] = e / (1.0 - h)
        return r
