"""What the polynomial, MLR and stepwise regressors share once their terms are chosen.

* :func:`prepare_fit` — scikit-learn input validation plus the project's checks (input names,
  no constant input, enough samples), returning the scaled inputs.
* :func:`ols` — an ordinary-least-squares fit of ``y`` on ``[1, terms]`` with statsmodels
  (coefficients, standard errors, t-test p-values, BIC), or ``None`` if the terms are
  collinear on these data.  statsmodels is the reference for every statistic used for term
  selection; nothing is re-derived here.
* :class:`TermRegressorMixin` — ``predict`` from the scaled terms, the raw-unit coefficients
  and the printed equation.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
import statsmodels.api as sm
from sklearn.utils.validation import check_is_fitted, validate_data

from rlgsim.estimators._validation import validate_fit_input
from rlgsim.estimators.columns import resolve_input_names, select_inputs
from rlgsim.estimators.terms import (Powers, design_matrix, format_equation, raw_coefficients,
                                     term_label, term_pretty)


def prepare_fit(estimator: Any, X: Any, y: Any,
                feature_names: Sequence[str] | None) -> tuple[np.ndarray, np.ndarray,
                                                              tuple[str, ...]]:
    """Validate ``X``/``y`` for ``estimator.fit`` and return ``(X, y, input_names)``.

    ``ValueError`` for NaN/inf, mismatched lengths, fewer than 2 samples, a constant input
    (named), or bad ``feature_names``.  Sets ``n_features_in_`` (via ``validate_data``).
    """
    given = X

    def input_names(n_features: int) -> tuple[str, ...]:
        return resolve_input_names(given, feature_names, n_features)

    X, y = validate_fit_input(estimator, X, y, input_names=input_names)
    return X, y, input_names(X.shape[1])


def ols(y: np.ndarray, terms: np.ndarray):
    """statsmodels OLS of ``y`` on ``[1, terms]``; ``None`` if rank deficient or no residual
    degree of freedom is left.

    Perfect fits (zero residual) are allowed; their p-values may be NaN, which callers treat
    as "not significant".
    """
    n, k = terms.shape[0], terms.shape[1] + 1
    if n - k < 1:
        return None
    exog = np.column_stack([np.ones(n), terms])
    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        warnings.simplefilter("ignore")        # singular-design and 0/0 warnings: checked below
        res = sm.OLS(y, exog, hasconst=True).fit()
    if res.model.rank < k:
        return None
    return res


def significance(res, index: int) -> float:
    """Two-sided t-test p-value of column ``index`` of a :func:`ols` fit (NaN read as 1)."""
    p = float(res.pvalues[index])
    return 1.0 if not np.isfinite(p) else p


class TermRegressorMixin:
    """``predict`` and ``equation`` for a fitted polynomial-term model.

    The estimator's ``fit`` calls :meth:`_set_terms`, which stores

    ``input_names_``   names of the inputs;
    ``center_``, ``scale_``  the input scaling ``z = (x − center_)/scale_`` (input units);
    ``powers_``        exponent tuple of each term (one exponent per input);
    ``terms_``         plain labels of the terms (``"T^2"``, ``"T*dT/dt"``);
    ``coef_scaled_``, ``intercept_scaled_``  the fit on the scaled terms (used by predict);
    ``coef_``, ``intercept_``  the same model on raw-unit terms (units of y per unit of the
                       term), for reports — aligned with ``terms_``.
    """

    def _set_terms(self, names: tuple[str, ...], powers: Sequence[Powers], coef_z: np.ndarray,
                   intercept_z: float, center: np.ndarray, scale: np.ndarray) -> None:
        self.input_names_ = names
        self.center_ = np.asarray(center, dtype=np.float64)
        self.scale_ = np.asarray(scale, dtype=np.float64)
        self.powers_ = tuple(tuple(p) for p in powers)
        self.terms_ = tuple(term_label(p, names) for p in self.powers_)
        self.coef_scaled_ = np.asarray(coef_z, dtype=np.float64)
        self.intercept_scaled_ = float(intercept_z)
        raw = raw_coefficients(self.powers_, self.coef_scaled_, self.intercept_scaled_,
                               self.center_, self.scale_)
        zero = (0,) * len(names)
        extra = set(raw) - set(self.powers_) - {zero}
        if extra:  # cannot happen for the term sets the estimators build
            raise RuntimeError(f"raw expansion produced terms outside the model: {extra}")
        self.intercept_ = raw[zero]
        self.coef_ = np.array([raw.get(p, 0.0) for p in self.powers_])

    def _set_ols_terms(self, names: tuple[str, ...], candidates: Sequence[Powers],
                       cols: Sequence[int], res: Any, scale: np.ndarray) -> None:
        """Store an :func:`ols` fit on the columns ``cols`` of the candidate terms evaluated on
        ``x / scale`` (:func:`scaled_terms`): ``candidates_``, raw-unit ``bse_``, ``pvalues_``
        and the terms/coefficients of :meth:`_set_terms`."""
        powers = [candidates[j] for j in cols]
        factors = np.array([np.prod(scale ** np.array(p)) for p in powers])
        self.candidates_ = tuple(term_label(p, names) for p in candidates)
        self.pvalues_ = np.asarray(res.pvalues[1:])
        self.bse_ = np.asarray(res.bse[1:]) / factors
        self._set_terms(names, powers, np.asarray(res.params[1:]), float(res.params[0]),
                        np.zeros(len(names)), scale)

    def predict(self, X: Any) -> np.ndarray:
        """Model output for inputs ``X`` (array or :class:`~rlgsim.estimators.columns.Columns`
        holding the fitted inputs by name); units of the training target."""
        check_is_fitted(self, "coef_scaled_")
        X = select_inputs(X, self.input_names_)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        Z = (X - self.center_) / self.scale_
        return self.intercept_scaled_ + design_matrix(Z, self.powers_) @ self.coef_scaled_

    def equation(self, target: str = "y", precision: int = 4, ascii: bool = False) -> str:
        """The fitted model with raw-unit coefficients, e.g.
        ``"B = 1.427×10⁻³ + 4.906×10⁻⁴·T − 4.616×10⁻⁶·T²"`` (paper 001 §4.2 style)."""
        check_is_fitted(self, "coef_scaled_")
        labels = self.terms_ if ascii else [term_pretty(p, self.input_names_)
                                            for p in self.powers_]
        return format_equation(target, self.intercept_, self.coef_, labels, precision, ascii)


def scaled_terms(X: np.ndarray, powers: Sequence[Powers]) -> tuple[np.ndarray, np.ndarray]:
    """Pure scaling ``z = x / max|x|`` (per input) and the term columns on ``z``.

    No shift, so each raw term is one scaled term times a constant and selecting terms on
    ``z`` selects the same raw-unit models (p-values and BIC are scale invariant).
    """
    scale = np.max(np.abs(X), axis=0)
    return scale, design_matrix(X / scale, powers)
