"""Which terms of a law does the recording support? Best-subset selection by the Bayesian
information criterion, then a joint refinement with uncertainties.

A law is ``y ≈ β₀ + Σ_t β_t·f_t(θ_t)``: each candidate term ``t`` is one feature column that may
depend on a few nonlinear parameters ``θ_t`` (a knee's centre and width, a step's), with a grid
of starting values. Criterion (Schwarz 1978):

    BIC = n·ln(SSR/n) + k·ln n,     k = 1 + (number of terms) + (nonlinear parameters)

Linear terms: every subset of up to ``max_linear`` candidates is fitted (least squares) and the
one of lowest BIC kept — not forward selection, because the thermal features of a gyro are
strongly collinear (a temperature rate, the gradients a ramp drives, the UHFO that follows
both) and a greedy first step then locks in a stand-in for the true term. Nonlinear terms are
added one at a time on top (each at the best θ of its grid, polished with the linear
coefficients profiled out — variable projection, Golub & Pereyra 1973), the linear subset
re-chosen after each, while the BIC falls. The nonlinear parameters count in ``k``, so a knee
is only chosen when it pays for its centre and width. (An effective sample size from the
residual autocorrelation was tried in the BIC and rejected: the residual of an incomplete law
is smooth, so it shrinks n until no missing term can enter.)

Refinement: every coefficient and every nonlinear parameter of the chosen terms are fitted
together by :func:`rlgsim.estimators.identify.lsq_stats.fit`, whose standard errors are
inflated for the residual autocorrelation (window series of a gyro bias carry flicker noise).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
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
    """The chosen ``terms``, the refined ``fit`` (parameters ``intercept``, ``<term>``,
    ``<term>.<theta>``), the selection ``steps`` (best linear subset of each size and each
    added nonlinear term, with its BIC) and the final ``bic``."""

    terms: tuple[str, ...]
    fit: LsqFit
    steps: tuple[tuple[str, float], ...]
    bic: float
    candidates: tuple[str, ...]

    def value(self, name: str) -> float:
        return float(self.fit.x[self.fit.names.index(name)])

    def se(self, name: str) -> float:
        return float(self.fit.se[self.fit.names.index(name)])


def _bic(y: np.ndarray, X: np.ndarray, k_extra: int) -> float:
    """BIC of the least-squares fit of ``y`` on the columns of ``X`` (intercept included)."""
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    r = y - X @ beta
    n = y.size
    ssr = max(float(r @ r), 1e-300)
    return n * np.log(ssr / n) + (X.shape[1] + k_extra) * np.log(n)


def _refine_theta(y: np.ndarray, base: np.ndarray, t: Term, th0: np.ndarray) -> np.ndarray:
    """Polish the nonlinear parameters of candidate ``t`` from ``th0`` with the linear
    coefficients profiled out (variable projection, Golub & Pereyra 1973)."""
    def resid(th: np.ndarray) -> np.ndarray:
        X = np.column_stack([base, np.asarray(t.feature(th), dtype=float)])
        return y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    lo, hi = np.asarray(t.lower, dtype=float), np.asarray(t.upper, dtype=float)
    th0 = np.clip(th0, lo + 1e-9 * (1 + np.abs(lo)), hi - 1e-9 * (1 + np.abs(hi)))
    try:
        return least_squares(resid, th0, bounds=(lo, hi), method="trf", x_scale="jac",
                             max_nfev=60).x
    except ValueError:
        return th0


def select_terms(y: np.ndarray, candidates: Sequence[Term], *, max_linear: int = 6,
                 batches: int = 8) -> SelectedLaw:
    """Choose terms by BIC (module docstring) and refine them jointly."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or y.size < 3 or not np.all(np.isfinite(y)):
        raise ValueError("select_terms needs a finite 1-D target with at least 3 values")
    ones = np.ones_like(y)
    lin = [t for t in candidates if not t.k]
    nonlin = [t for t in candidates if t.k]
    lcols = {t.name: np.asarray(t.feature(np.zeros(0)), dtype=float) for t in lin}
    lin = [t for t in lin if np.all(np.isfinite(lcols[t.name])) and np.ptp(lcols[t.name]) > 0]
    by_name = {t.name: t for t in candidates}
    steps: list[tuple[str, float]] = []

    def best_subset(fixed: list[np.ndarray], k_extra: int) -> tuple[float, list[str]]:
        base = np.column_stack([ones, *fixed])
        best = (_bic(y, base, k_extra), [])
        names = [t.name for t in lin]
        for size in range(1, min(max_linear, len(names)) + 1):
            best_k = None
            for combo in itertools.combinations(names, size):
                X = np.column_stack([base] + [lcols[c] for c in combo])
                b = _bic(y, X, k_extra)
                if best_k is None or b < best_k[0]:
                    best_k = (b, list(combo))
            steps.append((" + ".join(best_k[1]), float(best_k[0])))
            if best_k[0] < best[0]:
                best = best_k
        return best

    nl_chosen: list[str] = []
    nl_cols: dict[str, np.ndarray] = {}
    theta: dict[str, np.ndarray] = {}
    bic, lin_chosen = best_subset([], 0)
    while True:
        base = np.column_stack([ones] + [nl_cols[c] for c in nl_chosen]
                               + [lcols[c] for c in lin_chosen])
        k_now = sum(by_name[c].k for c in nl_chosen)
        best = None
        for t in nonlin:
            if t.name in nl_chosen:
                continue
            for th in t.grid:
                col = np.asarray(t.feature(np.asarray(th, dtype=float)), dtype=float)
                if not np.all(np.isfinite(col)) or np.ptp(col) == 0:
                    continue
                b = _bic(y, np.column_stack([base, col]), k_now + t.k)
                if best is None or b < best[0]:
                    best = (b, t, np.asarray(th, dtype=float))
        if best is None:
            break
        t = best[1]
        th = _refine_theta(y, base, t, best[2])
        col = np.asarray(t.feature(th), dtype=float)
        b = _bic(y, np.column_stack([base, col]), k_now + t.k)
        if min(b, best[0]) >= bic:
            break
        if best[0] < b:
            th = best[2]
            col = np.asarray(t.feature(th), dtype=float)
        nl_chosen.append(t.name)
        nl_cols[t.name], theta[t.name] = col, th
        steps.append((f"+{t.name}", float(min(b, best[0]))))
        bic, lin_chosen = best_subset([nl_cols[c] for c in nl_chosen],
                                      sum(by_name[c].k for c in nl_chosen))
    chosen = [c for c in (t.name for t in candidates) if c in lin_chosen or c in nl_chosen]
    cols = {**lcols, **nl_cols}
    names = ["intercept"] + chosen
    X0 = np.column_stack([np.ones_like(y)] + [cols[c] for c in chosen])
    beta0 = np.linalg.lstsq(X0, y, rcond=None)[0]
    x0 = list(beta0)
    lo = [-np.inf] * len(x0)
    hi = [np.inf] * len(x0)
    for c in chosen:
        t = by_name[c]
        if not t.k:
            continue
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

    if not any(by_name[c].k for c in chosen):
        # linear: one solve, statistics from the same machinery
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), max_nfev=5, batches=batches)
    else:
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), batches=batches)
    return SelectedLaw(terms=tuple(chosen), fit=res, steps=tuple(steps), bic=float(bic),
                       candidates=tuple(t.name for t in candidates))
