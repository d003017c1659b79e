"""Nonlinear least squares with the statistics an identification must report: standard errors
and correlations of the parameters from the Jacobian, an inflation for autocorrelated
residuals, and the identifiability screen that names what the data cannot determine.

Covariance (Gauss–Newton, e.g. Seber & Wild, *Nonlinear Regression*, 1989, §2.1):

    cov(x̂) = s² (JᵀJ)⁻¹,  s² = Σ r² / (N − p)

with ``J`` the Jacobian of the residuals at the solution. The formula assumes independent
residuals. Real residuals of a thermal or bias model are correlated in time (a model error is
slow, a quantised thermometer on a slow signal holds its error for many minutes), so the
standard errors reported are those of the sandwich covariance with a batch-means estimate of
the scores' long-run covariance (:func:`batch_means_covariance`), never below the
independent-residual value. (A first-order autoregressive inflation √((1 + ρ)/(1 − ρ)) was
tried first and undercovered: a quantisation error held through a soak is not AR(1); ρ is
still reported.)

Identifiability: a parameter is refused when the Jacobian is rank-deficient along it (the
smallest singular value of the column-scaled Jacobian below ``rcond`` times the largest, the
parameter with the largest share of that singular vector) or when its estimate correlates with
another beyond ``max_corr`` (default 0.99) — the recording then cannot separate the two, and the
less determined one is kept at its prior value. :func:`screen` returns one such parameter at
a time so the caller can refit without it.

The fitting itself is :func:`scipy.optimize.least_squares` (trust-region reflective).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

__all__ = ["LsqFit", "fit", "covariance", "ar1_inflation", "batch_means_covariance", "screen"]


@dataclass(frozen=True)
class LsqFit:
    """A least-squares fit: ``names`` and estimates ``x``, standard errors ``se`` (inflated by
    ``inflation``), correlation matrix ``corr``, residual vector ``residual`` at ``x``, its RMS,
    the residual lag-one correlation ``rho``, residual count ``n`` and parameter count ``p``,
    the Jacobian ``jac`` at ``x`` and the number of function evaluations ``nfev``."""

    names: tuple[str, ...]
    x: np.ndarray
    se: np.ndarray
    corr: np.ndarray
    residual: np.ndarray
    rms: float
    rho: float
    inflation: float
    n: int
    p: int
    jac: np.ndarray
    nfev: int

    def table(self) -> list[dict]:
        return [{"parameter": n, "estimate": float(v), "standard_error": float(s)}
                for n, v, s in zip(self.names, self.x, self.se)]


def ar1_inflation(residual: np.ndarray, segments: int = 1) -> tuple[float, float]:
    """Lag-one autocorrelation ρ of ``residual`` (split into ``segments`` equal consecutive
    series, e.g. one per probe, ρ averaged) and the standard-error factor √((1+ρ)/(1−ρ))
    (ρ clipped to [0, 0.999])."""
    r = np.asarray(residual, dtype=float).reshape(segments, -1)
    rhos = []
    for row in r:
        row = row - row.mean()
        den = float(np.dot(row, row))
        if row.size > 2 and den > 0:
            rhos.append(float(np.dot(row[1:], row[:-1]) / den))
    rho = float(np.mean(rhos)) if rhos else 0.0
    rc = min(max(rho, 0.0), 0.999)
    return rho, float(np.sqrt((1.0 + rc) / (1.0 - rc)))


def covariance(jac: np.ndarray, residual: np.ndarray) -> tuple[np.ndarray, float]:
    """``s²(JᵀJ)⁻¹`` (pseudo-inverse for a singular JᵀJ) and ``s²``."""
    J = np.asarray(jac, dtype=float)
    r = np.asarray(residual, dtype=float)
    n, p = J.shape
    s2 = float(np.dot(r, r)) / max(n - p, 1)
    _, sv, vt = np.linalg.svd(J, full_matrices=False)
    tol = sv.max() * max(n, p) * np.finfo(float).eps if sv.size else 0.0
    inv = np.where(sv > tol, 1.0 / np.where(sv > tol, sv, 1.0) ** 2, 0.0)
    return (vt.T * inv) @ vt * s2, s2


def _corr(cov: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(d, d)
    c[~np.isfinite(c)] = 0.0
    np.fill_diagonal(c, 1.0)
    return c


def screen(jac: np.ndarray, names: Sequence[str], *, max_corr: float = 0.99,
           rcond: float = 1e-7, optional: Sequence[bool] | None = None
           ) -> tuple[int, str] | None:
    """The one parameter (index, reason) the data cannot identify, or ``None``.

    Rank first (column-scaled Jacobian, smallest/largest singular value below ``rcond``), then
    the largest pairwise correlation of the estimates above ``max_corr``; of a correlated pair
    an ``optional`` parameter (a refinement of another, e.g. one heat source on its own) is
    refused before a general one, otherwise the one with the larger scaled standard error (the
    less determined)."""
    J = np.asarray(jac, dtype=float)
    norms = np.linalg.norm(J, axis=0)
    if np.any(norms == 0):
        i = int(np.flatnonzero(norms == 0)[0])
        return i, "the probes do not respond to it at all (zero column of the Jacobian)"
    Js = J / norms
    _, sv, vt = np.linalg.svd(Js, full_matrices=False)
    ratio = sv[-1] / sv[0]
    if ratio < rcond:
        v = np.abs(vt[-1])
        i = int(np.argmax(v))
        others = [names[k] for k in np.argsort(-v) if k != i and v[k] > 0.2]
        with_ = f" together with {', '.join(others)}" if others else ""
        return i, (f"rank-deficient Jacobian (singular-value ratio {ratio:.1e} < {rcond:g}): "
                   f"the recording does not constrain it{with_}")
    cov, _ = covariance(J, np.ones(J.shape[0]))
    c = _corr(cov)
    np.fill_diagonal(c, 0.0)
    i, j = np.unravel_index(int(np.argmax(np.abs(c))), c.shape)
    if abs(c[i, j]) > max_corr:
        se = np.sqrt(np.clip(np.diag(cov), 0, None)) * norms   # per unit of the parameter
        opt = list(optional) if optional is not None else [False] * len(names)
        if opt[i] != opt[j]:
            worse, other = (i, j) if opt[i] else (j, i)
        else:
            worse, other = (i, j) if se[i] >= se[j] else (j, i)
        return int(worse), (f"correlation {c[i, j]:+.4f} with {names[other]} (|r| > "
                            f"{max_corr:g}): the recording cannot separate the two")
    return None


def fit(fun: Callable[[np.ndarray], np.ndarray], x0: Sequence[float], names: Sequence[str],
        *, bounds: tuple = (-np.inf, np.inf), segments: int = 1, diff_step: float | None = None,
        max_nfev: int | None = None, x_scale: str | np.ndarray = "jac", batches: int = 20,
        whitened: bool = False, jac: Callable[[np.ndarray], np.ndarray] | None = None
        ) -> LsqFit:
    """Minimise ``Σ fun(x)²`` from ``x0`` and return estimates with inflated standard errors
    (``segments``: how many equal consecutive series the residual vector holds, for ρ).

    ``whitened``: ``fun`` returns residuals already divided by the Cholesky factor of their
    modelled covariance (generalised least squares), so they are independent with unit
    variance if the model holds: the covariance is ``(JᵀJ)⁻¹·max(1, s²)`` (the modelled one,
    inflated when the residual is larger than modelled) and no batch means are taken.

    ``jac``: the Jacobian ``jac(x)`` (e.g. the finite differences evaluated in one batch);
    by default scipy's forward differences with ``diff_step``."""
    x0 = np.asarray(x0, dtype=float)
    kw = {}
    if jac is not None:
        kw["jac"] = jac
    elif diff_step is not None:
        kw["diff_step"] = diff_step
    res = least_squares(fun, x0, bounds=bounds, method="trf", x_scale=x_scale,
                        max_nfev=max_nfev, **kw)
    r = np.asarray(res.fun, dtype=float)
    J = np.asarray(res.jac, dtype=float)
    cov0, s2 = covariance(J, r)
    rho, _ = ar1_inflation(r, segments)
    if whitened:
        cov = cov0 * (max(s2, 1.0) / s2 if s2 > 0 else 1.0)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        return LsqFit(names=tuple(names), x=np.asarray(res.x, dtype=float), se=se,
                      corr=_corr(cov), residual=r,
                      rms=float(np.sqrt(np.mean(r ** 2))) if r.size else 0.0, rho=rho,
                      inflation=float(np.sqrt(max(s2, 1.0))), n=r.size, p=x0.size, jac=J,
                      nfev=int(res.nfev))
    cov = batch_means_covariance(J, r, segments, batches)
    se0 = np.sqrt(np.clip(np.diag(cov0), 0.0, None))
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    # never below the independent-residual value (a sandwich from few batches can undershoot)
    se = np.maximum(se, se0)
    with np.errstate(invalid="ignore", divide="ignore"):
        infl = float(np.nanmedian(np.where(se0 > 0, se / se0, np.nan))) if se.size else 1.0
    return LsqFit(names=tuple(names), x=np.asarray(res.x, dtype=float), se=se, corr=_corr(cov),
                  residual=r, rms=float(np.sqrt(np.mean(r ** 2))) if r.size else 0.0, rho=rho,
                  inflation=infl if np.isfinite(infl) else 1.0, n=r.size, p=x0.size, jac=J,
                  nfev=int(res.nfev))


def batch_means_covariance(jac: np.ndarray, residual: np.ndarray, segments: int = 1,
                           batches: int = 20) -> np.ndarray:
    """Sandwich covariance ``A⁻¹ Ω A⁻¹`` (``A = JᵀJ``) with the long-run covariance Ω of the
    scores ``s_t = J_t r_t`` estimated by batch means: each of the ``segments`` consecutive
    series is cut into ``batches`` batches, Ω = Σ_b S_b S_bᵀ with S_b the score sum of batch
    b (a heteroscedasticity- and autocorrelation-consistent estimate, e.g. Conley 1999; the
    batch-means form of Newey & West 1987). Residual errors that persist over many samples —
    a quantised thermometer on a slow signal, flicker noise in bias windows — are then counted
    as the few independent pieces of information they are."""
    J = np.asarray(jac, dtype=float)
    r = np.asarray(residual, dtype=float)
    n, p = J.shape
    S = J * r[:, None]
    L = n // segments
    S = S[:L * segments].reshape(segments, L, p)
    b = max(1, min(batches, L))
    edges = np.linspace(0, L, b + 1).astype(int)
    sums = np.add.reduceat(S, edges[:-1], axis=1).reshape(-1, p)
    omega = sums.T @ sums
    A = J.T @ J
    Ainv = np.linalg.pinv(A)
    dof = n / max(n - p, 1)
    return Ainv @ omega @ Ainv * dof
