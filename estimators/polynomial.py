"""Least-squares polynomial compensator (cubic by default; any degree; one or several inputs).

Paper 001 eq. (19) (after Buchler et al., US 6,175,807): ``B = k0 + k1·X + k2·X² + k3·X³``
with X one of T, dT/dt, UHFO; paper 000 compares its relevance-vector regression with the same
cubic least squares.  With several inputs the model holds every monomial up to ``degree``
(cross terms included unless ``interaction=False``).

Conditioning: each input is mapped to [−1, 1] over the training range before the monomials are
formed (as ``numpy.polynomial.Polynomial.fit`` does with its domain/window), so a cubic in T
over −40…70 °C has a design-matrix condition number of order 10, not 10⁷.  The solve is
``numpy.linalg.lstsq`` (SVD).  :meth:`equation` reports the equivalent raw-unit coefficients.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin

from rlgsim.estimators._validation import check_min_samples
from rlgsim.estimators.term_model import TermRegressorMixin, prepare_fit
from rlgsim.estimators.terms import design_matrix, polynomial_powers


__all__ = ["PolynomialRegressor"]

class PolynomialRegressor(TermRegressorMixin, RegressorMixin, BaseEstimator):
    """Ordinary least-squares polynomial of total degree ``degree`` in the inputs.

    Parameters
    ----------
    degree : int, default 3
        Highest total degree (3 = the papers' cubic).
    interaction : bool, default True
        Include cross terms (``T·U`` ...) when there are several inputs; ``False`` gives an
        additive sum of per-input polynomials.
    feature_names : sequence of str, optional
        Input names for reports; default the names of a
        :class:`~rlgsim.estimators.columns.Columns`, else ``x0, x1, ...``.

    Attributes
    ----------
    terms_, powers_, coef_, intercept_, coef_scaled_, intercept_scaled_, center_, scale_,
    input_names_ : see :class:`~rlgsim.estimators.term_model.TermRegressorMixin`.
    condition_number_ : float
        2-norm condition number of the scaled design matrix ``[1, z, z², ...]``.
    n_features_in_ : int

    Fitting needs at least as many samples as coefficients and inputs that take enough distinct
    values to determine them; otherwise ``ValueError``.
    """

    def __init__(self, degree: int = 3, interaction: bool = True,
                 feature_names: Sequence[str] | None = None):
        self.degree = degree
        self.interaction = interaction
        self.feature_names = feature_names

    def fit(self, X: Any, y: Any) -> PolynomialRegressor:
        """Least-squares fit of ``y`` (any unit) on the polynomial terms of ``X``; returns self."""
        X, y, names = prepare_fit(self, X, y, self.feature_names)
        powers = polynomial_powers(X.shape[1], self.degree, self.interaction)
        n_coef = len(powers) + 1
        check_min_samples(X.shape[0], n_coef,
                          f"a degree-{self.degree} polynomial in {X.shape[1]} input(s) "
                          f"({n_coef} coefficients)")
        lo, hi = X.min(axis=0), X.max(axis=0)
        center, scale = (hi + lo) / 2.0, (hi - lo) / 2.0
        A = np.column_stack([np.ones(X.shape[0]), design_matrix((X - center) / scale, powers)])
        sol, _, rank, sv = np.linalg.lstsq(A, y, rcond=None)
        if rank < n_coef:
            raise ValueError(f"the inputs cannot determine a degree-{self.degree} polynomial: "
                             f"the design matrix has rank {rank} < {n_coef} coefficients "
                             "(too few distinct input values, or collinear inputs)")
        self.condition_number_ = float(sv[0] / sv[-1])
        self._set_terms(names, powers, sol[1:], sol[0], center, scale)
        return self
