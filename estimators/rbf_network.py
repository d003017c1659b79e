"""Traditional RBF neural network (paper 002 §2.1, the "traditional RBFNN" of its Table 1),
designed the way MATLAB's ``newrb`` designs it.

Model (paper 002 eq. 1-2; MATLAB ``newrb``)::

    y(x) = b + sum_j w_j * exp(-ln 2 * ||z(x) - z(c_j)||**2 / spread**2)

where ``z`` standardises each input column with the training mean and standard deviation
(ddof=0), so ``spread`` is measured in training standard deviations; a neuron outputs 0.5 at
distance ``spread`` from its centre (``newrb``: ``radbas(dist * 0.8326 / spread)``). Units:
``y`` and ``b``, ``w_j`` in the target's unit (e.g. °/h); ``goal`` in that unit squared;
centres in the input units (e.g. °C and K/s for inputs T and dT/dt).

Design (``newrb``'s ``designrb``): every training input is a candidate centre. Starting from an
empty hidden layer, the network adds, one at a time, the training input whose Gaussian column
most reduces the error — ranked by ``newrb``'s ratio ``e = (w' t)**2 / (w' w * t' t)`` of the
candidate column ``w`` made orthogonal to the columns already chosen, against the raw target
``t`` — which is the Chen-Cowan-Grant orthogonal-least-squares step without a bias term
(:class:`rlgsim.estimators.rbf_common.ForwardOLS`, ``bias="after"``). After each addition the linear
output layer (weights and bias) is the least-squares fit (what ``newrb``'s ``solvelin2``
computes; here by back substitution in the OLS triangular system), and growing stops once its
training mean squared error is at most ``goal`` or ``max_centers`` neurons are in place. (Unlike
``newrb``, no neuron is added when the bias alone already meets ``goal``.) Memory and time grow
as n² (the n x n candidate matrix), as in ``newrb``; a few thousand samples (paper 002's data:
hours at one 100 s average each) are fine.
"""

from __future__ import annotations

import math
import numbers
import warnings

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import ConvergenceWarning

from rlgsim.estimators._validation import check_positive, standardisation, validate_fit_input
from rlgsim.estimators.rbf_common import ForwardOLS, GaussianNetworkOutput, gaussian_design


__all__ = ["RBFNetwork"]

class RBFNetwork(GaussianNetworkOutput, RegressorMixin, BaseEstimator):
    """Gaussian RBF network grown like MATLAB ``newrb`` (paper 002's traditional RBFNN).

    Parameters
    ----------
    goal : float, default 0.0
        Mean-squared-error goal on the training data, in the target's unit squared (``newrb``
        GOAL). Growing stops as soon as the training MSE is <= ``goal``. With the default 0 the
        network grows to ``max_centers`` (or until every remaining candidate is numerically
        dependent on the chosen ones).
    spread : float, default 1.0
        Distance, in standardised input units (training standard deviations), at which a
        neuron's output falls to 0.5 (``newrb`` SPREAD). Paper 002's receptive field is
        ``delta = spread / sqrt(ln 2)``.
    max_centers : int or None, default None
        Largest number of hidden neurons (``newrb`` MN); None means the number of samples.
    centred_ranking : bool, default False
        False ranks candidates exactly as ``newrb`` does, against the raw target (the bias only
        enters the least-squares output layer). True puts the bias in the model before ranking,
        so candidates are ranked against the target's variation about its mean — the
        treatment of :class:`rlgsim.estimators.rbf_modified.ModifiedRBFNetwork`; not ``newrb``,
        it is there to separate the effect of the ranking from that of the candidate set.

    Attributes
    ----------
    centers_ : ndarray of shape (n_centers_, n_features_in_)
        Chosen centres in the input units, in the order they were added.
    center_indices_ : ndarray of int
        Row of the training ``X`` each centre was taken from.
    weights_ : ndarray of shape (n_centers_,)
        Output-layer weights (target unit).
    intercept_ : float
        Output-layer bias (target unit).
    n_centers_ : int
        Number of hidden neurons.
    err_ratios_ : ndarray of shape (n_centers_,)
        Error-reduction ratio of each chosen neuron: the fraction of ``y' y`` it explains,
        orthogonalised against those before it (``newrb``'s ``e``); with ``centred_ranking``
        the fraction of ``sum((y - mean y)**2)``.
    mse_history_ : ndarray of shape (n_centers_ + 1,)
        Training MSE with 0, 1, ... ``n_centers_`` neurons (entry 0: bias only, the variance
        of ``y``) — ``newrb``'s ``tr.perf``.
    mse_ : float
        Final training MSE (target unit squared).
    x_mean_, x_scale_ : ndarray of shape (n_features_in_,)
        Standardisation of the inputs (training mean and standard deviation, ddof=0).
    n_features_in_ : int
        Number of inputs.
    """

    def __init__(self, goal: float = 0.0, spread: float = 1.0,
                 max_centers: int | None = None, centred_ranking: bool = False) -> None:
        self.goal = goal
        self.spread = spread
        self.max_centers = max_centers
        self.centred_ranking = centred_ranking

    def fit(self, X, y):
        """Grow the network on inputs ``X`` (n, n_features) and target ``y`` (n,).

        Raises ``ValueError`` for NaN/inf, mismatched lengths, fewer than 2 samples, a
        constant input column, or invalid parameters.
        """
        X, y = validate_fit_input(self, X, y)
        spread = check_positive(self.spread, "spread")
        goal = self.goal
        if not (isinstance(goal, numbers.Real) and math.isfinite(goal) and goal >= 0):
            raise ValueError(f"goal must be a finite mean squared error >= 0, got {goal!r}")
        check_positive(self.max_centers, "max_centers", integer=True, allow_none=True)
        n = X.shape[0]
        self.x_mean_, self.x_scale_ = standardisation(X)
        Z = (X - self.x_mean_) / self.x_scale_
        ols = ForwardOLS(gaussian_design(Z, Z, spread), y,
                         bias="fixed" if self.centred_ranking else "after")
        limit = n if self.max_centers is None else min(int(self.max_centers), n)
        history = [float(np.mean((y - y.mean()) ** 2))]
        while len(ols.selected) < limit and history[-1] > goal:
            if ols.step() is None:
                break
            r = ols.residual_with_bias()
            history.append(float(r @ r) / n)
        self.weights_, self.intercept_ = ols.coefficients()
        self.center_indices_ = np.asarray(ols.selected, dtype=int)
        self.centers_ = X[self.center_indices_].astype(float)
        self.n_centers_ = len(ols.selected)
        self.err_ratios_ = np.asarray(ols.err_ratios)
        self.mse_history_ = np.asarray(history)
        self.mse_ = history[-1]
        if goal > 0 and self.mse_ > goal:
            warnings.warn(f"RBFNetwork: training MSE {self.mse_:.3g} did not reach goal "
                          f"{goal:.3g} with {self.n_centers_} neurons (max_centers={limit}); "
                          "raise max_centers or change spread", ConvergenceWarning,
                          stacklevel=2)
        return self
