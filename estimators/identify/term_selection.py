"""Which terms of a law does the recording support? Forward selection by the Bayesian
information criterion, then a joint refinement with uncertainties.

A law is ``y ≈ β₀ + Σ_t β_t·f_t(θ_t)``: each candidate term ``t`` is one feature column that may
depend on a few nonlinear parameters ``θ_t`` (a knee's centre and width, a step's), with a grid
of starting values. Selection (Schwarz 1978):

    BIC = n·ln(SSR/n) + k·ln n,     k = 1 + (number of terms) + (nonlinear parameters)

(An effective sample size from the residual autocorrelation was tried and rejected: the
residual of an incomplete law is smooth, so it shrinks n until no missing term can enter.)

Starting from the intercept, the candidate whose addition lowers the BIC most is added (each
nonlinear candidate at the best θ of its grid, polished with the linear coefficients profiled
out), until no addition lowers it; then every term
whose removal lowers the BIC is removed (one backward pass). The linear fits of the selection
are :class:`statsmodels.regression.linear_model.OLS`; the nonlinear parameters count in ``k``,
so a knee is only chosen when it pays for its centre and width.

Refinement: every coefficient and every nonlinear parameter of the chosen terms are fitted
together by :func:`rlgsim.estimators.identify.lsq_stats.fit`, whose standard errors are
inflated for the residual autocorrelation (window series of a gyro bias carry flicker noise).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import warnings

import numpy as np
import statsmodels.api as sm
from scipy.optimize import least_squares

from rlgsim.estimators.identify.lsq_stats import LsqFit, fit

__all__ = ["Term", "SelectedLaw", "select_terms"]


@dataclass(frozen=True)
class Term:
    """A candidate term: ``name``; ``feature(theta) -> (n,)`` column; ``theta_names`` of its
    nonlinear parameters with a ``grid`` of starting values (list of arrays) and ``lower`` /
    ``upper`` bounds; a linear term has no theta."""

    name: str
    feature: Callable[[np.ndarray], np.ndarray]
    theta_names: tuple[str, ...] = ()
    grid: Sequence[np.ndarray] = field(default_factory=lambda: [np.zeros(0)])
    lower: Sequence[float] = ()
    upper: Sequence[float] = ()

    @property
    def k(self) -> int:
        return len(self.theta_names)


@dataclass(frozen=True)
class SelectedLaw:
    """The chosen ``terms`` (names, in selection order), the refined ``fit`` (parameters
    ``intercept``, ``<term>``, ``<term>.<theta>``), the selection ``steps`` (term, BIC after)
    and ``bic``."""

    terms: tuple[str, ...]
    fit: LsqFit
    steps: tuple[tuple[str, float], ...]
    bic: float
    candidates: tuple[str, ...]
    n_eff: float = 0.0
    rho: float = 0.0

    def value(self, name: str) -> float:
        return float(self.fit.x[self.fit.names.index(name)])

    def se(self, name: str) -> float:
        return float(self.fit.se[self.fit.names.index(name)])


def _ols_bic(y: np.ndarray, cols: list[np.ndarray], k_extra: int, n_eff: float) -> float:
    X = np.column_stack([np.ones_like(y), *cols]) if cols else np.ones((y.size, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sm.OLS(y, X).fit()
    n = y.size
    ssr = max(float(res.ssr), 1e-300)
    return n_eff * np.log(ssr / n) + (X.shape[1] + k_extra) * np.log(n_eff)


def _refine_theta(y: np.ndarray, cols: list[np.ndarray], t: Term, best: tuple,
                  k_extra: int, n_eff: float) -> tuple:
    """Polish the nonlinear parameters of the candidate ``best`` from its grid point with the
    linear coefficients profiled out (variable projection, Golub & Pereyra 1973)."""
    base = np.column_stack([np.ones_like(y), *cols])

    def resid(th: np.ndarray) -> np.ndarray:
        col = np.asarray(t.feature(th), dtype=float)
        X = np.column_stack([base, col])
        return y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    lo, hi = np.asarray(t.lower, dtype=float), np.asarray(t.upper, dtype=float)
    th0 = np.clip(best[3], lo + 1e-9, hi - 1e-9)
    try:
        res = least_squares(resid, th0, bounds=(lo, hi), method="trf", x_scale="jac",
                            max_nfev=60)
    except ValueError:
        return best
    col = np.asarray(t.feature(res.x), dtype=float)
    b = _ols_bic(y, cols + [col], k_extra + t.k, n_eff)
    return (b, best[1], col, np.asarray(res.x)) if b < best[0] else best


def select_terms(y: np.ndarray, candidates: Sequence[Term], *, refine: bool = True
                 ) -> SelectedLaw:
    """Choose terms by BIC (module docstring) and refine them jointly."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or y.size < 3 or not np.all(np.isfinite(y)):
        raise ValueError("select_terms needs a finite 1-D target with at least 3 values")
    cols: dict[str, np.ndarray] = {}
    theta: dict[str, np.ndarray] = {}
    by_name = {t.name: t for t in candidates}
    chosen: list[str] = []
    n_eff, rho = float(y.size), 0.0
    bic = _ols_bic(y, [], 0, n_eff)
    steps: list[tuple[str, float]] = [("intercept", float(bic))]

    def k_extra(names: list[str]) -> int:
        return sum(by_name[n].k for n in names)

    while True:
        best = None
        for t in candidates:
            if t.name in chosen:
                continue
            for th in t.grid:
                col = np.asarray(t.feature(np.asarray(th, dtype=float)), dtype=float)
                if not np.all(np.isfinite(col)) or np.ptp(col) == 0:
                    continue
                b = _ols_bic(y, [cols[c] for c in chosen] + [col], k_extra(chosen) + t.k, n_eff)
                if best is None or b < best[0]:
                    best = (b, t.name, col, np.asarray(th, dtype=float))
        if best is not None and by_name[best[1]].k:
            best = _refine_theta(y, [cols[c] for c in chosen], by_name[best[1]], best,
                                 k_extra(chosen), n_eff)
        if best is None or best[0] >= bic:
            break
        bic, name, col, th = best
        chosen.append(name)
        cols[name], theta[name] = col, th
        steps.append((name, float(bic)))
    changed = True
    while changed and chosen:                       # backward pass
        changed = False
        for name in list(chosen):
            rest = [c for c in chosen if c != name]
            b = _ols_bic(y, [cols[c] for c in rest], k_extra(rest), n_eff)
            if b < bic:
                bic = b
                chosen = rest
                steps.append((f"-{name}", float(b)))
                changed = True
                break

    names = ["intercept"] + chosen
    X0 = np.column_stack([np.ones_like(y)] + [cols[c] for c in chosen])
    beta0 = np.linalg.lstsq(X0, y, rcond=None)[0]
    x0 = list(beta0)
    lo = [-np.inf] * len(x0)
    hi = [np.inf] * len(x0)
    for c in chosen:
        t = by_name[c]
        names += [f"{c}.{tn}" for tn in t.theta_names]
        x0 += list(theta[c])
        lo += list(t.lower)
        hi += list(t.upper)
    lo_a, hi_a = np.array(lo, dtype=float), np.array(hi, dtype=float)
    fin_lo, fin_hi = np.isfinite(lo_a), np.isfinite(hi_a)
    x0a = np.array(x0, dtype=float)
    x0a[fin_lo] = np.maximum(x0a[fin_lo], lo_a[fin_lo] + 1e-9 * (np.abs(lo_a[fin_lo]) + 1))
    x0a[fin_hi] = np.minimum(x0a[fin_hi], hi_a[fin_hi] - 1e-9 * (np.abs(hi_a[fin_hi]) + 1))

    def residual(x: np.ndarray) -> np.ndarray:
        pred = np.full_like(y, x[0])
        j = 1 + len(chosen)
        for i, c in enumerate(chosen):
            t = by_name[c]
            th = x[j:j + t.k]
            j += t.k
            pred = pred + x[1 + i] * (t.feature(th) if t.k else cols[c])
        return pred - y

    if not refine or not any(by_name[c].k for c in chosen):
        # linear: one solve, statistics from the same machinery
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), max_nfev=5)
    else:
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a))
    return SelectedLaw(terms=tuple(chosen), fit=res, steps=tuple(steps), bic=float(bic),
                       candidates=tuple(t.name for t in candidates), n_eff=float(n_eff),
                       rho=float(rho))
