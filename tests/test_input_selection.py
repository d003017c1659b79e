"""Correlation-based input selection (paper 001 Table 1, paper 003 §4.3)."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.columns import Columns
from rlgsim.estimators.features import pairwise_gradients
from rlgsim.estimators.input_selection import (CorrelationSelector, correlation_ranking,
                                        select_by_correlation)
from rlgsim.estimators.polynomial import PolynomialRegressor


def _paper001_like(n: int = 500, seed: int = 0) -> tuple[Columns, np.ndarray]:
    rng = np.random.default_rng(seed)
    T = rng.uniform(-40, 70, n)
    r = rng.normal(0, 0.01, n)
    U = rng.normal(4.0, 0.2, n)
    noise = rng.normal(0, 1, n)
    y = 2.0 * (T - T.mean()) / T.std() - 1.0 * (r / r.std()) - 3.0 * (U - 4.0) / 0.2 + noise
    return Columns({"T": T, "dT/dt": r, "U": U}), y


def test_ranking_matches_numpy_corrcoef_and_orders_by_abs_r():
    X, y = _paper001_like()
    ranking = correlation_ranking(X, y)
    assert [c.name for c in ranking] == ["U", "T", "dT/dt"]
    for name, r in ranking:
        assert r == pytest.approx(np.corrcoef(X[name], y)[0, 1], abs=1e-12)
    assert ranking[0].r < 0 < ranking[1].r               # the sign is kept, ranking uses |r|


def test_threshold_keeps_strong_inputs_only():
    X, y = _paper001_like()
    kept = select_by_correlation(X, y, threshold=0.4)
    assert [c.name for c in kept] == ["U", "T"]
    assert all(abs(c.r) >= 0.4 for c in kept)
    assert select_by_correlation(X, y, threshold=0.0) == correlation_ranking(X, y)
    with pytest.raises(ValueError, match="threshold must be in"):
        select_by_correlation(X, y, threshold=1.5)


def test_paper003_gradient_selection_picks_the_cathode_pairs():
    # the bias follows the gradients to probe A (paper 003 Fig. 5); the rest is unrelated
    rng = np.random.default_rng(3)
    n = 400
    probes = {p: 30 + rng.normal(0, 1, n) for p in "ABCDEFGH"}
    grads = pairwise_gradients(Columns(probes))
    bias = 0.02 * sum(grads[f"A-{p}"] for p in "BCDEFGH") + rng.normal(0, 0.005, n)
    kept = {c.name for c in select_by_correlation(grads, bias, threshold=0.3)}
    assert kept == {f"A-{p}" for p in "BCDEFGH"}


@pytest.mark.parametrize("X, y, message", [
    (np.array([[1.0, 2.0], [np.nan, 1.0], [3.0, 4.0]]), [1.0, 2.0, 3.0], "NaN"),
    (np.array([[1.0, 2.0], [np.inf, 1.0], [3.0, 4.0]]), [1.0, 2.0, 3.0], "infinity"),
    (np.array([[1.0, 2.0], [2.0, 1.0], [3.0, 4.0]]), [1.0, 2.0], "inconsistent numbers"),
    (np.array([[1.0, 2.0], [2.0, 1.0]]), [1.0, 2.0], "minimum of 3 is required"),
    (np.array([[1.0, 5.0], [2.0, 5.0], [3.0, 5.0]]), [1.0, 2.0, 4.0], r"constant input \(x1\)"),
    (np.array([[1.0, 2.0], [2.0, 1.0], [3.0, 4.0]]), [1.0, 1.0, 1.0], "constant target"),
])
def test_bad_input_is_a_clear_value_error(X, y, message):
    with pytest.raises(ValueError, match=message):
        correlation_ranking(X, y)


def test_selector_names_and_pipeline():
    X, y = _paper001_like()
    sel = CorrelationSelector(threshold=0.4).fit(X, y)
    assert sel.selected_names_ == ("U", "T")
    np.testing.assert_array_equal(sel.get_support(), [True, False, True])
    assert CorrelationSelector(threshold=0.0, max_features=1).fit(X, y).selected_names_ == ("U",)
    pipe = make_pipeline(CorrelationSelector(threshold=0.4), PolynomialRegressor(degree=1))
    pipe.fit(X, y)
    assert pipe.score(X, y) > 0.8
    # names survive the selector, so the model reports the inputs it used (original order)
    assert pipe[-1].input_names_ == ("T", "U")
    assert isinstance(pipe[0].transform(X), Columns)
    np.testing.assert_array_equal(pipe[0].transform(X.values), X.select(["T", "U"]).values)


@parametrize_with_checks([CorrelationSelector()])
def test_sklearn_contract(estimator, check):
    check(estimator)
