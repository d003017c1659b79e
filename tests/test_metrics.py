"""Metrics against independent references: sklearn.metrics, allantools, numpy formulas, and the
statistics of white noise over many seeds."""

from __future__ import annotations

import allantools
import numpy as np
import pytest
from sklearn import metrics as skm

from rlgsim.estimators.metrics import (allan_deviation, bias_stability, improvement_percent, mae, r2,
                                residual_variance, rmse)

RNG = np.random.default_rng(7)


def _pair(n: int = 300) -> tuple[np.ndarray, np.ndarray]:
    y = RNG.normal(0.01, 0.003, n)                    # a gyro bias, °/h
    return y, y + RNG.normal(0.0005, 0.001, n)      # a biased, noisy prediction


def test_rmse_mae_r2_match_sklearn_and_formulas():
    y, p = _pair()
    e = y - p
    assert rmse(y, p) == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-12)
    assert rmse(y, p) == pytest.approx(skm.root_mean_squared_error(y, p), rel=1e-12)
    assert mae(y, p) == pytest.approx(np.mean(np.abs(e)), rel=1e-12)
    assert mae(y, p) == pytest.approx(skm.mean_absolute_error(y, p), rel=1e-12)
    r2_formula = 1 - np.sum(e**2) / np.sum((y - y.mean())**2)
    assert r2(y, p) == pytest.approx(r2_formula, rel=1e-12)
    assert r2(y, p) == pytest.approx(skm.r2_score(y, p), rel=1e-12)


def test_residual_variance_ignores_offset_unlike_mse():
    y, p = _pair()
    assert residual_variance(y, p) == pytest.approx(np.var(y - p, ddof=1), rel=1e-12)
    assert residual_variance(y, p, ddof=0) == pytest.approx(np.var(y - p), rel=1e-12)
    assert residual_variance(y, p + 5.0) == pytest.approx(residual_variance(y, p), rel=1e-9)
    assert rmse(y, p + 5.0) > 4.0


def test_improvement_reproduces_paper001_tables():
    # Table 2 (LS on temperature) and Table 3 (stepwise Models 1 and 2)
    assert improvement_percent(0.01850, 0.01194) == pytest.approx(35.46, abs=0.005)
    assert improvement_percent(0.01850, 0.00942) == pytest.approx(49.08, abs=0.005)
    assert improvement_percent(0.01850, 0.00842) == pytest.approx(54.49, abs=0.005)
    assert improvement_percent(1.0, 1.5) == pytest.approx(-50.0)


def test_bias_stability_is_std_of_cluster_means():
    rate_hz, cluster_s = 10.0, 100.0
    x = RNG.normal(0.0, 0.01, 25_500)               # 25 full clusters + a partial one
    means = x[:25_000].reshape(25, 1000).mean(axis=1)
    assert bias_stability(x, rate_hz, cluster_s) == pytest.approx(np.std(means, ddof=1),
                                                                  rel=1e-12)
    assert bias_stability(x, rate_hz, cluster_s, ddof=0) == pytest.approx(np.std(means),
                                                                          rel=1e-12)
    x_tail = x.copy()
    x_tail[25_000:] = 1e6                            # partial cluster dropped
    assert bias_stability(x_tail, rate_hz, cluster_s) == bias_stability(x, rate_hz, cluster_s)
    # already-averaged 100 s data: one sample per cluster
    assert bias_stability(means, 0.01, 100.0) == pytest.approx(np.std(means, ddof=1), rel=1e-12)


def _oadev_reference(y: np.ndarray, m: int) -> float:
    """Overlapping Allan deviation of rate samples at τ = m samples (NIST SP 1065 eq. 11),
    written from the phase (cumulative sum) form."""
    x = np.concatenate([[0.0], np.cumsum(y)])        # phase in sample units
    d = x[2 * m:] - 2 * x[m:-m] + x[:-2 * m]
    return float(np.sqrt(np.mean(d**2) / (2 * m**2)))


def test_allan_deviation_matches_allantools_and_formula():
    y = RNG.normal(0.0, 0.02, 4000) + np.cumsum(RNG.normal(0, 1e-4, 4000))
    res = allan_deviation(y, rate_hz=2.0, taus_s=[0.5, 5.0, 50.0])
    np.testing.assert_allclose(res.tau_s, [0.5, 5.0, 50.0])
    tau, adev, err, n = allantools.oadev(y, rate=2.0, data_type="freq",
                                         taus=np.array([0.5, 5.0, 50.0]))
    np.testing.assert_allclose(res.adev, adev, rtol=1e-12)
    np.testing.assert_allclose(res.error, err, rtol=1e-12)
    np.testing.assert_array_equal(res.n, n)
    for tau_s, value in zip(res.tau_s, res.adev):
        assert value == pytest.approx(_oadev_reference(y, int(round(tau_s * 2.0))), rel=1e-9)
    octave = allan_deviation(y, rate_hz=2.0)
    assert octave.tau_s[0] == 0.5 and np.all(np.diff(octave.tau_s) > 0)


def test_bias_stability_equals_allan_deviation_on_white_noise():
    """For white rate noise of std σ, both estimate σ/√m at τ = m samples.

    Over 200 seeds the mean of each squared estimator must match σ²/m, and the two must agree
    with each other, within 4 standard errors of the seed-to-seed scatter.
    """
    rate_hz, cluster_s, sigma, n_clusters = 10.0, 10.0, 0.05, 100
    m = int(rate_hz * cluster_s)
    truth = sigma**2 / m
    bs2, ad2 = [], []
    for seed in range(200):
        y = np.random.default_rng(seed).normal(0.003, sigma, m * n_clusters)
        bs2.append(bias_stability(y, rate_hz, cluster_s) ** 2)
        ad2.append(allan_deviation(y, rate_hz, [cluster_s]).adev[0] ** 2)
    bs2, ad2 = np.array(bs2), np.array(ad2)
    se = lambda v: v.std(ddof=1) / np.sqrt(v.size)      # noqa: E731
    assert abs(bs2.mean() - truth) < 4 * se(bs2)
    assert abs(ad2.mean() - truth) < 4 * se(ad2)
    assert abs((bs2 - ad2).mean()) < 4 * se(bs2 - ad2)
    # and the scatter of the cluster-std estimate is the chi-square one: rel. std √(2/(K−1))
    assert bs2.std(ddof=1) / truth == pytest.approx(np.sqrt(2 / (n_clusters - 1)), rel=0.2)


@pytest.mark.parametrize("func", [rmse, mae, r2, residual_variance])
def test_pair_metrics_reject_bad_input(func):
    good = np.array([1.0, 2.0, 3.5, 4.0])
    with pytest.raises(ValueError, match="y_pred contains NaN"):
        func(good, np.array([1.0, np.nan, 3.0, 4.0]))
    with pytest.raises(ValueError, match="y_true contains infinity"):
        func(np.array([1.0, np.inf, 3.0, 4.0]), good)
    with pytest.raises(ValueError, match="mismatched lengths: y_true has 4 samples, y_pred has 3"):
        func(good, good[:3])
    with pytest.raises(ValueError, match="must be 1-D"):
        func(good.reshape(2, 2), good.reshape(2, 2))


def test_scalar_metrics_reject_bad_input():
    with pytest.raises(ValueError, match="constant y_true"):
        r2([2.0, 2.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="needs at least 2 samples"):
        bias_stability(np.ones(150), 1.0, 100.0)
    with pytest.raises(ValueError, match="whole number of samples"):
        bias_stability(np.ones(1000), 3.0, 0.5)
    with pytest.raises(ValueError, match="x contains NaN"):
        bias_stability(np.full(1000, np.nan), 1.0, 10.0)
    with pytest.raises(ValueError, match="ddof must be 0 or 1"):
        bias_stability(np.arange(1000.0), 1.0, 10.0, ddof=2)
    with pytest.raises(ValueError, match="positive 'before'"):
        improvement_percent(0.0, 0.01)
    with pytest.raises(ValueError, match="finite"):
        improvement_percent(0.01, np.nan)
    with pytest.raises(ValueError, match="no averaging time .* fits in 10 samples"):
        allan_deviation(np.arange(10.0), 1.0, [100.0])
    with pytest.raises(ValueError, match="rate_hz must be positive"):
        allan_deviation(np.arange(10.0), 0.0)
