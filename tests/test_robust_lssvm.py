"""IR-LSSVM (estimators/robust_lssvm.py) and its weights (estimators/robust_weights.py).

References: the closed-form weight functions and scales of paper 001 eqs. 15-20 (and scipy's
order statistics), numpy.linalg.solve of the weighted bordered system (eq. 14), brute-force
leave-one-out / k-fold refits, plain LS-SVM, and the analytic truth over several seeds.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats
from sklearn.model_selection import KFold
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.kernels import rbf
from rlgsim.estimators.lssvm import LSSVMRegressor
from rlgsim.estimators.robust_lssvm import MIN_WEIGHT, RobustLSSVMRegressor, robust_cv_score
from rlgsim.estimators.robust_weights import (hampel_weights, huber_weights, logistic_weights,
                                       myriad_weights, robust_scale, weight_function)

WEIGHTS = ("huber", "hampel", "logistic", "myriad")


def truth(x: np.ndarray) -> np.ndarray:
    """A bias-vs-temperature-like curve on the unit interval (unit of y)."""
    return np.sin(2 * np.pi * x[:, 0]) + 0.5 * x[:, 0]


def curve_data(seed: int, n: int = 200, noise: float = 0.1, outlier_fraction: float = 0.0):
    """Noisy samples of :func:`truth`; a fraction replaced by gross errors of 20-50 noise sigmas."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(0.0, 1.0, (n, 1))
    y = truth(X) + noise * rng.standard_normal(n)
    k = int(round(outlier_fraction * n))
    bad = rng.choice(n, k, replace=False)
    y[bad] += rng.choice([-1.0, 1.0], k) * rng.uniform(20 * noise, 50 * noise, k)
    return X, y, bad


def standardised(X):
    return (X - X.mean(axis=0)) / X.std(axis=0)


def weighted_bordered_reference(Xs, y, gamma, sigma2, v):
    """numpy.linalg.solve of [[0, 1'], [1, K + diag(1/(gamma v))]] [b; alpha] = [0; y]."""
    n = len(y)
    H = np.zeros((n + 1, n + 1))
    H[0, 1:] = H[1:, 0] = 1.0
    H[1:, 1:] = rbf(Xs, Xs, sigma2) + np.diag(1.0 / (gamma * v))
    sol = np.linalg.solve(H, np.r_[0.0, y])
    return sol[1:], sol[0]


GRID = np.linspace(0.0, 1.0, 401)[:, None]


def rmse_vs_truth(model) -> float:
    return float(np.sqrt(np.mean((model.predict(GRID) - truth(GRID)) ** 2)))


# --------------------------------------------------------------------------------------------
# weight functions and robust scale
# --------------------------------------------------------------------------------------------

def test_weight_functions_match_paper_formulas():
    r = np.array([-4.0, -2.8, -1.0, 0.0, 0.3, 1.345, 2.5, 2.75, 3.0, 10.0])
    a = np.abs(r)
    np.testing.assert_allclose(hampel_weights(r, 2.5, 3.0),
                               np.where(a < 2.5, 1, np.where(a <= 3, (3 - a) / 0.5, 0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        np.testing.assert_allclose(huber_weights(r, 1.345), np.where(a < 1.345, 1, 1.345 / a))
        np.testing.assert_allclose(logistic_weights(r), np.where(r == 0, 1, np.tanh(r) / r))
    np.testing.assert_allclose(myriad_weights(r, 0.7), 0.49 / (0.49 + r**2))
    assert logistic_weights(np.array([1e-12]))[0] == 1.0
    for name, p in [("huber", 1.0), ("hampel", None), ("logistic", None), ("myriad", 2.0)]:
        w = weight_function(name, p)(r)
        assert np.all((w >= 0) & (w <= 1)) and w[3] == 1.0  # weights in [0, 1], 1 at r = 0
        assert np.all(np.diff(w[3:]) <= 0)  # non-increasing in |r|


def test_robust_scales_match_definitions_and_ignore_outliers():
    rng = np.random.default_rng(0)
    e = 0.02 * rng.standard_normal(20_000)
    q75, q25 = np.percentile(e, [75, 25])
    assert robust_scale(e, "iqr") == pytest.approx((q75 - q25) / (2 * 0.6745), rel=1e-12)
    assert robust_scale(e, "mad") == pytest.approx(1.483 * np.median(np.abs(e - np.median(e))),
                                                   rel=1e-12)
    e[:2000] = 1e3  # 10 % gross errors barely move them; the standard deviation explodes
    for method in ("iqr", "mad"):
        assert robust_scale(e, method) == pytest.approx(0.02, rel=0.2)
    assert np.std(e) > 100


@pytest.mark.parametrize("call, message", [
    (lambda: robust_scale(np.ones(3), "std"), "unknown robust scale 'std'"),
    (lambda: huber_weights(np.ones(3), 0.0), "beta must be > 0"),
    (lambda: myriad_weights(np.ones(3), -1.0), "delta must be > 0"),
    (lambda: hampel_weights(np.ones(3), 3.0, 2.5), "0 < c1 < c2"),
    (lambda: weight_function("bisquare"), "unknown weight function 'bisquare'"),
    (lambda: weight_function("huber"), "needs its parameter"),
    (lambda: weight_function("logistic", 1.0), "huber and myriad weights only"),
    (lambda: robust_cv_score(np.ones(3), "mean"), "cv_criterion must be one of"),
])
def test_weight_helpers_reject_bad_arguments(call, message):
    with pytest.raises(ValueError, match=message):
        call()


# --------------------------------------------------------------------------------------------
# the re-weighted solution
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("rescale", [True, False])
@pytest.mark.parametrize("weight", WEIGHTS)
def test_final_model_solves_the_weighted_system_at_a_fixed_point_of_the_weights(weight, rescale):
    X, y, _ = curve_data(seed=1, n=120, outlier_fraction=0.1)
    est = RobustLSSVMRegressor(100.0, 0.1, weight=weight, rescale=rescale, tol=1e-6, cv=3,
                               random_state=0).fit(X, y)
    alpha, b = weighted_bordered_reference(standardised(X), y, 100.0, 0.1, est.weights_)
    np.testing.assert_allclose(est.dual_coef_, alpha, rtol=0, atol=1e-8 * np.abs(alpha).max())
    assert est.intercept_ == pytest.approx(b, abs=1e-8)
    e = y - est.predict(X)
    if rescale:  # De Brabanter et al. 2009: the scale of the final residuals
        assert est.scale_ == pytest.approx(robust_scale(e, "mad"), rel=1e-4)
    else:  # paper 001 / Suykens et al. 2002: the scale of the unweighted LS-SVM's residuals
        e0 = y - LSSVMRegressor(100.0, 0.1).fit(X, y).predict(X)
        assert est.scale_ == pytest.approx(1.483 * np.median(np.abs(e0 - np.median(e0))),
                                           rel=1e-9)
    # converged: the weights recomputed from the final residuals are the weights used
    wf = weight_function(weight, est.weight_param_)
    np.testing.assert_allclose(np.maximum(wf(e / est.scale_), MIN_WEIGHT), est.weights_,
                               atol=1e-5)
    assert 1 <= est.n_iter_ < 300


def test_one_step_equals_paper_001_algorithm_by_hand():
    """max_iter=1: LS-SVM -> xi_k = alpha_k/c -> s = IQR/1.349 -> Hampel weights -> weighted LS-SVM."""
    X, y, _ = curve_data(seed=2, n=100, outlier_fraction=0.1)
    Xs = standardised(X)
    est = RobustLSSVMRegressor(50.0, 0.2, weight="hampel", scale="iqr", max_iter=1).fit(X, y)
    alpha0, _ = weighted_bordered_reference(Xs, y, 50.0, 0.2, np.ones(len(y)))
    xi = alpha0 / 50.0  # paper 001 §2.3: xi_k = alpha_k / c
    s = stats.iqr(xi) / (2 * 0.6745)
    v = np.maximum(np.clip((3.0 - np.abs(xi / s)) / 0.5, 0.0, 1.0), MIN_WEIGHT)
    alpha1, b1 = weighted_bordered_reference(Xs, y, 50.0, 0.2, v)
    np.testing.assert_allclose(est.weights_, v, atol=1e-9)
    np.testing.assert_allclose(est.dual_coef_, alpha1, rtol=0, atol=1e-8 * np.abs(alpha1).max())
    assert est.intercept_ == pytest.approx(b1, abs=1e-8) and est.n_iter_ == 1
    assert np.sum(v <= MIN_WEIGHT) >= 10  # the Hampel weights removed the gross errors


@pytest.mark.parametrize("criterion", ["median", "weighted_l1"])
def test_robust_cv_scores_equal_brute_force_fold_refits(criterion):
    """Robust k-fold CV re-runs the whole re-weighting on each training fold (honest CV)."""
    X, y, _ = curve_data(seed=3, n=80, outlier_fraction=0.1)
    Xs, grid = standardised(X), (0.5, 2.0, 5.0)
    est = RobustLSSVMRegressor(100.0, 0.1, weight="myriad", weight_param_grid=grid, cv=4,
                               cv_criterion=criterion, random_state=7).fit(X, y)
    expected = []
    for delta in grid:
        r = np.empty(len(y))
        for train, test in KFold(4, shuffle=True, random_state=7).split(Xs):
            fold = RobustLSSVMRegressor(100.0, 0.1, weight="myriad", weight_param=delta,
                                        standardize=False).fit(Xs[train], y[train])
            r[test] = y[test] - fold.predict(Xs[test])
        a = np.abs(r)
        if criterion == "median":
            expected.append(np.median(a))
        else:  # Hampel(2.5, 3)-weighted mean of |r| over the robust scale of r
            w = np.clip((3.0 - a / (1.483 * np.median(np.abs(r - np.median(r))))) / 0.5, 0, 1)
            expected.append(np.sum(w * a) / np.sum(w))
    np.testing.assert_allclose(est.cv_scores_, expected, rtol=1e-9)
    assert est.weight_param_ == grid[int(np.argmin(expected))]
    final = RobustLSSVMRegressor(100.0, 0.1, weight="myriad", weight_param=est.weight_param_)
    np.testing.assert_allclose(est.predict(X), final.fit(X, y).predict(X), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# robustness: the acceptance criteria
# --------------------------------------------------------------------------------------------

SEEDS = range(5)


@pytest.mark.parametrize("weight", WEIGHTS)
def test_recovers_the_clean_function_under_10_percent_gross_outliers(weight):
    ratios = []
    for seed in SEEDS:
        X, y, _ = curve_data(seed, outlier_fraction=0.10)
        plain = rmse_vs_truth(LSSVMRegressor(100.0, 0.1).fit(X, y))
        robust = rmse_vs_truth(RobustLSSVMRegressor(100.0, 0.1, weight=weight, cv=5,
                                                    random_state=seed).fit(X, y))
        ratios.append(plain / robust)
    # plain LS-SVM is dragged by the outliers; IR-LSSVM stays near the noise-limited accuracy
    assert np.median(ratios) >= 4.0 and min(ratios) >= 2.0, ratios


def test_outlier_weights_flag_the_outliers():
    X, y, bad = curve_data(seed=11, outlier_fraction=0.10)
    est = RobustLSSVMRegressor(100.0, 0.1, weight="hampel").fit(X, y)
    good = np.setdiff1d(np.arange(len(y)), bad)
    assert np.all(est.weights_[bad] < 0.05) and np.median(est.weights_[good]) == 1.0


def test_tuned_pipeline_beats_tuned_plain_lssvm_under_outliers():
    """Both tuned as a user would: plain by LOO-MSE, robust by robust LOO (median |r|)."""
    from rlgsim.estimators.lssvm_cv import LSSVMRegressorCV
    ratios = []
    for seed in SEEDS:
        X, y, _ = curve_data(seed, outlier_fraction=0.10)
        plain = LSSVMRegressorCV().fit(X, y)
        tuned = LSSVMRegressorCV(scoring="median_abs").fit(X, y)
        robust = RobustLSSVMRegressor(tuned.gamma_, tuned.sigma2_, cv=5, random_state=seed)
        robust.fit(X, y)
        ratios.append(rmse_vs_truth(plain) / rmse_vs_truth(robust))
    assert np.median(ratios) >= 2.0, ratios


@pytest.mark.parametrize("weight", WEIGHTS)
def test_without_outliers_matches_plain_lssvm(weight):
    gaps, plain_err, robust_err = [], [], []
    for seed in SEEDS:
        X, y, _ = curve_data(seed, outlier_fraction=0.0)
        plain = LSSVMRegressor(100.0, 0.1).fit(X, y)
        robust = RobustLSSVMRegressor(100.0, 0.1, weight=weight, cv=5, random_state=seed)
        robust.fit(X, y)
        gaps.append(np.sqrt(np.mean((plain.predict(GRID) - robust.predict(GRID)) ** 2)))
        plain_err.append(rmse_vs_truth(plain))
        robust_err.append(rmse_vs_truth(robust))
    # the two curves differ by far less than the noise (0.1), and are equally accurate
    assert np.median(gaps) < 0.15 * 0.1 and max(gaps) < 0.5 * 0.1, gaps
    assert np.mean(robust_err) < 1.15 * np.mean(plain_err), (robust_err, plain_err)


# --------------------------------------------------------------------------------------------
# bad input
# --------------------------------------------------------------------------------------------

@pytest.mark.parametrize("est, mutate, message", [
    (RobustLSSVMRegressor(), lambda X, y: (np.where(X > 0.5, np.nan, X), y), "Input X contains NaN"),
    (RobustLSSVMRegressor(), lambda X, y: (X, np.where(y > 0.5, -np.inf, y)),
     "Input y contains infinity"),
    (RobustLSSVMRegressor(), lambda X, y: (X[:-2], y), "inconsistent numbers of samples"),
    (RobustLSSVMRegressor(), lambda X, y: (np.column_stack([X, np.ones(len(X))]), y),
     r"constant input \(column 1\)"),
    (RobustLSSVMRegressor(), lambda X, y: (X[:6], y[:6]),
     "too few samples for 10-fold cross-validation: 6 samples"),
    (RobustLSSVMRegressor(cv=None), None, "cv must be an integer number of folds"),
    (RobustLSSVMRegressor(weight="bisquare"), None, "weight must be one of"),
    (RobustLSSVMRegressor(weight="hampel", weight_param=2.0), None, "huber and myriad weights only"),
    (RobustLSSVMRegressor(weight="hampel", hampel_c1=3.0, hampel_c2=3.0), None, "0 < c1 < c2"),
    (RobustLSSVMRegressor(weight_param=-1.0), None, "weight_param must be a finite number > 0"),
    (RobustLSSVMRegressor(weight_param_grid=[1.0, 0.0]), None, "weight_param_grid must be"),
    (RobustLSSVMRegressor(scale="std"), None, "scale must be one of"),
    (RobustLSSVMRegressor(cv_criterion="mse"), None, "cv_criterion must be one of"),
    (RobustLSSVMRegressor(max_iter=0), None, "max_iter must be an integer >= 1"),
    (RobustLSSVMRegressor(tol=0.0), None, "tol must be a finite number > 0"),
    (RobustLSSVMRegressor(gamma=-1.0), None, "gamma must be a finite number > 0"),
])
def test_bad_input_raises_a_clear_value_error(est, mutate, message):
    X, y, _ = curve_data(seed=4, n=30)
    if mutate is not None:
        X, y = mutate(X, y)
    with pytest.raises(ValueError, match=message):
        est.fit(X, y)


def test_non_convergence_is_reported():
    from sklearn.exceptions import ConvergenceWarning
    X, y, _ = curve_data(seed=5, n=80, outlier_fraction=0.1)
    with pytest.warns(ConvergenceWarning, match="did not converge in max_iter=2"):
        RobustLSSVMRegressor(100.0, 0.1, weight="myriad", weight_param=1.0, max_iter=2,
                             tol=1e-12).fit(X, y)


# --------------------------------------------------------------------------------------------
# scikit-learn contract
# --------------------------------------------------------------------------------------------

@parametrize_with_checks([
    RobustLSSVMRegressor(weight_param_grid=(1.0, 2.0), cv=3, random_state=0),
    RobustLSSVMRegressor(weight="hampel", scale="iqr"),
    RobustLSSVMRegressor(weight="logistic", max_iter=1, rescale=False),
    RobustLSSVMRegressor(weight="myriad", weight_param_grid=(1.0, 3.0), cv=3,
                         cv_criterion="weighted_l1", random_state=0),
])
def test_sklearn_estimator_contract(estimator, check):
    check(estimator)
