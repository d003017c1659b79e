"""The identification maths (rlgsim.estimators.identify) against independent references:
statsmodels OLS for standard errors and the BIC, known synthetic laws for the term selection,
synthetic white noise and random walk for the Allan fit."""

import dataclasses

import numpy as np
import pytest
import statsmodels.api as sm

from rlgsim.estimators.identify.allan_noise import fit_allan
from rlgsim.estimators.identify.lsq_stats import ar1_inflation, fit, screen
from rlgsim.estimators.identify.term_selection import Term, _bic, select_terms


def test_standard_errors_equal_statsmodels_ols_for_a_linear_model():
    rng = np.random.default_rng(3)
    x = np.linspace(-1, 1, 400)
    y = 0.3 + 1.7 * x - 0.4 * x ** 2 + 0.05 * rng.standard_normal(x.size)
    X = np.column_stack([np.ones_like(x), x, x ** 2])
    ref = sm.OLS(y, X).fit()
    res = fit(lambda b: X @ b - y, np.zeros(3), ["a", "b", "c"])
    np.testing.assert_allclose(res.x, ref.params, rtol=1e-7, atol=1e-10)
    # never below OLS's: our Jacobian is scipy's forward differences (step √ε·max(1, |x|)), so
    # each entry carries a relative rounding error of about √ε ≈ 1.5e-8, which (JᵀJ)⁻¹ may
    # amplify by up to the condition number κ(X) in the standard errors; statsmodels solves
    # with the exact design. Allow that much and no more (κ ≈ 3.7 here: ~5e-7, not 1e-9).
    kappa = np.linalg.cond(X)
    tol = 10 * kappa * np.sqrt(np.finfo(float).eps)
    assert tol < 1e-5
    assert np.all(res.se >= ref.bse * (1 - tol))
    np.testing.assert_allclose(res.se, ref.bse, rtol=0.5)    # white residual: hardly inflated
    plain = fit(lambda b: X @ b - y, np.zeros(3), ["a", "b", "c"], batches=len(y))
    np.testing.assert_allclose(plain.se, ref.bse, rtol=0.2)


def test_autocorrelated_residuals_inflate_the_standard_errors():
    rng = np.random.default_rng(4)
    e = np.zeros(5000)
    for k in range(1, e.size):
        e[k] = 0.9 * e[k - 1] + rng.standard_normal()
    rho, factor = ar1_inflation(e)
    assert rho == pytest.approx(0.9, abs=0.02)
    assert factor == pytest.approx(np.sqrt(1.9 / 0.1), rel=0.1)


def test_screen_refuses_duplicate_and_dead_parameters_and_says_why():
    rng = np.random.default_rng(5)
    a = rng.standard_normal(200)
    b = rng.standard_normal(200)
    i, why = screen(np.column_stack([a, b, 2 * a + 1e-6 * rng.standard_normal(200)]),
                    ["p", "q", "r"])
    assert i in (0, 2) and ("correlation" in why or "rank-deficient" in why)
    i, why = screen(np.column_stack([a, np.zeros(200)]), ["p", "dead"])
    assert i == 1 and "do not respond" in why
    assert screen(np.column_stack([a, b]), ["p", "q"]) is None


def test_bic_differences_equal_statsmodels():
    rng = np.random.default_rng(6)
    x = rng.standard_normal(300)
    y = 1 + 0.5 * x + rng.standard_normal(300)
    X1 = np.column_stack([np.ones(300), x])
    X2 = np.column_stack([X1, x ** 2])
    ours = _bic(y, X2, 0) - _bic(y, X1, 0)
    ref = sm.OLS(y, X2).fit().bic - sm.OLS(y, X1).fit().bic
    assert ours == pytest.approx(ref, rel=1e-9, abs=1e-9)


def test_selection_finds_the_true_terms_among_collinear_candidates():
    rng = np.random.default_rng(7)
    n = 600
    T = np.concatenate([np.linspace(-20, 60, n // 2), np.linspace(60, -20, n // 2)])
    rate = np.gradient(T) + 0.3 * rng.standard_normal(n)
    grad = 0.8 * rate + 0.2 * rng.standard_normal(n)         # a stand-in for the rate
    truth = 0.02 + 3e-4 * T - 0.01 * rate + 0.006 * np.tanh((T - 25.0) / 4.0)
    y = truth + 2e-4 * rng.standard_normal(n)
    cands = [Term("c1", lambda th: T), Term("c2", lambda th: T ** 2),
             Term("c3", lambda th: T ** 3), Term("rate", lambda th: rate),
             Term("gradient", lambda th: grad),
             Term("knee", lambda th: np.tanh((T - th[0]) / th[1]), ("center_c", "width_k"),
                  [np.array([c, w]) for c in np.linspace(-10, 50, 13) for w in (1.0, 5.0)],
                  lower=(-20, 0.2), upper=(60, 40))]
    sel = select_terms(y, cands)
    assert set(sel.terms) == {"c1", "rate", "knee"}
    for name, true in (("c1", 3e-4), ("rate", -0.01), ("knee", 0.006), ("knee.center_c", 25.0),
                       ("knee.width_k", 4.0)):
        assert abs(sel.value(name) - true) < 4 * sel.se(name), name


def test_allan_fit_recovers_white_noise_and_random_walk_with_intervals():
    f, hours = 10.0, 8.0
    n = int(hours * 3600 * f)
    arw, rrw = 0.002, 0.05                       # °/√h, °/h/√h: RRW dominates beyond 100 s
    covered_rrw = unresolved_bi = 0
    seeds = range(8, 14)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        y = arw * 60 * np.sqrt(f) * rng.standard_normal(n)
        y += np.cumsum(rrw / 60 / np.sqrt(f) * rng.standard_normal(n))
        res = fit_allan(y, f)
        assert res.values["arw_deg_per_sqrt_h"] == pytest.approx(arw, rel=0.05)
        assert res.values["rrw_deg_per_h_per_sqrt_h"] == pytest.approx(rrw, rel=0.3)
        lo, hi = res.intervals["rrw_deg_per_h_per_sqrt_h"]
        covered_rrw += lo <= rrw <= hi
        unresolved_bi += res.intervals["bi_deg_per_h"][0] == 0.0     # there is no flicker
    # 95 % intervals, approximate (correlated Allan estimates): most of six runs
    assert covered_rrw >= 4 and unresolved_bi >= 4
    with pytest.raises(ValueError, match="too short|at least"):
        fit_allan(y[:50], f)


def _collinear_inputs(rng: np.random.Generator, n: int = 300):
    """A ramp up and down in temperature T [°C], its rate with noise, and a gradient that nearly
    repeats the rate (the rate's and the gradient's noise drawn from ``rng`` in that order)."""
    T = np.concatenate([np.linspace(-20, 60, n // 2), np.linspace(60, -20, n // 2)])
    rate = np.gradient(T) + 0.3 * rng.standard_normal(n)
    grad = rate + 0.05 * rng.standard_normal(n)
    return T, rate, grad


def _collinear_candidates(T: np.ndarray, rate: np.ndarray, grad: np.ndarray) -> list[Term]:
    """The candidate terms c1, c2, rate and gradient of :func:`_collinear_inputs`."""
    return [Term("c1", lambda th: T), Term("c2", lambda th: T ** 2),
            Term("rate", lambda th: rate), Term("gradient", lambda th: grad)]


def _collinear_law(seed: int, n: int = 300):
    """A rate term and a gradient that nearly repeats it (a ramp drives both); the truth uses
    the rate only; white noise large enough that the two cannot be told apart."""
    rng = np.random.default_rng(seed)
    T, rate, grad = _collinear_inputs(rng, n)
    y = 0.02 + 3e-4 * T - 0.01 * rate + 0.004 * rng.standard_normal(n)
    cands = _collinear_candidates(T, rate, grad)
    return y, cands, {"c1": T, "c2": T ** 2, "rate": rate, "gradient": grad}


def test_unseparable_terms_are_named_and_averaged_with_selection_uncertainty():
    y, cands, cols = _collinear_law(1)
    sel = select_terms(y, cands)
    assert sel.vif[sel.terms[-1]] > 1.0
    groups = [set(g) for g, _ in sel.unseparable]
    assert {"rate", "gradient"} in groups
    reason = sel.unseparable[groups.index({"rate", "gradient"})][1]
    assert "cannot be separated" in reason and "ramps at several rates" in reason
    # the averaged rate and gradient add up to the combined effect, which is well determined
    total = sel.averaged["rate"][0] + sel.averaged["gradient"][0]
    assert total == pytest.approx(-0.01, abs=1.5e-3)
    assert sum(sel.averaged[t][2] for t in ("rate", "gradient")) > 0.95
    # the combined effect along their common direction is determined, and named in the line
    lead, value, se_c, slopes = sel.combined[("rate", "gradient")]
    true_c = -0.01 * slopes["rate"]                     # the truth holds the rate only
    assert abs(value - true_c) < 3 * se_c and se_c < 0.5 * max(sel.averaged["rate"][1],
                                                               sel.averaged["gradient"][1])
    assert f"combined effect, in units of {lead}" in reason
    mean, se = sel.predict(cols)
    assert np.all(se > 0) and np.sqrt(np.mean((mean - (y + sel.fit.residual)) ** 2)) < 1e-3
    # over seeds: averaged standard errors cover the truth near nominal; a clear case
    # (the test above) keeps the selected values
    z_avg, z_comb = [], []
    for seed in range(40):
        y, cands, _ = _collinear_law(100 + seed)
        s = select_terms(y, cands)
        for name, true in (("rate", -0.01), ("gradient", 0.0), ("c1", 3e-4)):
            z_avg.append((s.averaged[name][0] - true) / s.averaged[name][1])
        for group, (lead, value, se_c, slopes) in s.combined.items():
            z_comb.append((value + 0.01 * slopes.get("rate", 0.0)) / se_c)
    z_avg = np.abs(z_avg)
    print("averaged |z| < 1, < 2:", np.mean(z_avg < 1), np.mean(z_avg < 2))
    assert np.mean(z_avg < 2) >= 0.85 and z_avg.max() < 4.5
    z_comb = np.abs(z_comb)
    print("combined |z| < 1, < 2:", len(z_comb), np.mean(z_comb < 1), np.mean(z_comb < 2))
    assert len(z_comb) >= 20 and np.mean(z_comb < 2) >= 0.85 and z_comb.max() < 4.5


def test_combined_effect_of_a_group_without_true_members_covers_at_nominal():
    """A rate and a gradient that repeat each other, neither in the true law (c1 only): over 60
    seeds the group's combined effect, averaged over the subsets that hold the group, covers the
    truth (0) near nominal; averaged over every subset — the excluding ones fixing it at exactly
    0 — it is too wide (term_averaging's docstring: Hjort & Claeskens 2003). Bounds: ±2 binomial
    standard errors of 60 groups (6 %) about 68 %; the unconditional form for contrast."""
    zc, zu = [], []
    for seed in range(60):
        rng = np.random.default_rng(300 + seed)
        n = 300
        T, rate, grad = _collinear_inputs(rng, n)
        y = 0.02 + 3e-4 * T + 0.004 * rng.standard_normal(n)
        s = select_terms(y, _collinear_candidates(T, rate, grad))
        for group, (lead, value, se_c, slopes) in s.combined.items():
            zc.append(value / se_c)
            vals, vars_, ws = [], [], []
            for bn, combo, beta, cov, wi in s.models:
                names = list(bn) + list(combo)
                idx = [names.index(g) for g in group if g in names]
                sv = np.array([slopes[names[i]] for i in idx])
                vals.append(float(beta[idx] @ sv) if idx else 0.0)
                vars_.append(float(sv @ cov[np.ix_(idx, idx)] @ sv) if idx else 0.0)
                ws.append(wi)
            v, s2, w = np.array(vals), np.array(vars_), np.array(ws)
            m = float(w @ v)
            zu.append(m / np.sqrt(w @ (s2 + (v - m) ** 2)))
    zc, zu = np.abs(zc), np.abs(zu)
    print("null group |z| < 1, < 2: given the group", np.mean(zc < 1), np.mean(zc < 2),
          "over every subset", np.mean(zu < 1), np.mean(zu < 2))
    assert len(zc) >= 50
    assert 0.56 <= np.mean(zc < 1) <= 0.80 and np.mean(zc < 2) >= 0.9
    assert np.mean(zu < 1) > np.mean(zc < 1) + 0.15


def test_prediction_band_widens_along_the_unseparable_direction():
    """Rate and gradient repeat each other on the recording and the truth splits the effect
    between them; on another programme the gradient no longer follows the rate. The band's
    within-model variance is that of the model holding both members, ``x*ᵀ Σ_full x*``: it
    equals statsmodels' GLS prediction variance of that model (``get_prediction``); on the
    recording's own columns its mean is the hat matrix's trace p σ²/n, on the other programme
    many times more (it widens along the direction the recording did not see). Over 40 seeds,
    where the group is reported (the full model then holds the truth) that model's own band
    covers near nominal and the reported band (that variance plus the models' spread) at least
    nominal; where the noise hid the group (one member taken at > 95 %), neither can."""
    sigma = 0.004
    z_band, z_full, z_hidden = [], [], []
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        n = 300
        T, rate, grad = _collinear_inputs(rng, n)
        y = 0.02 + 3e-4 * T - 0.005 * rate - 0.005 * grad + sigma * rng.standard_normal(n)
        sel = select_terms(y, _collinear_candidates(T, rate, grad),
                           noise_cov=sigma ** 2 * np.eye(n))
        T2 = np.linspace(0, 40, 200)
        rate2 = 0.2 + 0.3 * rng.standard_normal(200)
        grad2 = 0.3 * rate2 + 0.5 * rng.standard_normal(200)     # no longer follows the rate
        new = {"c1": T2, "c2": T2 ** 2, "rate": rate2, "gradient": grad2}
        truth = 0.02 + 3e-4 * T2 - 0.005 * rate2 - 0.005 * grad2
        mean, se = sel.predict(new)
        base, terms, beta, _ = sel.full_model
        X2 = np.column_stack([np.ones(T2.size)] + [new[t] for t in terms])
        if not sel.unseparable:
            z_hidden.append((mean - truth) / se)
            continue
        assert any(set(g) == {"rate", "gradient"} for g, _ in sel.unseparable)
        assert {"rate", "gradient"} <= set(terms) and base == ("intercept",)
        z_band.append((mean - truth) / se)
        z_full.append((X2 @ beta - truth) / np.sqrt(sel.full_variance(new)))
        if len(z_band) == 1:
            own = {"c1": T, "c2": T ** 2, "rate": rate, "gradient": grad}
            X = np.column_stack([np.ones(n)] + [own[t] for t in terms])
            ref = sm.GLS(y, X, sigma=sigma ** 2 * np.eye(n)).fit()
            v_ref = ref.get_prediction(X2).se_mean ** 2 * max(ref.scale, 1.0) / ref.scale
            # rtol: the full model's normal matrix has condition ~1e9 (T beside a rate and a
            # gradient at r ≈ 0.99); both solve it in double precision
            np.testing.assert_allclose(sel.full_variance(new), v_ref, rtol=1e-5)
            np.testing.assert_allclose(X2 @ beta, ref.predict(X2), rtol=1e-5, atol=1e-9)
            v_own = np.mean(sel.full_variance(own))
            np.testing.assert_allclose(v_own, X.shape[1] * sigma ** 2 / n
                                       * max(ref.scale, 1.0), rtol=1e-5)
            assert np.median(sel.full_variance(new)) > 5 * v_own
    zb, zf = np.abs(np.concatenate(z_band)), np.abs(np.concatenate(z_full))
    print(f"{len(z_band)} seeds with the group: |z| < 1, < 2 band {np.mean(zb < 1):.3f} "
          f"{np.mean(zb < 2):.3f}, full model alone {np.mean(zf < 1):.3f} {np.mean(zf < 2):.3f}; "
          f"{len(z_hidden)} seeds without")
    assert len(z_band) >= 30
    # the 200 points of a seed share one coefficient error: ~35 independent draws, ± 8 % at 1σ
    assert 0.55 <= np.mean(zf < 1) <= 0.85 and np.mean(zf < 2) >= 0.9
    assert np.mean(zb < 1) >= 0.68 and np.mean(zb < 2) >= 0.95


def test_window_mean_covariance_matches_the_simulators_noise_generators():
    """The covariance of 100 s window means of flicker, rate random walk, white and quantisation
    noise (rlgsim.estimators.identify.window_noise) against the empirical covariance over 3000
    realisations of the simulator's own generators (rlgsim.sim.sensors.noise: Gauss–Markov bank,
    cumulative-sum walk), within 4.5 standard errors of each empirical element."""
    from rlgsim.estimators.identify.window_noise import window_mean_covariance
    from rlgsim.sim.sensors.noise import FlickerBank, RandomWalk
    rng = np.random.default_rng(11)
    C, T, m = 3000, 100, 6
    starts = np.arange(m) * float(T)
    bank = FlickerBank(np.ones(C), 1.0, 2.0, 1e5, 2)
    flick, _ = bank.block(bank.initial_state(rng), rng, m * T)
    walk = RandomWalk(np.full(C, 0.02), 1.0)
    rw, _ = walk.block(walk.initial_state(), rng, m * T)
    e = 40.0 * rng.standard_normal((m + 1, C))            # angle quantisation error, Q = 40
    cases = {"flicker": (flick, dict(b=1.0, per_decade=2)), "random walk": (rw, dict(k=0.02)),
             "white": (3.0 * rng.standard_normal((m * T, C)), dict(n=3.0))}
    for name, (x, kw) in cases.items():
        means = x.reshape(m, T, C).mean(axis=1)
        model = window_mean_covariance(starts, T, **kw)
        emp = means @ means.T / C
        d2 = np.diag(model)
        se = np.sqrt((np.outer(d2, d2) + model ** 2) / C)
        assert np.max(np.abs(emp - model) / se) < 4.5, name
    means = np.diff(e, axis=0) / T
    model = window_mean_covariance(starts, T, q=40.0)
    assert model[0, 1] == pytest.approx(-(40.0 / T) ** 2) and model[0, 2] == 0.0
    np.testing.assert_allclose(means @ means.T / C, model, atol=5 * 2 * (40.0 / T) ** 2
                               / np.sqrt(C))
    # gaps: a window left out keeps the others' covariance (times, not row numbers, count)
    full = window_mean_covariance(starts, T, b=1.0, k=0.02, n=3.0, q=40.0)
    keep = [0, 1, 3, 4, 5]
    np.testing.assert_allclose(window_mean_covariance(starts[keep], T, b=1.0, k=0.02, n=3.0,
                                                      q=40.0), full[np.ix_(keep, keep)])


def _flicker_law(seeds: int, m: int = 160, T: int = 100):
    """A bias law (intercept 0.01 °/h, c1 3e-4 °/h/K over a ramp and soak) plus flicker and
    white noise from the simulator's generators, one realisation per seed."""
    from rlgsim.sim.sensors.noise import FlickerBank
    rng = np.random.default_rng(21)
    bank = FlickerBank(np.full(seeds, 0.002), 1.0, 2.0, 1e5, 2)
    noise, _ = bank.block(bank.initial_state(rng), rng, m * T)
    noise = noise + 0.02 * rng.standard_normal(noise.shape)
    temp = np.interp(np.arange(m), [0, 40, 80, 160], [20.0, 50.0, 50.0, 0.0])
    law = 0.01 + 3e-4 * (temp - 20.0)
    return law[:, None] + noise.reshape(m, T, seeds).mean(axis=1), temp


def test_generalised_least_squares_equals_statsmodels_and_covers_under_flicker():
    from rlgsim.estimators.identify.window_noise import window_mean_covariance
    Y, temp = _flicker_law(40)
    m, T = Y.shape[0], 100
    cov = window_mean_covariance(np.arange(m) * float(T), T, b=0.002, n=0.02, per_decade=2)
    x = temp - 20.0
    cands = [Term("c1", lambda th: x), Term("c2", lambda th: x ** 2)]
    # one realisation: the refined law is statsmodels' GLS of the chosen terms
    sel = select_terms(Y[:, 0], cands, noise_cov=cov)
    X = np.column_stack([np.ones(m)] + [{"c1": x, "c2": x ** 2}[t] for t in sel.terms])
    ref = sm.GLS(Y[:, 0], X, sigma=cov).fit()
    np.testing.assert_allclose(sel.fit.x, ref.params, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(sel.fit.se, ref.bse * np.sqrt(max(ref.scale, 1.0) / ref.scale),
                               rtol=1e-6)
    np.testing.assert_allclose(sel.residual, X @ ref.params - Y[:, 0], atol=1e-12)
    # over 40 realisations: the model-averaged intercept and c1 cover the truth near nominal;
    # the batch means of ordinary least squares (8 batches of 20 windows) cannot see the
    # flicker slower than a batch and cover the intercept far less often
    z_gls, z_ols = [], []
    for k in range(Y.shape[1]):
        g = select_terms(Y[:, k], cands, noise_cov=cov)
        o = select_terms(Y[:, k], cands)
        for name, true in (("intercept", 0.01), ("c1", 3e-4)):
            z_gls.append((g.averaged[name][0] - true) / g.averaged[name][1])
            z_ols.append((o.averaged[name][0] - true) / o.averaged[name][1])
    z_gls, z_ols = np.abs(z_gls), np.abs(z_ols)
    print("|z| < 1, < 2: GLS", np.mean(z_gls < 1), np.mean(z_gls < 2),
          "OLS", np.mean(z_ols < 1), np.mean(z_ols < 2))
    assert 0.55 <= np.mean(z_gls < 1) and np.mean(z_gls < 2) >= 0.88
    assert np.mean(z_gls < 2) > np.mean(z_ols < 2)


def test_quantised_reading_covariance_against_analytic_cases():
    """rlgsim.estimators.identify.quantisation: the mean of quantised readings of a constant
    temperature keeps the whole quantisation error (variance q²/12, not q²/12n: the error is
    held), two probes with independent grid offsets halve it, and noise far above the
    resolution dithers the error white ((σ² + q²/12)/n)."""
    from rlgsim.estimators.identify.quantisation import (quantised_covariance,
                                                         quantised_intervals, quantised_scores)
    n, q = 500, 0.0625
    J = np.ones((n, 1))
    soak = np.full((n, 1), 21.3)
    ok = np.ones((n, 1), dtype=bool)
    var = quantised_covariance(J, soak, ok, np.zeros(1), np.full(1, q), draws=2000)[0, 0]
    assert var == pytest.approx(q ** 2 / 12, rel=0.1)
    two = quantised_covariance(np.ones((2 * n, 1)), np.full((n, 2), 21.3), np.ones((n, 2), bool),
                               np.zeros(2), np.full(2, q), draws=2000)[0, 0]
    assert two == pytest.approx(q ** 2 / 24, rel=0.1)
    sigma = 1.0
    white = quantised_covariance(J, soak, ok, np.full(1, sigma), np.full(1, q), draws=2000)
    assert white[0, 0] == pytest.approx((sigma ** 2 + q ** 2 / 12) / n, rel=0.1)
    # a missing reading carries no error: half the samples masked, half the held error
    half = ok.copy()
    half[::2] = False
    var2 = quantised_covariance(J, soak, half, np.zeros(1), np.full(1, q), draws=2000)[0, 0]
    assert var2 == pytest.approx(q ** 2 / 48, rel=0.1)
    # the percentile intervals: the held error of one soaked probe is uniform on ±q/2, so its
    # central P interval is ±P·q/2 — wider than ±1σ at 68.3 % (±1.18σ) and narrower than
    # ±2σ at 95.4 % (±1.65σ), not the Gaussian ±1σ, ±2σ
    scores, a_inv = quantised_scores(J, soak, ok, np.zeros(1), np.full(1, q), draws=4000)
    h68, h95 = quantised_intervals(scores, a_inv)[:, 0]
    # quantile of a uniform from 4000 draws: standard error √(P(1−P)/4000)·q ≤ 0.008·q/2
    assert h68 == pytest.approx(0.6827 * q / 2, abs=0.02 * q / 2)
    assert h95 == pytest.approx(0.9545 * q / 2, abs=0.02 * q / 2)
    assert np.sqrt(var) < h68 < 2 * np.sqrt(var) and h95 < 2 * np.sqrt(var)


def test_batched_heater_network_equals_the_integrator():
    """The thermal fit's batched Jacobian integration (a PI-controlled heater, several parameter
    sets at once) gives the integrator's readings for every set."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify.batch_twin import batchable, twin_readings_batch
    from rlgsim.lab.identify.thermal_fit import (apply_multipliers, build, thermal_parameters,
                                                 twin_response)
    tmpl = presets.load_thermal_file("trplg_001_cabinet").data
    params = thermal_parameters(tmpl)
    t = np.arange(1, 2001) * 5.0
    air = 25.0 + 15.0 * np.sin(t / 3000.0)
    power = np.ones(t.size)
    power[1500:1600] = 0.0                       # the controller off and reset, then on again
    models = [build(apply_multipliers(tmpl, params, m)[0])
              for m in ({}, {params[0].name: 1.3}, {params[1].name: 0.8}, {params[-1].name: 2.0})]
    assert batchable(models[0][0])
    batch = twin_readings_batch(models, air, power, 5.0)
    for (net, pr), got in zip(models, batch):
        _, ref = twin_response(net, pr, air, power, 5.0)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
    # its step coefficients (closed-form φ-functions of one batched eigendecomposition) against
    # the integrator's (each mode's 5 × 5 exponential), at 5 s and at the fit's 30 s steps
    # (λh from 2e-3, the series branch of φ₂, to > 1): a few ε of each array's largest entry
    from rlgsim.lab.identify.batch_twin import _coefficients
    from rlgsim.sim.thermal.integrator import ThermalIntegrator
    nets = [net for net, _ in models]
    for h in (5.0, 30.0):
        for net, c in zip(nets, _coefficients(nets, h, 25.0, True)):
            it = ThermalIntegrator(net, h, 0.0)
            pairs = [(k, getattr(c, k), getattr(it, k)) for k in
                     ("_mu", "_c_s", "_c_ds", "_c_u", "_c_b", "_c_db", "_to_nodes_T")]
            pairs += [(f.name, getattr(c._heat, f.name), getattr(it._heat, f.name))
                      for f in dataclasses.fields(c._heat)]
            for k, got, want in pairs:
                np.testing.assert_allclose(got, want, rtol=0,
                                           atol=1e-13 * np.max(np.abs(want)), err_msg=k)
            np.testing.assert_allclose(c.w0, it.initial_state(25.0, True).modal_if_valid(),
                                       rtol=1e-13)


@pytest.mark.parametrize("preset", ["trplg_001_cabinet", "rlg_imu"])
def test_compiled_batch_kernel_equals_its_numpy_reference(preset):
    """The compiled recurrence of the batched Jacobian (one call for every step and parameter
    set) against the NumPy loop it replaced, on random networks of a heater preset's topology
    (every multiplier drawn log-normal, 30 %) driven by a random air programme with the power
    off for a while. trplg_001_cabinet's heater tracks a node and has a boundary, rlg_imu's
    does neither. The two sum each step's ≤ 42-term dot products in different orders
    (rounding ~n·ε of the temperatures, ~1e-14 °C here) and the recurrence is contracting
    (every modal factor |μ| < 1, the PI loop stable), so the readings agree to 1e-12 relative,
    not bit for bit."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify.batch_twin import twin_readings_batch
    from rlgsim.lab.identify.thermal_fit import apply_multipliers, build, thermal_parameters
    tmpl = presets.load_thermal_file(preset).data
    params = thermal_parameters(tmpl)
    rng = np.random.default_rng(28)
    models = [build(apply_multipliers(tmpl, params, {p.name: float(np.exp(rng.normal(0, 0.3)))
                                                     for p in params})[0]) for _ in range(3)]
    air = 20.0 + np.cumsum(rng.normal(0.0, 0.3, 1500))
    power = np.ones(air.size)
    power[700:760] = 0.0
    fast = twin_readings_batch(models, air, power, 10.0)
    ref = twin_readings_batch(models, air, power, 10.0, compiled=False)
    for got, want in zip(fast, ref):
        assert np.all(np.isfinite(want))
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)


def test_stacked_subset_screen_equals_the_one_by_one_screen():
    """The best-subset search's stacked collinearity screen accepts exactly the subsets that
    term_averaging.conditioned accepts one at a time, on random candidate sets with nearly
    collinear columns and an exact repeat (singular subsets, which fail a stacked inverse);
    and the subsets' (and single added columns') stacked residual sums of squares equal
    lstsq's one at a time."""
    import itertools
    from rlgsim.estimators.identify.subset_conditioning import passing
    from rlgsim.estimators.identify.subset_fits import added_column_ssr, subset_ssr
    from rlgsim.estimators.identify.subset_conditioning import conditioned
    from rlgsim.estimators.identify.term_averaging import corr_matrix
    rng = np.random.default_rng(17)
    refused = 0
    for _ in range(5):
        base = rng.normal(size=(200, 3))
        cols = {f"t{i}": base @ rng.normal(size=3) + rng.normal(size=200) * 10 ** rng.uniform(-3, 0)
                for i in range(9)}
        cols["repeat"] = 2.0 * cols["t0"]
        R = corr_matrix(cols, list(cols), np.ones(200))
        for size in range(1, 7):
            want = [c for c in itertools.combinations(cols, size) if conditioned(R, c)]
            assert passing(R, list(cols), size) == want
            refused += len(list(itertools.combinations(cols, size))) - len(want)
        # the subsets' residual sums of squares (Frisch–Waugh–Lovell, subset_fits) against
        # lstsq's, every subset of 3 and 5 — the refused and the singular ones (the exact
        # repeat: lstsq's fallback) too — on top of an intercept and two shared columns: the
        # solved ones have a Gram condition number ≤ 1e6, so ≲ 1e6·ε relative
        y = base @ rng.normal(size=3) + rng.normal(size=200)
        shared = np.column_stack([np.ones(200), rng.normal(size=(200, 2))])
        for size in (3, 5):
            combos = list(itertools.combinations(cols, size))
            want = [float(np.sum((y - X @ np.linalg.lstsq(X, y, rcond=None)[0]) ** 2))
                    for X in (np.column_stack([shared] + [cols[c] for c in co]) for co in combos)]
            np.testing.assert_allclose(subset_ssr(y, shared, cols, combos), want, rtol=1e-9)
        # one added column at a time (a nonlinear term's grid), one of them in the shared
        # columns' span (lstsq's fallback): ≲ ε·ỹᵀỹ/SSR relative
        grid = np.column_stack([*cols.values(), shared @ np.array([1.0, 2.0, -1.0])])
        want = [float(np.sum((y - X @ np.linalg.lstsq(X, y, rcond=None)[0]) ** 2))
                for X in (np.column_stack([shared, c]) for c in grid.T)]
        np.testing.assert_allclose(added_column_ssr(y, shared, grid), want, rtol=1e-9)
    assert refused > 0                      # the screen did refuse some


def test_compiled_rolling_median_equals_pandas():
    """The spike scan's centred rolling median (31 samples, at least 5 present) against
    pandas' on real-valued and whole-pulse series with scattered and long runs of missing
    samples: the same values bit for bit (a middle value or the half-sum of two, NaN where too
    few are present)."""
    import pandas as pd
    from rlgsim.lab.identify._median_kernel import rolling_median
    rng = np.random.default_rng(31)
    for kind in range(6):
        n = int(rng.integers(20, 4000))
        x = rng.normal(size=n) if kind % 2 else np.rint(rng.normal(2.14, 1.5, size=n))
        x[rng.random(n) < 0.1 * kind] = np.nan
        s = int(rng.integers(0, n))
        x[s:s + 40] = np.nan                  # a gap longer than the window
        want = pd.Series(x).rolling(31, center=True, min_periods=5).median().to_numpy()
        np.testing.assert_array_equal(rolling_median(x, 31, 5), want)


@pytest.mark.parametrize("preset", ["trplg_001_cabinet", "rlg_imu"])
def test_scaled_networks_equal_full_builds(preset):
    """The batched Jacobian's networks scaled from the template's arrays (scaled_twin) against
    networks built from the multiplied preset dicts, at 20 random multiplier sets (log-normal,
    50 %): every capacity, conductance, source, boundary link and probe lag to 1e-12 relative
    (the same products rounded in another order: a few ε), and the same heaters and topology;
    rlg_single, where one conductance entry sums links of two multipliers (the block's mount
    and air links), is refused."""
    from dataclasses import fields
    from rlgsim.sim import presets
    from rlgsim.lab.identify.scaled_twin import ScaledTwin
    from rlgsim.lab.identify.thermal_fit import apply_multipliers, build, thermal_parameters
    tmpl = presets.load_thermal_file(preset).data
    params = thermal_parameters(tmpl)
    st = ScaledTwin(tmpl, params, build)
    assert st.ok
    rng = np.random.default_rng(5)
    for _ in range(20):
        mult = {p.name: float(np.exp(rng.normal(0.0, 0.5))) for p in params}
        (net, pr), (want, want_pr) = st.model(mult), build(apply_multipliers(tmpl, params, mult)[0])
        for f in fields(net):
            a, b = getattr(net, f.name), getattr(want, f.name)
            if isinstance(b, np.ndarray):
                np.testing.assert_allclose(a, b, rtol=1e-12, atol=0, err_msg=f.name)
            else:
                assert a == b, f.name
        np.testing.assert_allclose(pr.tau_s, want_pr.tau_s, rtol=1e-12, atol=0)
    single = presets.load_thermal_file("rlg_single").data
    assert not ScaledTwin(single, thermal_parameters(single), build).ok
