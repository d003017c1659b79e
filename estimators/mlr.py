"""Multiple linear regression with term selection by the Bayesian information criterion.

Paper 002 §4.2: "The MLR model was used in selecting regression variables using approximate
Bayesian information criteria to eliminate unimportant variables ... When the criterion
function achieves the smallest value, the selected variables suggest the best compensation
model" (their result: constant, T and dT/dt).  Candidates are the polynomial terms of the
inputs up to ``degree`` (or an explicit list); the intercept is always in the model.

BIC (Schwarz 1978) is statsmodels' ``OLSResults.bic = −2·ln L + k·ln n`` with the Gaussian
log-likelihood at the ML variance, ``k`` = number of coefficients including the intercept.
It differs from the "approximate" ``n·ln(RSS/n) + k·ln n`` only by the constant
``n·(1 + ln 2π)``, so both pick the same model.

Search: ``"exhaustive"`` scores every subset of the free candidates (2^m OLS fits);
``"greedy"`` starts from the forced terms and repeatedly makes the single addition or removal
that lowers BIC most, until none does; ``"auto"`` is exhaustive up to
``max_exhaustive_terms`` free candidates, greedy beyond.  Terms are raw-unit monomials (T, T²,
T·dT/dt ...); they are evaluated on inputs divided by their largest magnitude, which leaves
every BIC unchanged and keeps the design well conditioned.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import combinations
from typing import Any, NamedTuple

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin

from rlgsim.estimators._validation import check_min_samples
from rlgsim.estimators.term_model import TermRegressorMixin, ols, prepare_fit, scaled_terms
from rlgsim.estimators.terms import Powers, parse_term, polynomial_powers, term_label


__all__ = ["ScoredModel", "resolve_candidates", "parse_terms", "MLRBICRegressor"]

class ScoredModel(NamedTuple):
    """One visited model: its terms (labels, intercept implied) and its BIC."""

    terms: tuple[str, ...]
    bic: float


def resolve_candidates(names: tuple[str, ...], degree: int, interaction: bool,
                       candidate_terms: Sequence | None, *extra: Sequence | None) -> list[Powers]:
    """Candidate terms: ``candidate_terms`` parsed, else all monomials up to ``degree``; terms
    in ``extra`` lists (forced/initial) are appended if missing.  Duplicates are an error."""
    if candidate_terms is None:
        cands = polynomial_powers(len(names), degree, interaction)
    else:
        cands = [parse_term(t, names) for t in candidate_terms]
        if len(set(cands)) != len(cands):
            raise ValueError(f"candidate_terms repeats a term: {list(candidate_terms)}")
    for terms in extra:
        for t in terms or ():
            p = parse_term(t, names)
            if p not in cands:
                cands.append(p)
    if not cands:
        raise ValueError("no candidate terms")
    return cands


def parse_terms(terms: Sequence | None, names: tuple[str, ...]) -> list[Powers]:
    """Parse a list of term labels/exponent tuples (``None`` → empty), rejecting repeats."""
    out = [parse_term(t, names) for t in terms or ()]
    if len(set(out)) != len(out):
        raise ValueError(f"a term is listed twice: {list(terms)}")
    return out


class MLRBICRegressor(TermRegressorMixin, RegressorMixin, BaseEstimator):
    """Multiple linear regression whose terms are chosen by minimum BIC (paper 002).

    Parameters
    ----------
    degree : int, default 2
        Candidate terms are all monomials of the inputs up to this total degree.
    interaction : bool, default True
        Include cross terms among the candidates.
    candidate_terms : sequence, optional
        Explicit candidates instead (labels such as ``"T"``, ``"T^2"``, ``"T*dT/dt"`` or
        exponent tuples); overrides ``degree``/``interaction``.
    forced_terms : sequence, optional
        Terms always in the model (the intercept always is).
    search : {"auto", "exhaustive", "greedy"}, default "auto"
    max_exhaustive_terms : int, default 10
        "auto" searches exhaustively up to this many free candidates (2^10 = 1024 fits).
    feature_names : sequence of str, optional
        Input names (default: a :class:`~rlgsim.estimators.columns.Columns`' names, else
        x0, x1 ...).

    Attributes
    ----------
    terms_, powers_, coef_, intercept_, ... : see
        :class:`~rlgsim.estimators.term_model.TermRegressorMixin`; ``coef_`` are the statsmodels OLS
        coefficients of the chosen terms in raw units.
    bic_ : float  BIC of the chosen model.
    pvalues_, bse_ : ndarray  t-test p-values and standard errors of ``coef_`` (statsmodels).
    candidates_ : tuple[str, ...]  All candidate terms.
    search_path_ : list[ScoredModel]  Exhaustive: the best model of each size; greedy: the
        model after each step.
    search_used_ : str  "exhaustive" or "greedy".
    """

    def __init__(self, degree: int = 2, interaction: bool = True,
                 candidate_terms: Sequence | None = None, forced_terms: Sequence | None = None,
                 search: str = "auto", max_exhaustive_terms: int = 10,
                 feature_names: Sequence[str] | None = None):
        self.degree = degree
        self.interaction = interaction
        self.candidate_terms = candidate_terms
        self.forced_terms = forced_terms
        self.search = search
        self.max_exhaustive_terms = max_exhaustive_terms
        self.feature_names = feature_names

    def fit(self, X: Any, y: Any) -> MLRBICRegressor:
        """Choose the terms by BIC and fit them by OLS; returns self."""
        if self.search not in ("auto", "exhaustive", "greedy"):
            raise ValueError(f"search must be 'auto', 'exhaustive' or 'greedy', "
                             f"got {self.search!r}")
        X, y, names = prepare_fit(self, X, y, self.feature_names)
        cands = resolve_candidates(names, self.degree, self.interaction, self.candidate_terms,
                                   self.forced_terms)
        forced_p = parse_terms(self.forced_terms, names)
        forced = [cands.index(p) for p in forced_p]
        # intercept + forced terms + one candidate, with a residual degree of freedom left
        check_min_samples(X.shape[0], len(forced) + 3,
                          f"BIC selection over {len(forced)} forced term(s) and an intercept")
        scale, D = scaled_terms(X, cands)
        free = [j for j in range(len(cands)) if j not in forced]

        def bic(cols: Sequence[int]) -> float:
            res = ols(y, D[:, sorted(cols)])
            return np.inf if res is None else float(res.bic)

        def labels(cols: Sequence[int]) -> tuple[str, ...]:
            return tuple(term_label(cands[j], names) for j in sorted(cols))

        exhaustive = self.search == "exhaustive" or (
            self.search == "auto" and len(free) <= self.max_exhaustive_terms)
        path: list[ScoredModel] = []
        if exhaustive:
            best_cols, best_bic = list(forced), bic(forced)
            path.append(ScoredModel(labels(forced), best_bic))
            for size in range(1, len(free) + 1):
                size_best: tuple[float, list[int]] = (np.inf, [])
                for extra in combinations(free, size):
                    cols = forced + list(extra)
                    b = bic(cols)
                    if b < size_best[0]:
                        size_best = (b, cols)
                if size_best[1]:
                    path.append(ScoredModel(labels(size_best[1]), size_best[0]))
                    if size_best[0] < best_bic:
                        best_bic, best_cols = size_best
        else:
            best_cols, best_bic = list(forced), bic(forced)
            path.append(ScoredModel(labels(best_cols), best_bic))
            while True:
                moves = [best_cols + [j] for j in free if j not in best_cols]
                moves += [[c for c in best_cols if c != j] for j in best_cols if j not in forced]
                scored = [(bic(m), m) for m in moves]
                if not scored:
                    break
                b, cols = min(scored, key=lambda s: s[0])
                if not b < best_bic:
                    break
                best_bic, best_cols = b, cols
                path.append(ScoredModel(labels(best_cols), best_bic))
        if not np.isfinite(best_bic):
            raise ValueError("no candidate model could be fitted: the forced terms are "
                             "collinear on these data or there are too few samples")
        cols = sorted(best_cols)
        res = ols(y, D[:, cols])
        self.search_used_ = "exhaustive" if exhaustive else "greedy"
        self.search_path_ = path
        self.bic_ = float(res.bic)
        self._set_ols_terms(names, cands, cols, res, scale)
        return self
