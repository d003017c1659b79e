"""Tests of the traditional (newrb-style) and the modified (Kohonen + OLS) RBF networks and of
their shared OLS machinery (estimators/rbf_common.py, rbf_network.py, rbf_modified.py).

References are independent of the code under test: brute-force least squares
(``numpy.linalg.lstsq``) for the OLS ranking, weights and error-reduction ratios; known smooth
functions of temperature T [°C] and its rate dT/dt [K/min] for the fits; paper 002's claim
(same error with fewer centres) on paper-002-like data.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.rbf_common import ForwardOLS, gaussian_design
from rlgsim.estimators.rbf_modified import ModifiedRBFNetwork
from rlgsim.estimators.rbf_network import RBFNetwork


# -- known smooth functions (°/h) ---------------------------------------------------------
def bias_vs_t(T):
    """Smooth nonlinear gyro bias [°/h] against temperature T [°C], -40..60 °C."""
    x = (T - 20.0) / 50.0
    return 0.5 + 4e-3 * x + 3e-3 * x**2 - 2e-3 * x**3 + 1.5e-3 * np.tanh((T - 5.0) / 8.0)


def bias_vs_t_rate(T, R):
    """Bias [°/h] against T [°C] and dT/dt R [K/min] (rate and cross terms added)."""
    x = (T - 20.0) / 50.0
    return bias_vs_t(T) + 1.5e-3 * np.tanh(R / 1.5) + 1e-3 * R / 3.0 * x


def cycle_run(rate_c_per_min: float, seed: int, hours: float = 8.0):
    """Paper-002-like run: 100 s averages of a lagged gyro temperature in a chamber cycle.

    Chamber: 0 °C for 1 h, then ramps at ``rate`` between 60 °C and -40 °C with 2 h holds
    (paper 002 §4.1); gyro: first-order lag (20 min) plus 12 K self-heating (40 min time
    constant). Returns X = [T °C, dT/dt K/min] per 100 s and the noisy bias [°/h] with
    sigma 6e-4 °/h (white noise of 1e-4 °/sqrt(h) averaged over 100 s).
    """
    dt = 10.0
    t = np.arange(0.0, hours * 3600.0 + dt, dt)
    knots_t, knots_T = [0.0, 3600.0], [0.0, 0.0]
    for target, hold in [(60.0, False), (60.0, True), (-40.0, False), (-40.0, True)] * 3:
        step = 7200.0 if hold else abs(target - knots_T[-1]) / (rate_c_per_min / 60.0)
        knots_t.append(knots_t[-1] + step)
        knots_T.append(target)
    chamber = np.interp(t, knots_t, knots_T)
    a = math.exp(-dt / 1200.0)
    lag = np.zeros_like(t)
    for k in range(1, t.size):
        slope = (chamber[k] - chamber[k - 1]) / dt
        lag[k] = lag[k - 1] * a - slope * 1200.0 * (1.0 - a)
    T = chamber + lag + 12.0 * (1.0 - np.exp(-t / 2400.0))
    m = 10
    nb = (t.size - 1) // m
    T100 = T[1:nb * m + 1].reshape(nb, m).mean(axis=1)
    R100 = np.gradient(T100, 100.0) * 60.0
    rng = np.random.default_rng(seed)
    y = bias_vs_t_rate(T100, R100) + 6e-4 * rng.standard_normal(nb)
    return np.column_stack([T100, R100]), y


def lstsq_with_bias(P, y):
    M = np.column_stack([P, np.ones(len(y))])
    sol = np.linalg.lstsq(M, y, rcond=None)[0]
    return sol[:-1], sol[-1], y - M @ sol


# -- scikit-learn contract ---------------------------------------------------------------------
# No check is expected to fail. Random data in the checks cannot reach rho/goal, so the
# networks' ConvergenceWarning is expected there.
@pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")
@parametrize_with_checks([RBFNetwork(), ModifiedRBFNetwork(random_state=0)],
                         expected_failed_checks=lambda est: {})
def test_sklearn_contract(estimator, check):
    check(estimator)


# -- Gaussian layer ----------------------------------------------------------------------------
def test_gaussian_is_half_at_spread_and_matches_paper_002_eq2():
    c = np.zeros((1, 2))
    Z = np.array([[0.0, 0.0], [0.7, 0.0], [0.3, -0.4], [1.0, 1.0]])
    phi = gaussian_design(Z, c, spread=0.7)[:, 0]
    assert phi[0] == 1.0
    assert phi[1] == pytest.approx(0.5, rel=1e-14)
    assert phi[2] == pytest.approx(0.5 ** ((0.5 / 0.7) ** 2), rel=1e-14)
    delta = 0.7 / math.sqrt(math.log(2.0))          # paper 002 eq. (2) receptive field
    r2 = (Z**2).sum(axis=1)
    np.testing.assert_allclose(phi, np.exp(-r2 / delta**2), rtol=1e-13)


# -- OLS machinery against brute-force least squares -------------------------------------------
def _small_problem(seed=3):
    rng = np.random.default_rng(seed)
    Z = rng.uniform(-2, 2, size=(60, 2))
    C = rng.uniform(-2, 2, size=(25, 2))
    d = 3.0 + np.sin(1.3 * Z[:, 0]) * np.cos(Z[:, 1]) + 0.05 * rng.standard_normal(60)
    return gaussian_design(Z, C, 1.0), d


@pytest.mark.parametrize("bias", ["fixed", "after", None])
def test_ols_picks_largest_error_reduction_like_brute_force(bias):
    """Each pick minimises the residual of a fresh least-squares fit over all candidates."""
    P, d = _small_problem()
    ols = ForwardOLS(P, d, bias=bias)
    ones = np.ones((len(d), 1)) if bias == "fixed" else np.empty((len(d), 0))
    chosen: list[int] = []
    for _ in range(8):
        sse = {}
        for i in set(range(P.shape[1])) - set(chosen):
            M = np.column_stack([ones, P[:, chosen + [i]]])
            r = d - M @ np.linalg.lstsq(M, d, rcond=None)[0]
            sse[i] = r @ r
        best = min(sse, key=sse.get)
        assert ols.step() == best
        chosen.append(best)
    assert ols.selected == chosen


@pytest.mark.parametrize("bias", ["fixed", "after", None])
def test_ols_weights_and_error_ratios_equal_least_squares(bias):
    P, d = _small_problem(seed=7)
    ols = ForwardOLS(P, d, bias=bias)
    for _ in range(10):
        ols.step()
    Ps = P[:, ols.selected]
    w, b = ols.coefficients()
    if bias is None:
        ref_w = np.linalg.lstsq(Ps, d, rcond=None)[0]
        ref_b, energy = 0.0, d @ d
        resid = d - Ps @ ref_w
    else:
        ref_w, ref_b, resid = lstsq_with_bias(Ps, d)
        energy = ((d - d.mean()) ** 2).sum() if bias == "fixed" else d @ d
    np.testing.assert_allclose(w, ref_w, rtol=1e-8, atol=1e-10)
    assert b == pytest.approx(ref_b, rel=1e-9, abs=1e-12)
    # 1 - sum(err) = residual energy / target energy (Chen et al. 1991 eq. 17).
    if bias == "after":      # ratios refer to the fit without bias; newrb adds the bias later
        r0 = d - Ps @ np.linalg.lstsq(Ps, d, rcond=None)[0]
        assert ols.unexplained == pytest.approx((r0 @ r0) / energy, rel=1e-9)
        np.testing.assert_allclose(ols.residual_with_bias(), resid, atol=1e-10)
    else:
        assert ols.unexplained == pytest.approx((resid @ resid) / energy, rel=1e-9)
        np.testing.assert_allclose(ols.residual(), resid, atol=1e-10)
    assert all(e >= 0 for e in ols.err_ratios)


def test_ols_skips_numerically_dependent_candidates():
    P, d = _small_problem()
    P = np.column_stack([P, P[:, 4]])                # exact duplicate of column 4
    ols = ForwardOLS(P, d, bias="fixed")
    picks = [ols.step() for _ in range(P.shape[1])]
    got = [p for p in picks if p is not None]
    assert not ({4, P.shape[1] - 1} <= set(got))     # never both copies
    assert picks[-1] is None


# -- fits of known smooth functions ------------------------------------------------------------
def _rel_rmse(model, X, y):
    return float(np.sqrt(np.mean((model.predict(X) - y) ** 2)) / np.std(y))


def test_traditional_fits_bias_vs_temperature_1d():
    rng = np.random.default_rng(11)
    T = rng.uniform(-40, 60, 200)[:, None]
    y = bias_vs_t(T[:, 0])
    goal = 1e-5 * y.var()
    net = RBFNetwork(goal=goal, spread=0.5).fit(T, y)
    assert net.mse_ <= goal
    grid = np.linspace(-40, 60, 1001)[:, None]
    # Between the training temperatures: RMSE within 1 % of the bias' spread (1.9e-3 °/h).
    assert _rel_rmse(net, grid, bias_vs_t(grid[:, 0])) < 0.01
    assert net.n_centers_ < 30


def test_modified_fits_bias_vs_temperature_1d():
    rng = np.random.default_rng(11)
    T = rng.uniform(-40, 60, 200)[:, None]
    y = bias_vs_t(T[:, 0])
    net = ModifiedRBFNetwork(rho=1e-5, spread=0.5, random_state=0).fit(T, y)
    assert net.unexplained_ < 1e-5
    grid = np.linspace(-40, 60, 1001)[:, None]
    assert _rel_rmse(net, grid, bias_vs_t(grid[:, 0])) < 0.01
    assert net.n_centers_ < 30


@pytest.mark.parametrize("make", [
    lambda y: RBFNetwork(goal=1e-4 * y.var(), spread=0.7),
    lambda y: ModifiedRBFNetwork(rho=1e-4, spread=0.7, random_state=0),
], ids=["traditional", "modified"])
def test_fits_bias_vs_temperature_and_rate_2d(make):
    rng = np.random.default_rng(5)
    X = np.column_stack([rng.uniform(-40, 60, 400), rng.uniform(-5, 5, 400)])
    y = bias_vs_t_rate(*X.T)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)      # goal / rho must be reached
        net = make(y).fit(X, y)
    assert np.mean((net.predict(X) - y) ** 2) <= 1e-4 * y.var()
    Xt = np.column_stack([rng.uniform(-40, 60, 2000), rng.uniform(-5, 5, 2000)])
    # Off the training points: RMSE within 2 % of the bias' spread (3.0e-3 °/h).
    assert _rel_rmse(net, Xt, bias_vs_t_rate(*Xt.T)) < 0.02


# -- the two designs ----------------------------------------------------------------------------
def test_traditional_reaches_goal_with_no_more_neurons_than_needed():
    X, y = cycle_run(3.0, seed=1)
    goal = 1.2 * 6e-4**2
    net = RBFNetwork(goal=goal, spread=0.5).fit(X, y)
    mse = np.mean((y - net.predict(X)) ** 2)              # independent of mse_
    assert mse == pytest.approx(net.mse_, rel=1e-8)
    assert mse <= goal < net.mse_history_[-2]
    assert np.all(np.diff(net.mse_history_) <= 1e-18)      # adding a neuron never hurts
    np.testing.assert_array_equal(net.centers_, X[net.center_indices_])
    P = gaussian_design((X - net.x_mean_) / net.x_scale_,
                        (net.centers_ - net.x_mean_) / net.x_scale_, net.spread)
    w, b, _ = lstsq_with_bias(P, y)
    np.testing.assert_allclose(net.weights_, w, rtol=1e-6, atol=1e-9 * np.abs(w).max())
    assert net.intercept_ == pytest.approx(b, rel=1e-6)


def test_modified_weights_and_ratios_against_least_squares():
    X, y = cycle_run(5.0, seed=2)
    net = ModifiedRBFNetwork(rho=0.05, spread=0.5, random_state=3).fit(X, y)
    P = gaussian_design((X - net.x_mean_) / net.x_scale_,
                        (net.centers_ - net.x_mean_) / net.x_scale_, net.spread)
    w, b, resid = lstsq_with_bias(P, y)
    np.testing.assert_allclose(net.weights_, w, rtol=1e-6, atol=1e-9 * np.abs(w).max())
    assert net.intercept_ == pytest.approx(b, rel=1e-6)
    energy = ((y - y.mean()) ** 2).sum()
    unexplained = ((y - net.predict(X)) ** 2).sum() / energy
    assert 1.0 - net.err_ratios_.sum() == pytest.approx(unexplained, rel=1e-8)
    assert unexplained == pytest.approx((resid @ resid) / energy, rel=1e-8)
    assert unexplained < 0.05 <= 1.0 - net.err_ratios_[:-1].sum()   # stopped at eq. (16)
    # Candidates are the prototypes of the non-empty map nodes; centres are among them.
    assert net.n_candidates_ == np.count_nonzero(net.node_counts_)
    assert net.node_counts_.sum() == len(y)
    assert all((net.candidate_centers_ == c).all(axis=1).any() for c in net.centers_)


@pytest.mark.parametrize("rate,seed", [(1.0, 0), (3.0, 1), (5.0, 2)])
def test_modified_reaches_same_error_with_fewer_centres(rate, seed):
    """Paper 002 §4.2: the modified RBFNN reaches the traditional one's error with fewer
    centres. Same 8 h run (288 samples, 100 s averages), same spread; goal = 1.2x the noise
    variance, i.e. rho = goal / var(y) for the modified network."""
    X, y = cycle_run(rate, seed=seed)
    goal = 1.2 * 6e-4**2
    trad = RBFNetwork(goal=goal, spread=0.5).fit(X, y)
    mod = ModifiedRBFNetwork(rho=goal / y.var(), spread=0.5, random_state=seed).fit(X, y)
    assert trad.mse_ <= goal and mod.mse_ <= goal
    assert mod.n_centers_ < trad.n_centers_
    # Where the saving comes from: newrb ranks candidates against the raw target (0.5 °/h
    # offset); ranked with the bias in the model it needs fewer neurons too.
    centred = RBFNetwork(goal=goal, spread=0.5, centred_ranking=True).fit(X, y)
    assert centred.mse_ <= goal and centred.n_centers_ < trad.n_centers_


# -- standardisation, reproducibility -----------------------------------------------------------
@pytest.mark.parametrize("make", [
    lambda y: RBFNetwork(goal=1.2 * 6e-4**2, spread=0.7),
    lambda y: ModifiedRBFNetwork(rho=1.2 * 6e-4**2 / y.var(), spread=0.7, random_state=4),
], ids=["traditional", "modified"])
def test_input_units_do_not_matter(make):
    """Inputs are standardised: dT/dt in K/s instead of K/min, T in K instead of °C."""
    X, y = cycle_run(3.0, seed=4)
    a = make(y).fit(X, y)
    X2 = np.column_stack([X[:, 0] + 273.15, X[:, 1] / 60.0])
    b = make(y).fit(X2, y)
    assert a.n_centers_ == b.n_centers_
    np.testing.assert_allclose(a.predict(X), b.predict(X2), rtol=1e-9, atol=1e-12)


def test_modified_reproducible_from_random_state():
    X, y = cycle_run(3.0, seed=5)
    a = ModifiedRBFNetwork(rho=0.05, random_state=8).fit(X, y)
    b = ModifiedRBFNetwork(rho=0.05, random_state=8).fit(X, y)
    c = ModifiedRBFNetwork(rho=0.05, random_state=9).fit(X, y)
    np.testing.assert_array_equal(a.centers_, b.centers_)
    np.testing.assert_array_equal(a.weights_, b.weights_)
    assert not np.array_equal(a.som_weights_, c.som_weights_)


def test_default_map_size_follows_5_sqrt_n_rule():
    X, y = cycle_run(3.0, seed=6)                     # 288 samples: 5*sqrt(288) = 85 nodes
    net = ModifiedRBFNetwork(rho=0.05, random_state=0).fit(X, y)
    assert net.som_shape_ == (10, 10)                 # ceil(sqrt(84.9)) = 10
    assert net.som_weights_.shape == (10, 10, 2)


def test_limits_and_convergence_warning():
    X, y = cycle_run(3.0, seed=7)
    with pytest.warns(ConvergenceWarning, match="did not reach goal"):
        net = RBFNetwork(goal=1e-12, max_centers=3).fit(X, y)
    assert net.n_centers_ == 3
    with pytest.warns(ConvergenceWarning, match="did not fall below rho"):
        mod = ModifiedRBFNetwork(rho=1e-6, max_centers=2, random_state=0).fit(X, y)
    assert mod.n_centers_ == 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        RBFNetwork().fit(X[:20], y[:20])             # goal 0: grows to max, no warning


def test_constant_target_needs_no_centre():
    X, _ = cycle_run(1.0, seed=0)
    y = np.full(len(X), 0.5)
    for net in (RBFNetwork(), ModifiedRBFNetwork(random_state=0)):
        net.fit(X, y)
        assert net.n_centers_ == 0
        np.testing.assert_allclose(net.predict(X), 0.5)


# -- bad input ----------------------------------------------------------------------------------
ESTIMATORS = [RBFNetwork, lambda: ModifiedRBFNetwork(random_state=0)]


@pytest.mark.parametrize("make", ESTIMATORS, ids=["traditional", "modified"])
@pytest.mark.parametrize("case,match", [
    ("nan_x", "NaN"), ("inf_x", "infinity"), ("nan_y", "NaN"), ("lengths", "inconsistent"),
    ("one_sample", "1 sample"), ("constant", "constant input"), ("empty", "0 sample"),
])
def test_bad_input_raises_clear_value_error(make, case, match):
    X, y = cycle_run(1.0, seed=0)
    X = X[:40].copy()
    y = y[:40].copy()
    if case == "nan_x":
        X[3, 0] = np.nan
    elif case == "inf_x":
        X[5, 1] = np.inf
    elif case == "nan_y":
        y[2] = np.nan
    elif case == "lengths":
        y = y[:-1]
    elif case == "one_sample":
        X, y = X[:1], y[:1]
    elif case == "constant":
        X[:, 1] = 0.0
    elif case == "empty":
        X, y = X[:0], y[:0]
    with pytest.raises(ValueError, match=match):
        make().fit(X, y)


@pytest.mark.parametrize("net,match", [
    (RBFNetwork(spread=0.0), "spread"), (RBFNetwork(spread=np.inf), "spread"),
    (RBFNetwork(goal=-1.0), "goal"), (RBFNetwork(max_centers=0), "max_centers"),
    (ModifiedRBFNetwork(rho=1.0), "rho"), (ModifiedRBFNetwork(rho=0.0), "rho"),
    (ModifiedRBFNetwork(som_shape=(0, 3)), "som_shape"),
    (ModifiedRBFNetwork(som_shape=5), "som_shape"),
    (ModifiedRBFNetwork(som_iterations=0), "som_iterations"),
    (ModifiedRBFNetwork(som_sigma=-1.0), "som_sigma"),
    (ModifiedRBFNetwork(max_centers=2.5), "max_centers"),
])
def test_bad_parameters_raise_value_error(net, match):
    X, y = cycle_run(1.0, seed=0)
    with pytest.raises(ValueError, match=match):
        net.fit(X, y)


def test_predict_checks_feature_count_and_finiteness():
    X, y = cycle_run(1.0, seed=0)
    net = ModifiedRBFNetwork(rho=0.1, random_state=0).fit(X, y)
    with pytest.raises(ValueError, match="features"):
        net.predict(X[:, :1])
    Xb = X.copy()
    Xb[0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        net.predict(Xb)
