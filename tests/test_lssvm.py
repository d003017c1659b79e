"""LS-SVM (estimators/lssvm.py, estimators/lssvm_cv.py) against independent references.

References: numpy.linalg.solve of the bordered KKT system (paper 001 eq. 8), scikit-learn's
KernelRidge (b = 0), brute-force leave-one-out / k-fold refits, and the analytic truth.
"""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.kernel_ridge import KernelRidge
from sklearn.model_selection import KFold
from sklearn.preprocessing import StandardScaler
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.kernels import rbf
from rlgsim.estimators.lssvm import LSSVMRegressor
from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV


def truth(X: np.ndarray) -> np.ndarray:
    """Gyro bias (deg/h) vs temperature (°C), temperature rate (K/s), U_HFO (V): smooth, nonlinear."""
    T, dT, U = X[:, 0], X[:, 1], X[:, 2]
    return 0.02 * np.sin(T / 15.0) + 2.0 * dT + 0.01 * (U - 11.0) ** 2 + 1e-5 * T * (U - 11.0)


def gyro_data(n: int, seed: int, noise: float = 0.003) -> tuple[np.ndarray, np.ndarray]:
    """Paper 001-like inputs in their own units: wildly different scales per column."""
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-40.0, 70.0, n),          # temperature, °C
                         rng.uniform(-1 / 60, 1 / 60, n),       # dT/dt, K/s (±1 °C/min)
                         rng.uniform(10.0, 12.0, n)])           # U_HFO, V
    return X, truth(X) + noise * rng.standard_normal(n)


def standardised(X: np.ndarray) -> np.ndarray:
    return (X - X.mean(axis=0)) / X.std(axis=0)


def bordered_reference(Xs, y, gamma, sigma2):
    """Independent solution of [[0, 1'], [1, K + I/gamma]] [b; alpha] = [0; y] (numpy.linalg.solve)."""
    n = len(y)
    H = np.zeros((n + 1, n + 1))
    H[0, 1:] = H[1:, 0] = 1.0
    H[1:, 1:] = np.exp(-((Xs[:, None, :] - Xs[None, :, :]) ** 2).sum(-1) / (2 * sigma2))
    H[1:, 1:] += np.eye(n) / gamma
    sol = np.linalg.solve(H, np.r_[0.0, y])
    return sol[1:], sol[0]


# --------------------------------------------------------------------------------------------
# the dense solver
# --------------------------------------------------------------------------------------------

def standardised_with(Xnew: np.ndarray, Xtrain: np.ndarray) -> np.ndarray:
    return (Xnew - Xtrain.mean(axis=0)) / Xtrain.std(axis=0)


@pytest.mark.parametrize("standardize", [True, False])
def test_dense_equals_independent_bordered_solve(standardize):
    X, y = gyro_data(150, seed=1)
    Xt, _ = gyro_data(50, seed=2)
    Xs, Xts = standardised(X), standardised_with(Xt, X)
    # standardize=False is given pre-standardised inputs, so both cases share one reference
    est = LSSVMRegressor(gamma=50.0, sigma2=0.7, standardize=standardize)
    est.fit(X if standardize else Xs, y)
    alpha, b = bordered_reference(Xs, y, 50.0, 0.7)
    scale = np.abs(alpha).max()
    np.testing.assert_allclose(est.dual_coef_, alpha, rtol=0, atol=1e-8 * scale)
    assert abs(est.intercept_ - b) < 1e-8 * max(1.0, abs(b))
    assert abs(est.dual_coef_.sum()) < 1e-10 * scale  # KKT: sum(alpha) = 0
    Kt = np.exp(-((Xts[:, None] - Xs[None]) ** 2).sum(-1) / (2 * 0.7))
    np.testing.assert_allclose(est.predict(Xt if standardize else Xts), Kt @ alpha + b,
                               rtol=0, atol=1e-8 * np.abs(y).max())


@pytest.mark.parametrize("standardize", [True, False])
def test_without_bias_equals_kernel_ridge(standardize):
    X, y = gyro_data(200, seed=3)
    Xtest, _ = gyro_data(80, seed=4)
    gamma, sigma2 = 30.0, 1.5
    est = LSSVMRegressor(gamma, sigma2, fit_intercept=False, standardize=standardize).fit(X, y)
    assert est.intercept_ == 0.0
    if standardize:  # documented mapping: KernelRidge on the standardised inputs
        scaler = StandardScaler().fit(X)
        Xk, Xtk = scaler.transform(X), scaler.transform(Xtest)
    else:
        Xk, Xtk = X, Xtest
    kr = KernelRidge(alpha=1.0 / gamma, kernel="rbf", gamma=1.0 / (2.0 * sigma2)).fit(Xk, y)
    np.testing.assert_allclose(est.dual_coef_, kr.dual_coef_, rtol=1e-8,
                               atol=1e-10 * np.abs(kr.dual_coef_).max())
    np.testing.assert_allclose(est.predict(Xtest), kr.predict(Xtk), rtol=1e-8, atol=1e-12)


def test_standardised_fit_is_invariant_to_input_units():
    X, y = gyro_data(120, seed=5)
    est = LSSVMRegressor(20.0, 1.0).fit(X, y)
    X_other_units = X * np.array([1.8, 3600.0, 1000.0]) + np.array([32.0, 0.0, 0.0])  # °F, K/h, mV
    est2 = LSSVMRegressor(20.0, 1.0).fit(X_other_units, y)
    np.testing.assert_allclose(est2.predict(X_other_units), est.predict(X), rtol=1e-9, atol=1e-12)
    # and the fit is useful: error vs truth below the noise (0.003) and the signal's spread
    rmse = np.sqrt(np.mean((est.predict(X) - truth(X)) ** 2))
    assert rmse < 0.003 and rmse < 0.15 * np.std(truth(X))


# --------------------------------------------------------------------------------------------
# closed-form cross-validation
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("fit_intercept", [True, False])
def test_closed_form_loo_equals_brute_force_refits(fit_intercept):
    X, y = gyro_data(60, seed=6)
    Xs = standardised(X)
    est = LSSVMRegressor(40.0, 0.8, fit_intercept=fit_intercept, standardize=False,
                         compute_loo=True).fit(Xs, y)
    brute = np.empty(len(y))
    for i in range(len(y)):
        keep = np.arange(len(y)) != i
        m = LSSVMRegressor(40.0, 0.8, fit_intercept=fit_intercept, standardize=False)
        brute[i] = y[i] - m.fit(Xs[keep], y[keep]).predict(Xs[i:i + 1])[0]
    np.testing.assert_allclose(est.loo_residuals_, brute, rtol=1e-7, atol=1e-12)
    # LOO residuals exceed training residuals in magnitude (each point is predicted without itself)
    assert np.all(np.abs(est.loo_residuals_) >= np.abs(y - est.predict(Xs)) - 1e-15)


def test_cv_loo_scores_equal_brute_force_and_pick_the_minimum():
    X, y = gyro_data(50, seed=7)
    Xs = standardised(X)
    gammas, sigma2s = (1.0, 30.0, 1000.0), (0.2, 1.0, 5.0)
    cv = LSSVMRegressorCV(gammas, sigma2s, cv=None).fit(X, y)
    brute = np.empty((3, 3))
    for i, s2 in enumerate(sigma2s):
        for j, g in enumerate(gammas):
            r = [y[k] - LSSVMRegressor(g, s2, standardize=False)
                 .fit(np.delete(Xs, k, 0), np.delete(y, k)).predict(Xs[k:k + 1])[0]
                 for k in range(len(y))]
            brute[i, j] = np.mean(np.square(r))
    np.testing.assert_allclose(cv.cv_scores_, brute, rtol=1e-6)
    i, j = np.unravel_index(np.argmin(brute), brute.shape)
    assert (cv.sigma2_, cv.gamma_) == (sigma2s[i], gammas[j])
    np.testing.assert_allclose(cv.predict(X), LSSVMRegressor(cv.gamma_, cv.sigma2_).fit(X, y)
                               .predict(X), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("fit_intercept", [True, False])
def test_cv_kfold_residuals_equal_brute_force_fold_refits(fit_intercept):
    X, y = gyro_data(70, seed=8)
    Xs = standardised(X)
    cv = LSSVMRegressorCV((25.0,), (0.9,), cv=5, scoring="mae", random_state=3,
                          fit_intercept=fit_intercept).fit(X, y)
    brute = np.empty(len(y))
    for train, test in KFold(5, shuffle=True, random_state=3).split(Xs):
        m = LSSVMRegressor(25.0, 0.9, fit_intercept=fit_intercept, standardize=False)
        brute[test] = y[test] - m.fit(Xs[train], y[train]).predict(Xs[test])
    np.testing.assert_allclose(cv.cv_residuals_, brute, rtol=1e-7, atol=1e-12)
    assert cv.best_score_ == pytest.approx(np.mean(np.abs(brute)), rel=1e-7)


def test_cv_tuning_recovers_the_function():
    X, y = gyro_data(300, seed=9)
    cv = LSSVMRegressorCV(cv=10, random_state=0).fit(X, y)
    Xt, _ = gyro_data(500, seed=10)
    def rmse(model):
        return np.sqrt(np.mean((model.predict(Xt) - truth(Xt)) ** 2))

    oracle = min(rmse(LSSVMRegressor(g, s2).fit(X, y)) for g in cv.gammas for s2 in cv.sigma2s)
    assert rmse(cv) < 0.003  # below the measurement noise
    assert rmse(cv) < 1.3 * oracle  # close to the best the grid could do, judged by the truth
    assert cv.best_score_ == pytest.approx(np.nanmin(cv.cv_scores_))


# --------------------------------------------------------------------------------------------
# fixed-size (Nyström) solver
# --------------------------------------------------------------------------------------------

def test_nystroem_with_all_points_as_landmarks_equals_dense():
    X, y = gyro_data(120, seed=11)
    dense = LSSVMRegressor(10.0, 1.0, solver="dense").fit(X, y)
    ny = LSSVMRegressor(10.0, 1.0, solver="nystroem", n_landmarks=120, random_state=0).fit(X, y)
    Xt, _ = gyro_data(60, seed=12)
    np.testing.assert_allclose(ny.predict(Xt), dense.predict(Xt), rtol=0, atol=1e-8)
    assert ny.intercept_ == pytest.approx(dense.intercept_, abs=1e-8)


def nystroem_features(est: LSSVMRegressor, Xs: np.ndarray) -> np.ndarray:
    return rbf(Xs, est.support_, est.sigma2) @ est.feature_map_


@pytest.mark.parametrize("fit_intercept", [True, False])
def test_nystroem_solves_the_bordered_primal_system_and_its_loo(fit_intercept):
    X, y = gyro_data(400, seed=13)
    Xs = standardised(X)
    est = LSSVMRegressor(100.0, 0.5, solver="nystroem", n_landmarks=40, random_state=1,
                         fit_intercept=fit_intercept, standardize=False, compute_loo=True)
    est.fit(Xs, y)
    Phi = nystroem_features(est, Xs)
    r = Phi.shape[1]

    def primal(P, t):  # independent: [[N, s'], [s, P'P + I/gamma]] [b; w] = [1't; P't]
        Z = np.column_stack([np.ones(len(t)), P]) if fit_intercept else P
        M = Z.T @ Z + np.diag(np.r_[0.0, np.full(r, 1 / 100.0)] if fit_intercept
                              else np.full(r, 1 / 100.0))
        return Z, np.linalg.solve(M, Z.T @ t)

    Z, sol = primal(Phi, y)
    w = sol[1:] if fit_intercept else sol
    np.testing.assert_allclose(est.primal_coef_, w, rtol=1e-7, atol=1e-9 * np.abs(w).max())
    np.testing.assert_allclose(est.predict(Xs), Z @ sol, rtol=0, atol=1e-9)
    brute = np.empty(len(y))
    for i in range(0, len(y), 7):  # every 7th point: enough to catch any error, keeps it fast
        keep = np.arange(len(y)) != i
        _, s_i = primal(Phi[keep], y[keep])
        brute[i] = y[i] - (np.r_[1.0, Phi[i]] if fit_intercept else Phi[i]) @ s_i
    np.testing.assert_allclose(est.loo_residuals_[::7], brute[::7], rtol=1e-6, atol=1e-10)


def test_nystroem_is_reproducible_from_random_state_and_accurate():
    X, y = gyro_data(12_000, seed=14)
    a = LSSVMRegressor(100.0, 1.0, random_state=5).fit(X, y)
    b = LSSVMRegressor(100.0, 1.0, random_state=5).fit(X, y)
    c = LSSVMRegressor(100.0, 1.0, random_state=6).fit(X, y)
    assert a.solver_ == "nystroem" and a.support_.shape == (300, 3)
    np.testing.assert_array_equal(a.dual_coef_, b.dual_coef_)
    assert not np.array_equal(a.support_, c.support_)
    Xt, _ = gyro_data(2000, seed=15)
    ra = np.sqrt(np.mean((a.predict(Xt) - truth(Xt)) ** 2))
    rc = np.sqrt(np.mean((c.predict(Xt) - truth(Xt)) ** 2))
    assert max(ra, rc) < 0.2 * 0.003  # 12 000 samples average the noise far down


# --------------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("make", [lambda: LSSVMRegressor(), lambda: LSSVMRegressorCV(cv=3)])
@pytest.mark.parametrize("mutate, message", [
    (lambda X, y: (np.where(np.arange(X.size).reshape(X.shape) == 4, np.nan, X), y),
     "Input X contains NaN"),
    (lambda X, y: (X, np.where(np.arange(y.size) == 3, np.inf, y)), "Input y contains infinity"),
    (lambda X, y: (X, y[:-1]), "inconsistent numbers of samples"),
    (lambda X, y: (np.column_stack([X, np.full(len(X), 25.0)]), y), r"constant input \(column 3\)"),
    (lambda X, y: (X[:1], y[:1]), "1 sample"),
])
def test_bad_input_raises_a_clear_value_error(make, mutate, message):
    X, y = gyro_data(20, seed=16)
    with pytest.raises(ValueError, match=message):
        make().fit(*mutate(X, y))


@pytest.mark.parametrize("est, message", [
    (LSSVMRegressorCV(cv=5), "too few samples for 5-fold cross-validation: 4 samples"),
    (LSSVMRegressorCV(cv=1), "at least 2 folds"),
    (LSSVMRegressorCV(cv="loo"), "cv must be None"),
    (LSSVMRegressorCV(scoring="r2"), "scoring must be one of"),
    (LSSVMRegressorCV(gammas=(1.0, -2.0)), "each value of gammas must be a finite number > 0"),
    (LSSVMRegressorCV(sigma2s=()), "sigma2s must be a non-empty"),
    (LSSVMRegressor(gamma=0.0), "gamma must be a finite number > 0"),
    (LSSVMRegressor(sigma2=np.nan), "sigma2 must be a finite number > 0"),
    (LSSVMRegressor(solver="qr"), "solver must be one of"),
    (LSSVMRegressor(solver="nystroem", n_landmarks=0), "n_landmarks must be an integer >= 1"),
])
def test_bad_parameters_raise_a_clear_value_error(est, message):
    X, y = gyro_data(4, seed=17)
    with pytest.raises(ValueError, match=message):
        est.fit(X, y)


def test_feature_names_name_the_constant_column():
    pd = pytest.importorskip("pandas")
    X, y = gyro_data(10, seed=18)
    df = pd.DataFrame(X, columns=["T_c", "dTdt_k_per_s", "u_hfo_v"]).assign(u_hfo_v=11.0)
    with pytest.raises(ValueError, match=r"constant input \(u_hfo_v\)"):
        LSSVMRegressor().fit(df, y)


# --------------------------------------------------------------------------------------------
# scikit-learn contract
# --------------------------------------------------------------------------------------------

@parametrize_with_checks([
    LSSVMRegressor(),
    LSSVMRegressor(solver="nystroem", n_landmarks=150, random_state=0),
    LSSVMRegressorCV(gammas=(1.0, 10.0, 100.0), sigma2s=(0.3, 1.0, 3.0)),
    LSSVMRegressorCV(gammas=(1.0, 100.0), sigma2s=(0.5, 2.0), cv=3, scoring="median_abs",
                     random_state=0),
])
def test_sklearn_estimator_contract(estimator, check):
    check(estimator)
