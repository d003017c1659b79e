"""Stepwise regression (paper 001 §4.2): true terms recovered, spurious ones rejected at about
the p-to-enter rate, the stopping rules hold (checked with statsmodels directly), and the
coefficients are statsmodels OLS on the final terms."""

from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.columns import Columns
from rlgsim.estimators.stepwise import StepwiseRegressor
from rlgsim.estimators.terms import design_matrix, parse_term
from selection_bad_inputs import BAD_INPUTS

MODEL1_START = ("T", "T^2", "dT/dt")                          # paper 001 Model 1 initial terms


def model1_data(seed: int, n: int = 300) -> tuple[Columns, np.ndarray]:
    """Paper 001 Model 1 shape without the (dT/dt)² term; bias in °/h, T in °C, dT/dt in K/s."""
    rng = np.random.default_rng(seed)
    T = rng.uniform(-40, 70, n)
    r = rng.uniform(-1 / 60, 1 / 60, n)                       # ±1 °C/min
    y = (1.427e-3 + 4.906e-4 * T - 4.616e-6 * T**2 - 0.917 * r - 1.926e-2 * T * r
         + rng.normal(0, 1e-3, n))
    return Columns({"T": T, "dT/dt": r}), y


def model2_data(seed: int, n: int = 300) -> tuple[Columns, np.ndarray]:
    """Three inputs; 4 true terms out of the 9 second-order candidates."""
    rng = np.random.default_rng(seed)
    T = rng.uniform(-40, 60, n)
    r = rng.uniform(-0.05, 0.05, n)
    U = rng.uniform(1, 5, n)
    y = 6.8e-3 + 2e-5 * T + 0.02 * r - 1e-3 * U + 1e-6 * T**2 + rng.normal(0, 2e-4, n)
    return Columns({"T": T, "dT/dt": r, "U": U}), y


def _raw_ols(X: Columns, y: np.ndarray, terms: list[str]):
    powers = [parse_term(t, X.names) for t in terms]
    return sm.OLS(y, sm.add_constant(design_matrix(X.values, powers), has_constant="add")).fit()


def test_model1_keeps_true_terms_and_drops_rate_squared():
    X, y = model1_data(0)
    model = StepwiseRegressor(initial_terms=MODEL1_START).fit(X, y)
    assert set(model.terms_) == {"T", "T^2", "dT/dt", "T*dT/dt"}
    assert model.history_[0].action == "enter" and model.history_[0].term == "T*dT/dt"
    eq = model.equation("B")
    assert eq.startswith("B = ") and "·T·dT/dt" in eq and "(dT/dt)²" not in eq


def test_true_terms_recovered_and_spurious_rejected_over_seeds():
    """9 candidates, 4 true.  All seeds must keep every true term; a spurious term enters at
    roughly the p-to-enter level (5 % per test, a little more for the best of several): over
    30 seeds x 5 spurious terms, more than 15 % inclusions would be a failure."""
    true = {"T", "dT/dt", "U", "T^2"}
    spurious = 0
    for seed in range(30):
        X, y = model2_data(seed)
        chosen = set(StepwiseRegressor().fit(X, y).terms_)
        assert true <= chosen, f"seed {seed}: missed {true - chosen}"
        spurious += len(chosen - true)
    assert spurious <= 0.15 * 30 * 5


def test_stopping_rules_hold_when_checked_with_statsmodels():
    X, y = model2_data(7)
    model = StepwiseRegressor(p_enter=0.05, p_remove=0.10).fit(X, y)
    final = list(model.terms_)
    res = _raw_ols(X, y, final)
    assert np.all(res.pvalues[1:] <= 0.10)                 # nothing left to remove
    for cand in model.candidates_:
        if cand in final:
            continue
        p_new = _raw_ols(X, y, final + [cand]).pvalues[-1]
        assert p_new >= 0.05, f"{cand} would enter with p={p_new}"


def test_coefficients_are_statsmodels_ols_on_the_final_terms():
    X, y = model1_data(1)
    model = StepwiseRegressor(initial_terms=MODEL1_START).fit(X, y)
    res = _raw_ols(X, y, list(model.terms_))
    assert model.intercept_ == pytest.approx(res.params[0], rel=1e-7)
    np.testing.assert_allclose(model.coef_, res.params[1:], rtol=1e-7)
    np.testing.assert_allclose(model.bse_, res.bse[1:], rtol=1e-7)
    np.testing.assert_allclose(model.pvalues_, res.pvalues[1:], rtol=1e-6, atol=1e-300)
    assert model.rsquared_ == pytest.approx(res.rsquared, rel=1e-10)
    np.testing.assert_allclose(model.predict(X), res.fittedvalues, rtol=1e-9)


def test_initial_terms_can_leave_forced_terms_cannot():
    X, y = model1_data(2)
    free = StepwiseRegressor(initial_terms=MODEL1_START + ("dT/dt^2",)).fit(X, y)
    assert "dT/dt^2" not in free.terms_
    assert ("remove", "dT/dt^2") in [(s.action, s.term) for s in free.history_]
    removed = next(s for s in free.history_ if s.term == "dT/dt^2")
    assert removed.p_value > 0.10
    forced = StepwiseRegressor(forced_terms=["dT/dt^2"]).fit(X, y)
    assert "dT/dt^2" in forced.terms_


def test_paper001_model2_with_uhfo_names():
    rng = np.random.default_rng(8)
    n = 400
    T = rng.uniform(-40, 70, n)
    r = rng.uniform(-1 / 60, 1 / 60, n)
    U = rng.uniform(3.5, 5.5, n)
    y = (1.565 + 8.292e-3 * T + 26.263 * r + 0.646 * U - 6.494e-2 * U**2 - 4.055e-2 * T * r
         - 1.562e-3 * T * U - 4.666 * r * U + rng.normal(0, 1e-3, n))
    model = StepwiseRegressor(initial_terms=MODEL1_START).fit(Columns({"T": T, "dT/dt": r,
                                                                      "U": U}), y)
    assert {"T", "dT/dt", "U", "U^2", "T*dT/dt", "T*U", "dT/dt*U"} <= set(model.terms_)
    assert "dT/dt^2" not in model.terms_
    assert "U²" in model.equation("B") and "dT/dt·U" in model.equation("B")


def test_max_steps_warns():
    X, y = model2_data(9)
    with pytest.warns(ConvergenceWarning, match="max_steps=1"):
        StepwiseRegressor(max_steps=1).fit(X, y)


@pytest.mark.parametrize("X, y, message", BAD_INPUTS)
def test_bad_input_is_a_clear_value_error(X, y, message):
    with pytest.raises(ValueError, match=message):
        StepwiseRegressor().fit(X, y)


def test_bad_parameters_and_collinear_start():
    X, y = model1_data(3, n=40)
    with pytest.raises(ValueError, match="need 0 < p_enter <= p_remove < 1"):
        StepwiseRegressor(p_enter=0.2, p_remove=0.1).fit(X, y)
    with pytest.raises(ValueError, match="'V' is not one of the inputs"):
        StepwiseRegressor(initial_terms=["V"]).fit(X, y)
    with pytest.raises(ValueError, match="needs at least 6 samples, got 5"):
        StepwiseRegressor(initial_terms=MODEL1_START).fit(X.rows(slice(0, 5)), y[:5])
    binary = np.column_stack([np.tile([0.0, 1.0], 10), np.arange(20.0)])
    with pytest.raises(ValueError, match="collinear"):
        StepwiseRegressor(initial_terms=["x0", "x0^2"]).fit(binary, np.arange(20.0))


@parametrize_with_checks([StepwiseRegressor()])
def test_sklearn_contract(estimator, check):
    check(estimator)
