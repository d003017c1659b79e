"""Covariance of least-squares estimates fitted to quantised, slightly noisy readings of a slow
signal — thermometers with a resolution far above their noise (0.0625 °C against 0.01 °C).

The reading error ``e(t) = q·round((T(t) + n(t))/q) − T(t)`` of such a probe is not noise in
the usual sense: through a soak it holds one value for an hour, along a ramp it is a sawtooth,
and probes at nearly the same temperature make nearly the same error. What varies from one
unit (or one recording) to the next is where the signal sits on the quantisation grid, so the
error is modelled with the grid at a random offset ``u ~ U[0, q)`` per probe (subtractive
dither; Widrow & Kollár, *Quantization Noise*, 2008, ch. 19) plus the white noise ``n``:

    e = q·round((T + u + n)/q) − (T + u).

Linearised estimate (Gauss–Newton): ``δx = −A⁻¹Jᵀe``, ``A = JᵀJ``, so

    cov(x̂) = A⁻¹ Ω A⁻¹,  Ω = E[Jᵀe eᵀJ],

with Ω estimated over ``draws`` realisations of ``(u, n)`` on the fitted (noise-free) readings
``T`` — a linearised parametric bootstrap: no refit per draw, the whole error path (held values,
cross-probe agreement) carried through the exact Jacobian. The probe specification (noise σ,
resolution q) is the thermal template's.

Intervals (:func:`quantised_intervals`): the same draws ``δx_d = −A⁻¹Jᵀe_d`` are draws of the
estimates' error, so the central interval of probability ``P`` is the ``P``-quantile of
``|δx_d|`` (the bootstrap percentile interval of a symmetric error, Efron & Tibshirani, *An
Introduction to the Bootstrap*, 1993, ch. 13). It is not ``±z_P`` standard deviations: when the
error is dominated by a few probes' grid offsets it is a sum of a few uniform variables — flatter
than Gaussian (excess kurtosis below 0; a single uniform error's 68.3 % interval is ±1.18 standard
deviations, its 95.4 % one ±1.65) — so ±1 standard error covers less than 68 %.
"""

from __future__ import annotations

import numpy as np

__all__ = ["quantised_covariance", "quantised_scores", "quantised_intervals"]


def quantised_scores(jac: np.ndarray, readings_c: np.ndarray, mask: np.ndarray,
                     sigma_c: np.ndarray, resolution_c: np.ndarray, *, draws: int = 300,
                     seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The ``draws`` score vectors ``Jᵀe_d`` (draws, p) of the reading error realisations and
    ``A⁻¹`` (p, p) (arguments of :func:`quantised_covariance`); the estimates' error of draw d
    is ``−A⁻¹ Jᵀe_d``."""
    J = np.asarray(jac, dtype=float)
    T = np.asarray(readings_c, dtype=float).T            # (P, m), probe-major like J
    M = np.asarray(mask, dtype=bool).T
    P, m = T.shape
    if J.shape[0] != P * m:
        raise ValueError(f"jac has {J.shape[0]} rows, readings {P}×{m}")
    sig = np.asarray(sigma_c, dtype=float)[:, None]
    q = np.asarray(resolution_c, dtype=float)[:, None]
    rng = np.random.default_rng(seed)
    scores = np.empty((draws, J.shape[1]))
    for d in range(draws):
        u = rng.uniform(0.0, 1.0, (P, 1)) * q
        x = T + u + sig * rng.standard_normal((P, m))
        e = np.where(q > 0, np.round(x / np.where(q > 0, q, 1.0)) * q, x) - (T + u)
        scores[d] = np.where(M, e, 0.0).reshape(-1) @ J
    return scores, np.linalg.pinv(J.T @ J)


def quantised_covariance(jac: np.ndarray, readings_c: np.ndarray, mask: np.ndarray,
                         sigma_c: np.ndarray, resolution_c: np.ndarray, *, draws: int = 300,
                         seed: int = 0) -> np.ndarray:
    """(p, p) covariance of the estimates (module docstring).

    ``jac`` (P·m, p) the residual Jacobian, probe-major (probe 0's m rows first);
    ``readings_c`` (m, P) the fitted noise-free readings at those rows; ``mask`` (m, P) where a
    reading exists; ``sigma_c``, ``resolution_c`` (P,) the probes' noise and resolution (0: no
    quantisation). Deterministic for a given ``seed``."""
    scores, Ainv = quantised_scores(jac, readings_c, mask, sigma_c, resolution_c, draws=draws,
                                    seed=seed)
    omega = scores.T @ scores / scores.shape[0]
    return Ainv @ omega @ Ainv


def quantised_intervals(scores: np.ndarray, Ainv: np.ndarray,
                        levels: tuple[float, ...] = (0.6827, 0.9545)) -> np.ndarray:
    """(len(levels), p) half-widths of the central intervals of the estimates' error at the
    probabilities ``levels`` (default: those of ±1 and ±2 standard deviations of a Gaussian):
    the quantiles of ``|A⁻¹ Jᵀe_d|`` over the draws of :func:`quantised_scores` (module
    docstring)."""
    err = np.abs(np.asarray(scores, dtype=float) @ np.asarray(Ainv, dtype=float).T)
    return np.quantile(err, levels, axis=0)
