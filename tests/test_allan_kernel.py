"""The compiled overlapping-Allan sum (estimators/_allan_kernel.py) against allantools.oadev.

Tolerance: both compute σ(τ) = √(S/(2n))/m·rate from the same phase; only the order of the
n squared second differences in S differs (allantools sums pairwise, the kernel in sequence).
Sequential summation of n non-negative terms has a relative error below n·ε (Higham,
*Accuracy and Stability of Numerical Algorithms*, §4.2), ≤ 1e5 × 2.2e-16 ≈ 2e-11 here, and the
square root halves it; 1e-9 leaves room without hiding a wrong term or a wrong n.
"""

from __future__ import annotations

import allantools
import numpy as np
import pytest

from rlgsim.estimators.metrics import allan_deviation


def _series(kind: str, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    white = rng.normal(size=n)
    if kind == "white":
        return white
    if kind == "walk":
        return np.cumsum(white) * 1e-2 + 3.0
    return white * 1e-3 + 1e4            # a large mean: allantools removes it before the cumsum


@pytest.mark.parametrize("kind", ["white", "walk", "offset"])
@pytest.mark.parametrize("n,taus", [(1000, "all"), (4097, "octave"), (100_000, "octave"),
                                    (100_000, "decade"), (5000, [0.01, 0.5, 3.0, 24.99])])
def test_matches_allantools(kind: str, n: int, taus) -> None:
    x = _series(kind, n, seed=n)
    ours = allan_deviation(x, 100.0, taus)
    tau, adev, err, ns = allantools.oadev(x, rate=100.0, data_type="freq", taus=taus)
    np.testing.assert_array_equal(ours.tau_s, tau)
    np.testing.assert_array_equal(ours.n, ns)
    np.testing.assert_allclose(ours.adev, adev, rtol=1e-9, atol=0)
    np.testing.assert_allclose(ours.error, err, rtol=1e-9, atol=0)


def test_white_noise_level() -> None:
    """An independent check of the scale: white rate noise of σ at rate f has Allan deviation
    σ/√(τ·f) (IEEE Std 952-1997, annex C: angle random walk); over 2e5 samples the estimate at
    τ = 10 samples has a relative spread of about 1/√(n/m) ≈ 0.7 %, so 3 % is a 4σ bound."""
    sigma, rate = 0.3, 50.0
    x = np.random.default_rng(7).normal(0.0, sigma, 200_000)
    ad = allan_deviation(x, rate, [10 / rate])
    assert ad.adev[0] == pytest.approx(sigma / np.sqrt(10), rel=0.03)
