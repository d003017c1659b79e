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

Selection uncertainty — the model-averaged coefficients, the unseparable groups, their combined
effects and stand-ins — is computed by :mod:`rlgsim.estimators.identify.term_averaging` (its
docstring gives the method and sources); the subsets it weighs are those this module fits.

Refinement: every coefficient and every nonlinear parameter of the chosen terms are fitted
together by :func:`rlgsim.estimators.identify.lsq_stats.fit`, whose standard errors are
inflated for the residual autocorrelation (window series of a gyro bias carry flicker noise).

Generalised least squares: given the modelled covariance C of the target's noise
(``noise_cov``, e.g. :mod:`rlgsim.estimators.identify.window_noise` for the window means of a
gyro's flicker), everything above runs on the problem whitened by the Cholesky factor of C —
the BIC, the subset weights (ĉ then the whitened residual's variance per degree of freedom),
the variance inflation factors, the unseparable groups — and the standard errors are the
modelled ``(XᵀC⁻¹X)⁻¹`` instead of batch means.

Fixed regressors (``fixed``): linear columns that are in every model — e.g. the piecewise
offsets of detected mode hops (:mod:`rlgsim.lab.identify.hop_fit`) — are part of the base
beside the intercept: not selected, not counted in the BIC's comparison (every subset carries
them), refined jointly with the chosen terms (parameters named as the fixed terms) and held in
every averaged model (inclusion 1).

Why this file is long: the selection (subsets, nonlinear terms), its joint refinement and the
selected law's record with its predictions are one procedure read together; the subsets' fits
(:mod:`.subset_fits`), their screen (:mod:`.subset_conditioning`) and the averaging
(:mod:`.term_averaging`) are apart.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from rlgsim.estimators.identify.lsq_stats import LsqFit, fit
from rlgsim.estimators.identify.subset_conditioning import passing
from rlgsim.estimators.identify.subset_fits import added_column_ssr, subset_ssr
from rlgsim.estimators.identify.term_averaging import (averaging, corr_matrix, vif_of,
                                                      without_intercept)
from rlgsim.estimators.identify.whitening import whitener

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
    #: the feature at several thetas at once, (n, len(thetas)) (None: one at a time)
    columns: Callable[[list[np.ndarray]], np.ndarray] | None = None

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
    #: {term or "intercept": (model-averaged value, its standard error, inclusion probability)}
    averaged: dict = field(default_factory=dict)
    #: ((terms, one-line reason), ...) groups the recording cannot separate
    unseparable: tuple = ()
    #: variance inflation factor of each chosen linear term; overdispersion ĉ of the weights
    vif: dict = field(default_factory=dict)
    c_hat: float = 1.0
    #: averaged models: (base names, subset, coefficients, covariance, weight)
    models: tuple = ()
    #: window residual of the refined law, prediction − target (not whitened)
    residual: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: True when fitted by generalised least squares with a modelled noise covariance
    gls: bool = False
    #: {unseparable group: (lead term, combined coefficient in its units, standard error,
    #: {member: slope on the lead})}
    combined: dict = field(default_factory=dict)
    #: names of the fixed regressors (in every model, not selected)
    fixed: tuple[str, ...] = ()
    #: {unseparable group: {member: (stand-in coefficient, regressor names, coefficients)}}:
    #: the member alone carrying the group's combined effect, and the member's feature
    #: regressed on the intercept, the fixed and nonlinear terms, the chosen law's other terms
    #: and the lead (:func:`~rlgsim.estimators.identify.term_averaging._standins`)
    standins: dict = field(default_factory=dict)
    #: the model holding the chosen terms and every member of every unseparable group: (base
    #: names, its linear terms, coefficients, covariance) — the within-model variance of
    #: :meth:`predict` (:func:`~rlgsim.estimators.identify.term_averaging._full_model`)
    full_model: tuple = ()

    def value(self, name: str) -> float:
        return float(self.fit.x[self.fit.names.index(name)])

    def se(self, name: str) -> float:
        return float(self.fit.se[self.fit.names.index(name)])

    def predict(self, cols: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        """Model-averaged prediction and its standard error (selection included) from the
        feature columns ``cols`` {term: (m,)} (nonlinear terms at their chosen parameters):
        the variance is Burnham & Anderson's unconditional one (2002, §4.3.2, in the form
        with the squares averaged, §6.3), the spread of the models' predictions about the average plus a
        within-model variance taken from :attr:`full_model`, ``x*ᵀ Σ_full x*``, in place of
        each subset's own (:mod:`~rlgsim.estimators.identify.term_averaging`, *Prediction
        band*)."""
        m = next(iter(cols.values())).shape[0]
        preds, vars_, ws = [], [], []
        for base, subset, beta, cov, w in self.models:
            X = self._design(cols, base, subset, m)
            preds.append(X @ beta)
            vars_.append(np.einsum("ij,jk,ik->i", X, cov, X))
            ws.append(w)
        P, V, W = np.array(preds), np.array(vars_), np.array(ws)[:, None]
        mean = (W * P).sum(axis=0)
        spread = (W * (P - mean) ** 2).sum(axis=0)
        within = self.full_variance(cols) if self.full_model else (W * V).sum(axis=0)
        return mean, np.sqrt(within + spread)

    @staticmethod
    def _design(cols: dict, base: Sequence[str], subset: Sequence[str], m: int) -> np.ndarray:
        return np.column_stack([np.ones(m)] + [cols[c] for c in base[1:]]
                               + [cols[c] for c in subset])

    def full_variance(self, cols: dict[str, np.ndarray]) -> np.ndarray:
        """Variance of the :attr:`full_model`'s prediction on ``cols``, ``x*ᵀ Σ_full x*``."""
        m = next(iter(cols.values())).shape[0]
        base, terms, _, cov = self.full_model
        X = self._design(cols, base, terms, m)
        return np.einsum("ij,jk,ik->i", X, cov, X)


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


def _distinct(lin: list[Term], lcols: dict, ones: np.ndarray) -> list[Term]:
    """The linear candidates without those whose column repeats an earlier one exactly (two
    gradients of a symmetric twin: A−D and A−E with D, E mirror nodes) — it carries nothing
    new: the earlier candidate stands for both."""
    lin = list(lin)
    unit = {}
    for t in list(lin):
        v = without_intercept(lcols[t.name], ones)
        v = v / np.linalg.norm(v)
        if any(abs(float(v @ u)) > 1 - 1e-9 for u in unit.values()):
            lin.remove(t)
        else:
            unit[t.name] = v
    return lin


def _best_subset(y: np.ndarray, base: np.ndarray, names: list[str], lcols: dict, R: dict,
                 max_linear: int, k_extra: int,
                 steps: list[tuple[str, float]]) -> tuple[float, list[str]]:
    """Lowest-BIC subset of the linear candidates ``names`` (up to ``max_linear``, every
    well-conditioned one) on top of ``base``; appends the best of each size to ``steps``."""
    best = (_bic(y, base, k_extra), [])
    n = y.size
    for size in range(1, min(max_linear, len(names)) + 1):
        combos = passing(R, names, size)               # the well-conditioned ones
        if not combos:
            continue
        ssr = np.maximum(subset_ssr(y, base, lcols, combos), 1e-300)   # all at once
        bics = n * np.log(ssr / n) + (base.shape[1] + size + k_extra) * np.log(n)
        i = int(np.argmin(bics))                       # the first of equal ones, as before
        best_k = (float(bics[i]), list(combos[i]))
        steps.append((" + ".join(best_k[1]), float(best_k[0])))
        if best_k[0] < best[0]:
            best = best_k
    return best


def _best_nonlinear(y: np.ndarray, base: np.ndarray, nonlin: list[Term], nl_chosen: list[str],
                    k_now: int) -> tuple[float, Term, np.ndarray] | None:
    """The nonlinear candidate (not yet chosen) and grid start of lowest BIC added to
    ``base``: (BIC, term, theta), or None when no grid point gives a usable column. A term's
    grid at once (its ``columns``; the fits: :func:`added_column_ssr`)."""
    best, n = None, y.size
    for t in nonlin:
        if t.name in nl_chosen:
            continue
        grid = [np.asarray(th, dtype=float) for th in t.grid]
        C = (t.columns(grid) if t.columns is not None
             else np.column_stack([np.asarray(t.feature(th), dtype=float) for th in grid]))
        good = np.flatnonzero(np.all(np.isfinite(C), axis=0) & (np.ptp(C, axis=0) != 0))
        if not good.size:
            continue
        ssr = np.maximum(added_column_ssr(y, base, C[:, good]), 1e-300)
        b = n * np.log(ssr / n) + (base.shape[1] + 1 + k_now + t.k) * np.log(n)
        j = int(np.argmin(b))                 # the first of equal ones, in grid order
        if best is None or b[j] < best[0]:
            best = (float(b[j]), t, grid[good[j]])
    return best


def _start_and_bounds(y: np.ndarray, X0: np.ndarray, chosen: list[str], by_name: dict,
                      theta: dict, names: list[str]
                      ) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray]:
    """Starting point of the joint refinement (the linear least-squares coefficients, then the
    chosen thetas), its parameter names (``names`` extended by ``<term>.<theta>``) and bounds;
    the start nudged 1e-9 (relative) inside finite bounds."""
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
    return x0a, names, lo_a, hi_a


def _raw_residual(res: LsqFit, y_raw: np.ndarray, fixed: Sequence[Term], chosen: list[str],
                  by_name: dict, raw_features: dict) -> np.ndarray:
    """The refined law's prediction − target in the target's own units (not whitened)."""
    nf = len(fixed)
    raw_pred = np.full_like(y_raw, res.x[0])
    for i, t in enumerate(fixed):
        raw_pred = raw_pred + res.x[1 + i] * np.asarray(t.feature(np.zeros(0)), dtype=float)
    j = 1 + nf + len(chosen)
    for i, c in enumerate(chosen):
        k = by_name[c].k
        raw_pred = raw_pred + res.x[1 + nf + i] * np.asarray(raw_features[c](res.x[j:j + k]),
                                                             dtype=float)
        j += k
    return raw_pred - y_raw


def _choose(y: np.ndarray, ones: np.ndarray, fcols: list[np.ndarray], lin: list[Term],
            lcols: dict, nonlin: list[Term], by_name: dict, max_linear: int,
            steps: list[tuple[str, float]]) -> tuple[float, list[str], list[str], dict, dict]:
    """The selection: the best linear subset, then nonlinear terms added one at a time (best
    grid start, polished by variable projection) while the BIC falls, the linear subset
    re-chosen after each. Returns (BIC, chosen linear names, chosen nonlinear names, their
    columns, their thetas)."""
    R = corr_matrix(lcols, [t.name for t in lin], ones)
    lin_names = [t.name for t in lin]
    nl_chosen: list[str] = []
    nl_cols: dict[str, np.ndarray] = {}
    theta: dict[str, np.ndarray] = {}
    bic, lin_chosen = _best_subset(y, np.column_stack([ones, *fcols]), lin_names, lcols, R,
                                   max_linear, 0, steps)
    while True:
        base = np.column_stack([ones] + fcols + [nl_cols[c] for c in nl_chosen]
                               + [lcols[c] for c in lin_chosen])
        k_now = sum(by_name[c].k for c in nl_chosen)
        best = _best_nonlinear(y, base, nonlin, nl_chosen, k_now)
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
        bic, lin_chosen = _best_subset(
            y, np.column_stack([ones, *fcols, *[nl_cols[c] for c in nl_chosen]]), lin_names,
            lcols, R, max_linear, sum(by_name[c].k for c in nl_chosen), steps)
    return bic, lin_chosen, nl_chosen, nl_cols, theta


def select_terms(y: np.ndarray, candidates: Sequence[Term], *, max_linear: int = 6,
                 batches: int = 8, noise_cov: np.ndarray | None = None,
                 fixed: Sequence[Term] = ()) -> SelectedLaw:
    """Choose terms by BIC (module docstring) and refine them jointly.

    ``fixed``: linear terms (no theta) carried in every model beside the intercept (module
    docstring); their names must differ from the candidates'.

    ``noise_cov``: the modelled (n, n) covariance of the target's noise (e.g. the window
    means of a gyro's flicker, :mod:`rlgsim.estimators.identify.window_noise`). With it every
    fit is generalised least squares (Aitken 1935): target, intercept and every feature are
    whitened by its Cholesky factor ``L`` (``L⁻¹y = L⁻¹Xβ + L⁻¹e``, independent unit-variance
    errors if the model holds), the BIC, the weights and the collinearity measures are those
    of the whitened problem, and the standard errors are the modelled ``(XᵀC⁻¹X)⁻¹`` (times the
    whitened residual's variance when above 1) instead of batch means, which cannot see noise
    slower than a batch."""
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or y.size < 3 or not np.all(np.isfinite(y)):
        raise ValueError("select_terms needs a finite 1-D target with at least 3 values")
    y_raw = y
    white = whitener(noise_cov, y.size)
    gls = noise_cov is not None
    ones = white(np.ones_like(y))
    y = white(y)
    fixed_names = [t.name for t in fixed]
    if any(t.k for t in fixed) or set(fixed_names) & {t.name for t in candidates}:
        raise ValueError("fixed regressors must be linear terms named apart from the candidates")
    fcols = [white(np.asarray(t.feature(np.zeros(0)), dtype=float)) for t in fixed]
    lin = [t for t in candidates if not t.k]
    lcols = {t.name: np.asarray(t.feature(np.zeros(0)), dtype=float) for t in lin}
    lin = [t for t in lin if np.all(np.isfinite(lcols[t.name])) and np.ptp(lcols[t.name]) > 0]
    raw_features = {t.name: t.feature for t in candidates}
    if gls:
        lcols = {k: white(v) for k, v in lcols.items()}
        candidates = [Term(t.name, (lambda th, f=t.feature: white(f(th))), t.theta_names,
                           t.grid, t.lower, t.upper, (lambda ths, f=t.feature: white(
                               np.column_stack([np.asarray(f(th), dtype=float) for th in ths]))))
                      for t in candidates]
        lin = [next(c for c in candidates if c.name == t.name) for t in lin]
    nonlin = [t for t in candidates if t.k]
    lin = _distinct(lin, lcols, ones)
    by_name = {t.name: t for t in candidates}
    steps: list[tuple[str, float]] = []
    bic, lin_chosen, nl_chosen, nl_cols, theta = _choose(y, ones, fcols, lin, lcols, nonlin,
                                                         by_name, max_linear, steps)
    chosen = [c for c in (t.name for t in candidates) if c in lin_chosen or c in nl_chosen]
    cols = {**lcols, **nl_cols, **dict(zip(fixed_names, fcols))}
    nf = len(fixed_names)
    X0 = np.column_stack([ones] + fcols + [cols[c] for c in chosen])
    x0a, names, lo_a, hi_a = _start_and_bounds(y, X0, chosen, by_name, theta,
                                               ["intercept"] + fixed_names + chosen)

    def residual(x: np.ndarray) -> np.ndarray:
        pred = x[0] * ones
        for i, col in enumerate(fcols):
            pred = pred + x[1 + i] * col
        j = 1 + nf + len(chosen)
        for i, c in enumerate(chosen):
            t = by_name[c]
            th = x[j:j + t.k]
            j += t.k
            pred = pred + x[1 + nf + i] * (t.feature(th) if t.k else cols[c])
        return pred - y

    if not any(by_name[c].k for c in chosen):
        # linear: one solve, statistics from the same machinery
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), max_nfev=5, batches=batches,
                  whitened=gls)
    else:
        res = fit(residual, x0a, names, bounds=(lo_a, hi_a), batches=batches, whitened=gls)
    base = np.column_stack([ones] + fcols + [nl_cols[c] for c in nl_chosen])
    averaged, groups, c_hat, models, combined, standins, full_model = averaging(
        y, base, ["intercept", *fixed_names, *nl_chosen], [t.name for t in lin], lcols,
        lin_chosen, max_linear, batches, gls)
    for name in nl_chosen:                     # held at the choice: its own refined values
        averaged[name] = (float(res.x[names.index(name)]), float(res.se[names.index(name)]), 1.0)
    return SelectedLaw(terms=tuple(chosen), fit=res, steps=tuple(steps), bic=float(bic),
                       candidates=tuple(t.name for t in candidates), averaged=averaged,
                       unseparable=groups, vif=vif_of(base, lcols, lin_chosen), c_hat=c_hat,
                       models=models, residual=_raw_residual(res, y_raw, fixed, chosen,
                                                             by_name, raw_features),
                       gls=gls, combined=combined, fixed=tuple(fixed_names),
                       standins=standins, full_model=full_model)
