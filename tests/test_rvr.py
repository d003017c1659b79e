"""Tests of estimators/rvr.py: the fastrvm-cored Tipping-Faul RVR against an independent
re-estimation (EM) RVR written here from Tipping 2001, on a noisy 1-D nonlinear function."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlgsim.estimators.kernels import squared_distances
from rlgsim.estimators.rvr import RVR, rbf_from_sqdist

NOISE = 0.1


def sinc_data(n=100, seed=0, noise=NOISE):
    rng = np.random.default_rng(seed)
    x = np.sort(rng.uniform(-10.0, 10.0, n))
    return x[:, None], np.sinc(x / np.pi) + noise * rng.standard_normal(n)


def truth(X):
    return np.sinc(X[:, 0] / np.pi)


def em_rvr(x, t, width, max_iter=3000, prune=1e9, tol=1e-8):
    """Reference RVR: Tipping 2001 §2-3 re-estimation, eq. (13) Sigma and mu, eq. (16)
    alpha_i = gamma_i / mu_i^2, eq. (18) beta = (N - sum gamma) / ||t - Phi mu||^2, starting
    from every basis function and pruning those whose alpha exceeds ``prune``. Same kernel
    exp(-r^2/width^2), bias as a free basis function (alpha = 0)."""
    N = t.size
    Phi = np.column_stack([np.exp(-(x[:, None] - x[None, :]) ** 2 / width ** 2), np.ones(N)])
    keep = np.arange(N + 1)
    alpha = np.full(N + 1, 1.0 / N)
    alpha[-1] = 0.0
    beta = 1.0 / (0.1 * np.std(t)) ** 2
    for _ in range(max_iter):
        P, a = Phi[:, keep], alpha[keep]
        Sig = np.linalg.inv(np.diag(a) + beta * P.T @ P)
        mu = beta * Sig @ P.T @ t
        gamma = 1.0 - a * np.diag(Sig)
        new = gamma / mu ** 2
        new[keep == N] = 0.0
        beta = (N - gamma.sum()) / np.sum((t - P @ mu) ** 2)
        old = alpha[keep].copy()
        alpha[keep] = new
        change = np.max(np.abs(np.log(new[:-1]) - np.log(old[:-1])))
        keep = keep[new < prune]
        if change < tol:
            break
    P, a = Phi[:, keep], alpha[keep]
    Sig = np.linalg.inv(np.diag(a) + beta * P.T @ P)
    mu = beta * Sig @ P.T @ t

    def predict(xq):
        Pq = np.column_stack([np.exp(-(xq[:, None] - x[keep[:-1]][None, :]) ** 2 / width ** 2),
                              np.ones(xq.size)])
        return Pq @ mu, np.sqrt(1.0 / beta + np.einsum("ij,jk,ik->i", Pq, Sig, Pq))

    return keep[:-1], beta, predict


@parametrize_with_checks([RVR(), RVR(width=0.7, fit_intercept=False, max_iter=500)])
def test_sklearn_contract(estimator, check):
    check(estimator)


def test_sparse_accurate_and_agrees_with_independent_em_rvr():
    X, y = sinc_data()
    model = RVR(width=2.0).fit(X, y)
    Xq = np.linspace(-10, 10, 400)[:, None]
    mean, std = model.predict(Xq, return_std=True)
    # sparse: a handful of relevance vectors out of 100 points
    assert 3 <= model.n_relevance_ <= 12
    assert model.relevance_vectors_.shape == (model.n_relevance_, 1)
    assert np.array_equal(model.relevance_vectors_, X[model.relevance_])
    # accurate: error against the noise-free function well below the noise
    rmse = np.sqrt(np.mean((mean - truth(Xq)) ** 2))
    assert rmse < 0.5 * NOISE
    assert model.noise_std_ == pytest.approx(NOISE, rel=0.25)
    # independent implementation on the same data
    rv_em, beta_em, predict_em = em_rvr(X[:, 0], y, 2.0)
    mean_em, std_em = predict_em(Xq[:, 0])
    assert rv_em.size <= 12
    assert np.sqrt(np.mean((mean - mean_em) ** 2)) < 0.25 * NOISE
    assert np.max(np.abs(mean - mean_em)) < 0.6 * NOISE
    assert np.allclose(std, std_em, rtol=0.2)


def test_posterior_is_consistent_with_reported_hyperparameters():
    """covariance_ = (beta Phi'Phi + diag(alpha, 0))^-1 and the mean = beta Sigma Phi' t
    (Tipping 2001 eq. 13) — checks the alpha scaling and that the bias is in the covariance."""
    X, y = sinc_data(seed=3)
    m = RVR(width=1.5).fit(X, y)
    Phi = np.column_stack([rbf_from_sqdist(squared_distances(X, m.relevance_vectors_), 1.5),
                           np.ones(len(y))])
    Sig = np.linalg.inv(m.beta_ * Phi.T @ Phi + np.diag(np.r_[m.alpha_, 0.0]))
    assert np.allclose(Sig, m.covariance_, rtol=1e-5, atol=1e-9 * np.abs(Sig).max())
    assert np.allclose(m.beta_ * Sig @ Phi.T @ y, np.r_[m.dual_coef_, m.intercept_],
                       atol=1e-6)


def test_predictive_std_is_calibrated():
    X, y = sinc_data(n=150, seed=5)
    m = RVR(width=2.0).fit(X, y)
    Xq, yq = sinc_data(n=2000, seed=6)
    mean, std = m.predict(Xq, return_std=True)
    inside = np.mean(np.abs(yq - mean) <= 1.96 * std)
    assert 0.90 <= inside <= 0.98


def test_matches_fastrvm_public_estimator():
    """Our kernel convention exp(-r^2/width^2) = fastrvm's rbf with gamma = 1/width^2."""
    fastrvm = pytest.importorskip("fastrvm")
    X, y = sinc_data(seed=2)
    ours = RVR(width=2.5).fit(X, y)
    theirs = fastrvm.RVR(kernel="rbf", gamma=1.0 / 2.5 ** 2, fit_intercept=True).fit(X, y)
    assert np.array_equal(ours.relevance_, theirs.relevance_)
    Xq = np.linspace(-10, 10, 50)[:, None]
    assert np.allclose(ours.predict(Xq), theirs.predict(Xq), atol=1e-6)


def test_si_unit_targets_are_scale_equivariant():
    """Gyro bias in rad/s is ~1e-8: the fit must not depend on the unit of y."""
    X, y = sinc_data(seed=4)
    a = RVR(width=2.0).fit(X, y)
    b = RVR(width=2.0).fit(X, 1e-8 * y)
    assert np.array_equal(a.relevance_, b.relevance_)
    Xq = np.linspace(-10, 10, 30)[:, None]
    ma, sa = a.predict(Xq, return_std=True)
    mb, sb = b.predict(Xq, return_std=True)
    assert np.allclose(mb, 1e-8 * ma, rtol=1e-6, atol=1e-15)
    assert np.allclose(sb, 1e-8 * sa, rtol=1e-6)


def test_default_width_and_constant_target():
    X, y = sinc_data()
    m = RVR().fit(X, y)
    assert m.width_ == pytest.approx(np.sqrt(X.var()))
    c = RVR().fit(X, np.full(len(y), 3.5))
    assert c.n_relevance_ == 0
    assert np.allclose(c.predict(X), 3.5)


@pytest.mark.parametrize("X, y, match", [
    (np.array([[0.0], [np.nan], [2.0]]), np.array([1.0, 2.0, 3.0]), "NaN"),
    (np.array([[0.0], [1.0], [2.0]]), np.array([1.0, np.inf, 3.0]), "infinity"),
    (np.array([[0.0], [1.0], [2.0]]), np.array([1.0, 2.0]), "inconsistent numbers of samples"),
    (np.array([[1.0, 0.0], [1.0, 1.0], [1.0, 2.0]]), np.array([1.0, 2.0, 3.0]),
     "constant input.*column 0"),
    (np.array([[1.0]]), np.array([1.0]), "at least 2 samples"),
])
def test_bad_input_raises_clear_value_error(X, y, match):
    with pytest.raises(ValueError, match=match):
        RVR().fit(X, y)


@pytest.mark.parametrize("params, match", [({"width": 0.0}, "width"), ({"width": "auto"}, "width"),
                                           ({"max_iter": 0}, "max_iter")])
def test_bad_parameters(params, match):
    X, y = sinc_data(n=20)
    with pytest.raises(ValueError, match=match):
        RVR(**params).fit(X, y)


def test_max_basis_limits_candidates_and_keeps_the_fit():
    X, y = sinc_data(n=300, seed=7)
    full = RVR(width=2.0, max_basis=None).fit(X, y)
    capped = RVR(width=2.0, max_basis=60).fit(X, y)
    centres = np.unique(np.linspace(0, 299, 60).round().astype(int))
    assert np.all(np.isin(capped.relevance_, centres))
    assert np.all(np.diff(capped.relevance_) > 0)
    Xq = np.linspace(-10, 10, 200)[:, None]
    assert np.sqrt(np.mean((capped.predict(Xq) - full.predict(Xq)) ** 2)) < 0.2 * NOISE
    assert capped.noise_std_ == pytest.approx(full.noise_std_, rel=0.1)


def test_diverged_core_fit_raises_instead_of_returning_garbage(monkeypatch):
    import rlgsim.estimators.rvr as rvr

    def broken(basis, ts, fit_intercept, max_iter):
        return (np.array([3, basis.shape[1]]), np.array([4.5e4, 1.0]), np.array([1.0, 0.0]),
                -0.017, np.eye(2), 3310, 0)

    monkeypatch.setattr(rvr, "_core_inference", broken)
    X, y = sinc_data(n=30)
    with pytest.raises(FloatingPointError, match="diverged.*max_basis"):
        RVR(width=2.0).fit(X, y)
