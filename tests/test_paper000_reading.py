"""The reading of paper 000's summary numbers (src/rlgsim/lab/studies/paper000_reading.py):
the R²/RMSE identity against scikit-learn's r2_score on real least-squares fits, the paper's
maxima worked by hand, and the §4.2 classes on curves built to be in each."""

from __future__ import annotations

import math

import numpy as np
import pytest
from sklearn.metrics import r2_score

from rlgsim.lab.studies import paper000_reading as rd


def _curve(seed: int, trend: float, step: float, noise: float, m: int = 175):
    """m windows over 5..72 °C: a linear trend, a step at 45 °C, white scatter; the cubic's
    and the truth's in-sample predictions."""
    rng = np.random.default_rng(seed)
    t = np.linspace(5.0, 72.0, m)
    truth = trend * (t - 40.0) / 67.0 + step / (1.0 + np.exp(-(t - 45.0) / 0.5))
    est = truth + noise * rng.standard_normal(m)
    lsm = np.polyval(np.polyfit(t - t.mean(), est, 3), t - t.mean())
    return t, est, truth, lsm


@pytest.mark.parametrize("trend,step", [(1.0, 0.3), (10.0, 1.0), (0.5, 0.05)])
def test_r2_gain_identity_matches_sklearn(trend, step):
    """(R1) with the cubic's share a and the RMSE gain g gives the R² improvement that
    sklearn's r2_score gives for the same two in-sample fits (the truth stands for RVR). The
    identity is exact for least squares with an intercept: agreement to rounding."""
    t, est, truth, lsm = _curve(1, trend, step, 0.1)
    r2_l, r2_r = r2_score(est, lsm), r2_score(est, truth)
    row = rd.parameter_reading(t, est, truth, truth, lsm)
    assert row["R² LSM"] == pytest.approx(r2_l, rel=1e-12)
    assert row["R² impr %"] == pytest.approx(100 * (r2_r - r2_l) / r2_l, rel=1e-9)
    a = row["cubic share %"] / 100
    assert rd.r2_gain_pct(a, row["RMSE impr %"]) == pytest.approx(row["R² impr %"], rel=1e-9)
    assert rd.unexplained_share(row["RMSE impr %"], row["R² impr %"]) == pytest.approx(a,
                                                                                     rel=1e-9)
    # the trend the cubic captures: Var(est) = Var(cubic fit) + RMSE² (orthogonal residual)
    assert row["trend/σ_e"] * row["σ_e"] == pytest.approx(np.std(lsm), rel=1e-9)


def test_paper_maxima_worked_by_hand():
    """g = 80.12 %, h = 9.15 %: a = 0.0915 / (1 − 0.1988² + 0.0915) = 0.0870."""
    mx = rd.paper_maximum()
    keep = (1 - 0.8012) ** 2
    a = 0.0915 / (1 - keep + 0.0915)
    assert mx["cubic share %"] == pytest.approx(100 * a, rel=1e-12)
    assert mx["cubic share %"] == pytest.approx(8.70, abs=0.005)
    assert mx["RVR share %"] == pytest.approx(100 * a * keep, rel=1e-12)
    assert mx["n/σ_e"] == pytest.approx(math.sqrt(1 / keep - 1), rel=1e-12)
    assert rd.ceiling_pct(1.0, mx["n/σ_e"]) == pytest.approx(80.12, rel=1e-12)


def test_classes_of_built_curves():
    """A big trend with a step several times the scatter is class c; a small trend with the
    same step class b; a big trend alone class a; scatter about a small trend class d."""
    cases = {"c": (100.0, 1.0), "b": (3.0, 1.0), "a": (100.0, 0.0), "d": (0.3, 0.0)}
    for want, (trend, step) in cases.items():
        t, est, truth, lsm = _curve(2, trend, step, 0.1)
        row = rd.parameter_reading(t, est, truth, truth, lsm)
        assert row["class"] == want, (want, row)
    assert rd.classify(float("nan"), 1.0) == "?"


def test_without_truth_only_the_in_sample_part():
    t, est, truth, lsm = _curve(3, 1.0, 0.3, 0.1)
    row = rd.parameter_reading(t, est, np.full_like(truth, np.nan), truth, lsm)
    assert math.isnan(row["σ_e"]) and row["class"] == "?"
    assert np.isfinite(row["R² impr %"])


def test_class_b_profile_worked_by_hand():
    """Four curves carry 15 × 2.29 − 11 × 0.1 = 33.25 points: 8.3125 % each; at g = 80 % the
    cubic leaves 0.083125 / (1 − 0.04 + 0.083125) = 7.97 %."""
    cb = rd.class_b_profile()
    assert cb["R² impr %"][0] == pytest.approx(8.3125, rel=1e-12)
    assert cb["cubic share %"][1] == pytest.approx(100 * 0.083125 / (1 - 0.04 + 0.083125),
                                                   rel=1e-9)
    assert cb["n/σ_e"][1] == pytest.approx(math.sqrt(1 / 0.04 - 1), rel=1e-12)
    # the share and the gain give back the R² improvement (eq. R1)
    for a, g in zip(cb["cubic share %"], (55.0, 80.0)):
        assert rd.r2_gain_pct(a / 100, g) == pytest.approx(8.3125, rel=1e-9)
