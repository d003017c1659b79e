"""Stepwise regression over second-order and cross terms (paper 001 §4.2, Models 1 and 2).

Paper 001 Model 1 selects among ``T, T², dT/dt, (dT/dt)², T·dT/dt`` starting from
``T, T², dT/dt``; Model 2 adds UHFO (``U, U², T·U, dT/dt·U``).  Terms enter when their
p-value is below 0.05 and leave when it is above 0.10.  The procedure is the classical
Efroymson stepwise algorithm in the form MATLAB's ``stepwiselm`` documents (which the paper's
"interactive stepwise regression" follows):

1. Fit the initial model (intercept + ``initial_terms`` + ``forced_terms``).
2. If some candidate outside the model would have a p-value below ``p_enter`` once added,
   add the one with the smallest p-value and repeat 2; otherwise go to 3.
3. If some term in the model (other than forced terms and the intercept) has a p-value above
   ``p_remove``, remove the one with the largest p-value and go to 2; otherwise stop.

A term's p-value is the two-sided t-test of its coefficient in the OLS fit that contains it
(equal to the partial F-test of adding/removing that single term), computed by statsmodels.
A candidate that would make the design rank deficient is never added.  No hierarchy is
imposed (paper 001 keeps ``T·dT/dt`` after dropping ``(dT/dt)²``).  Terms are raw-unit
monomials evaluated on inputs divided by their largest magnitude (p-values are scale
invariant; the design stays well conditioned).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any, NamedTuple

from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import ConvergenceWarning

from rlgsim.estimators._validation import check_min_samples
from rlgsim.estimators.mlr import parse_terms, resolve_candidates
from rlgsim.estimators.term_model import TermRegressorMixin, ols, prepare_fit, scaled_terms, \
    significance
from rlgsim.estimators.terms import term_label


__all__ = ["Step", "StepwiseRegressor"]

class Step(NamedTuple):
    """One stepwise move: ``action`` is "enter" or "remove"; ``p_value`` the term's p-value."""

    action: str
    term: str
    p_value: float


class StepwiseRegressor(TermRegressorMixin, RegressorMixin, BaseEstimator):
    """Forward/backward stepwise OLS with p-to-enter / p-to-remove (paper 001 §4.2).

    Parameters
    ----------
    degree : int, default 2
        Candidates are all monomials up to this total degree (2: squares and cross terms).
    interaction : bool, default True
        Include cross terms among the candidates.
    candidate_terms : sequence, optional
        Explicit candidates (labels ``"T"``, ``"T^2"``, ``"T*U"``, ``"(dT/dt)^2"`` or exponent
        tuples); overrides ``degree``/``interaction``.
    initial_terms : sequence, optional
        Terms in the starting model; they may be removed later.  Paper 001 Model 1:
        ``("T", "T^2", "dT/dt")``.
    forced_terms : sequence, optional
        Terms kept in the model whatever their p-value.
    p_enter : float, default 0.05
    p_remove : float, default 0.10
        Must satisfy ``0 < p_enter <= p_remove < 1`` (so a term cannot enter and leave forever).
    max_steps : int, default 100
        Safety cap on moves; reaching it gives a ``ConvergenceWarning``.
    feature_names : sequence of str, optional
        Input names (default: a :class:`~rlgsim.estimators.columns.Columns`' names, else
        x0, x1 ...).

    Attributes
    ----------
    terms_, powers_, coef_, intercept_, ... : see
        :class:`~rlgsim.estimators.term_model.TermRegressorMixin`; ``coef_`` are the statsmodels OLS
        coefficients of the final terms in raw units.
    pvalues_, bse_ : ndarray  p-values and standard errors (raw units) of ``coef_``.
    rsquared_ : float  R² of the final fit on the training data.
    history_ : list[Step]  Every move in order.
    candidates_ : tuple[str, ...]  All candidate terms.
    """

    def __init__(self, degree: int = 2, interaction: bool = True,
                 candidate_terms: Sequence | None = None, initial_terms: Sequence | None = None,
                 forced_terms: Sequence | None = None, p_enter: float = 0.05,
                 p_remove: float = 0.10, max_steps: int = 100,
                 feature_names: Sequence[str] | None = None):
        self.degree = degree
        self.interaction = interaction
        self.candidate_terms = candidate_terms
        self.initial_terms = initial_terms
        self.forced_terms = forced_terms
        self.p_enter = p_enter
        self.p_remove = p_remove
        self.max_steps = max_steps
        self.feature_names = feature_names

    def fit(self, X: Any, y: Any) -> StepwiseRegressor:
        """Run the stepwise selection and fit the final terms by OLS; returns self."""
        if not 0.0 < self.p_enter <= self.p_remove < 1.0:
            raise ValueError(f"need 0 < p_enter <= p_remove < 1, got p_enter={self.p_enter}, "
                             f"p_remove={self.p_remove}")
        X, y, names = prepare_fit(self, X, y, self.feature_names)
        cands = resolve_candidates(names, self.degree, self.interaction, self.candidate_terms,
                                   self.initial_terms, self.forced_terms)
        forced = [cands.index(p) for p in parse_terms(self.forced_terms, names)]
        model = sorted(set(forced) | {cands.index(p)
                                      for p in parse_terms(self.initial_terms, names)})
        # the initial model + one candidate, with a residual degree of freedom left
        check_min_samples(X.shape[0], len(model) + 3,
                          f"a stepwise regression starting from {len(model)} term(s) and an "
                          "intercept")
        scale, D = scaled_terms(X, cands)
        if ols(y, D[:, model]) is None:
            raise ValueError("the initial/forced terms are collinear on these data: "
                             f"{[term_label(cands[j], names) for j in model]}")
        history: list[Step] = []
        for _ in range(self.max_steps):
            # forward: smallest p-value among candidates that can be added
            best: tuple[float, int] | None = None
            for j in range(len(cands)):
                if j in model:
                    continue
                cols = sorted(model + [j])
                res = ols(y, D[:, cols])
                if res is None:
                    continue
                p = significance(res, cols.index(j) + 1)
                if best is None or p < best[0]:
                    best = (p, j)
            if best is not None and best[0] < self.p_enter:
                model = sorted(model + [best[1]])
                history.append(Step("enter", term_label(cands[best[1]], names), best[0]))
                continue
            # backward: largest p-value among removable terms
            res = ols(y, D[:, model])
            removable = [(significance(res, i + 1), j) for i, j in enumerate(model)
                         if j not in forced]
            if removable:
                p, j = max(removable)
                if p > self.p_remove:
                    model.remove(j)
                    history.append(Step("remove", term_label(cands[j], names), p))
                    continue
            break
        else:
            warnings.warn(f"stepwise regression did not settle within max_steps="
                          f"{self.max_steps} moves", ConvergenceWarning, stacklevel=2)
        res = ols(y, D[:, model])
        self.history_ = history
        self.rsquared_ = float(res.rsquared)
        self._set_ols_terms(names, cands, model, res, scale)
        return self
