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
"""

from __future__ import annotations

import numpy as np

__all__ = ["quantised_covariance"]


def quantised_covariance(jac: np.ndarray, readings_c: np.ndarray, mask: np.ndarray,
                         sigma_c: np.ndarray, resolution_c: np.ndarray, *, draws: int = 300,
                         seed: int = 0) -> np.ndarray:
    """(p, p) covariance of the estimates (module docstring).

    ``jac`` (P·m, p) the residual Jacobian, probe-major (probe 0's m rows first);
    ``readings_c`` (m, P) the fitted noise-free readings at those rows; ``mask`` (m, P) where a
    reading exists; ``sigma_c``, ``resolution_c`` (P,) the probes' noise and resolution (0: no
    quantisation). Deterministic for a given ``seed``."""
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
    omega = scores.T @ scores / draws
    Ainv = np.linalg.pinv(J.T @ J)
    return Ainv @ omega @ Ainv
