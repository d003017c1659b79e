"""MLR with BIC selection: recovers the true terms of a noisy polynomial, rejects spurious ones
at the rate BIC implies, and its coefficients are statsmodels OLS on the chosen terms."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
import statsmodels.api as sm
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.columns import Columns
from rlgsim.estimators.mlr import MLRBICRegressor
from rlgsim.estimators.terms import design_matrix
from selection_bad_inputs import BAD_INPUTS

TRUE_TERMS = {"T", "dT/dt", "U", "T^2"}


def synthetic(seed: int, n: int = 300) -> tuple[Columns, np.ndarray]:
    """Gyro bias (°/h) = polynomial in T (°C), dT/dt (K/s), U (V) + white noise."""
    rng = np.random.default_rng(seed)
    T = rng.uniform(-40, 60, n)
    r = rng.uniform(-0.05, 0.05, n)
    U = rng.uniform(1, 5, n)
    y = 6.8e-3 + 2e-5 * T + 0.02 * r - 1e-3 * U + 1e-6 * T**2 + rng.normal(0, 2e-4, n)
    return Columns({"T": T, "dT/dt": r, "U": U}), y


def test_recovers_true_terms_and_rejects_spurious_ones_over_seeds():
    """Candidates: the 9 terms of degree <= 2 in (T, dT/dt, U); 4 are true, 5 spurious.

    Every seed must keep all true terms.  A spurious term enters BIC's choice when its
    likelihood-ratio statistic exceeds ln n ≈ 5.7, probability ≈ 1.7 % each: over 30 seeds
    x 5 spurious terms (~2.5 expected), more than 9 inclusions would be a failure.
    """
    spurious = 0
    for seed in range(30):
        X, y = synthetic(seed)
        model = MLRBICRegressor().fit(X, y)
        assert model.search_used_ == "exhaustive"
        chosen = set(model.terms_)
        assert TRUE_TERMS <= chosen, f"seed {seed}: missed {TRUE_TERMS - chosen}"
        spurious += len(chosen - TRUE_TERMS)
    assert spurious <= 9


def test_coefficients_are_statsmodels_ols_on_the_chosen_terms():
    X, y = synthetic(1)
    model = MLRBICRegressor().fit(X, y)
    ols = sm.OLS(y, sm.add_constant(design_matrix(X.values, model.powers_))).fit()
    assert model.intercept_ == pytest.approx(ols.params[0], rel=1e-8)
    np.testing.assert_allclose(model.coef_, ols.params[1:], rtol=1e-7)
    np.testing.assert_allclose(model.bse_, ols.bse[1:], rtol=1e-7)
    np.testing.assert_allclose(model.pvalues_, ols.pvalues[1:], rtol=1e-6, atol=1e-300)
    assert model.bic_ == pytest.approx(ols.bic, rel=1e-10)
    np.testing.assert_allclose(model.predict(X), ols.fittedvalues, rtol=1e-10)


def test_exhaustive_choice_is_the_minimum_bic_over_all_subsets():
    X, y = synthetic(2, n=120)
    cand = ["T", "dT/dt", "U", "T^2", "T*U"]
    model = MLRBICRegressor(candidate_terms=cand).fit(X, y)
    best = (np.inf, ())
    for k in range(len(cand) + 1):
        for subset in combinations(range(len(cand)), k):
            powers = [[(1, 0, 0), (0, 1, 0), (0, 0, 1), (2, 0, 0), (1, 0, 1)][j] for j in subset]
            exog = sm.add_constant(design_matrix(X.values, powers), has_constant="add")
            bic = sm.OLS(y, exog).fit().bic
            if bic < best[0]:
                best = (bic, tuple(cand[j] for j in subset))
    assert model.bic_ == pytest.approx(best[0], rel=1e-10)
    assert set(model.terms_) == set(best[1])
    assert min(m.bic for m in model.search_path_) == pytest.approx(model.bic_, rel=1e-12)


def test_greedy_search_agrees_here_and_auto_switches_to_it():
    X, y = synthetic(3)
    exhaustive = MLRBICRegressor(search="exhaustive").fit(X, y)
    greedy = MLRBICRegressor(search="greedy").fit(X, y)
    assert set(greedy.terms_) == set(exhaustive.terms_)
    auto = MLRBICRegressor(max_exhaustive_terms=4).fit(X, y)
    assert auto.search_used_ == "greedy"
    bics = [m.bic for m in greedy.search_path_]
    assert all(b1 > b2 for b1, b2 in zip(bics, bics[1:]))          # every step lowers BIC


def test_paper002_model_constant_T_and_rate():
    rng = np.random.default_rng(4)
    T = rng.uniform(-40, 60, 400)
    r = rng.uniform(-5 / 60, 5 / 60, 400)                          # up to 5 °C/min
    y = 7e-3 + 3e-6 * T - 4e-3 * r + rng.normal(0, 1e-5, 400)
    model = MLRBICRegressor(feature_names=["T", "dT/dt"]).fit(np.column_stack([T, r]), y)
    assert model.terms_ == ("T", "dT/dt")
    assert model.equation("B").startswith("B = 0.007")


def test_forced_terms_stay_and_explicit_candidates():
    X, y = synthetic(5)
    model = MLRBICRegressor(forced_terms=["dT/dt^2"]).fit(X, y)
    assert "dT/dt^2" in model.terms_ and TRUE_TERMS <= set(model.terms_)
    model = MLRBICRegressor(candidate_terms=["T", "U", "T²"]).fit(X, y)
    assert model.candidates_ == ("T", "U", "T^2")
    assert set(model.terms_) <= {"T", "U", "T^2"}


@pytest.mark.parametrize("X, y, message", BAD_INPUTS)
def test_bad_input_is_a_clear_value_error(X, y, message):
    with pytest.raises(ValueError, match=message):
        MLRBICRegressor().fit(X, y)


def test_bad_parameters():
    X, y = synthetic(6, n=40)
    with pytest.raises(ValueError, match="search must be"):
        MLRBICRegressor(search="random").fit(X, y)
    with pytest.raises(ValueError, match="'V' is not one of the inputs"):
        MLRBICRegressor(forced_terms=["V"]).fit(X, y)
    with pytest.raises(ValueError, match="repeats a term"):
        MLRBICRegressor(candidate_terms=["T", "T^1"]).fit(X, y)


@parametrize_with_checks([MLRBICRegressor()])
def test_sklearn_contract(estimator, check):
    check(estimator)
