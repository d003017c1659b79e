"""The compiled overlapping-Allan sum (estimators/_allan_kernel.py) against allantools.oadev:
the same IEEE-754 operations in the same order and numpy's pairwise sum of the squares, so the
deviations are equal bit for bit (any τ list, any length, a large mean)."""

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
    np.testing.assert_array_equal(ours.adev, adev)
    np.testing.assert_array_equal(ours.error, err)


def test_phase_matches_allantools_with_and_without_nan() -> None:
    """The compiled phase (a running sum in index order) is allantools' bit for bit; a record
    with NaN ends (which allantools trims) takes allantools' own path."""
    from rlgsim.estimators._allan_kernel import _frequency2phase
    x = _series("offset", 3001, seed=3)
    np.testing.assert_array_equal(_frequency2phase(x, 10.0), allantools.frequency2phase(x, 10.0))
    x[[0, -1]] = np.nan
    np.testing.assert_array_equal(_frequency2phase(x, 10.0), allantools.frequency2phase(x, 10.0))


def test_white_noise_level() -> None:
    """An independent check of the scale: white rate noise of σ at rate f has Allan deviation
    σ/√(τ·f) (IEEE Std 952-1997, annex C: angle random walk); over 2e5 samples the estimate at
    τ = 10 samples has a relative spread of about 1/√(n/m) ≈ 0.7 %, so 3 % is a 4σ bound."""
    sigma, rate = 0.3, 50.0
    x = np.random.default_rng(7).normal(0.0, sigma, 200_000)
    ad = allan_deviation(x, rate, [10 / rate])
    assert ad.adev[0] == pytest.approx(sigma / np.sqrt(10), rel=0.03)
