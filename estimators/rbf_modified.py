"""Modified RBF neural network of paper 002 (§3): Kohonen map + orthogonal least squares.

Model (paper 002 eq. 1-2), as in :mod:`rlgsim.estimators.rbf_network`::

    y(x) = b + sum_j w_j * exp(-ln 2 * ||z(x) - c_j||**2 / spread**2)

``z`` standardises each input column with the training mean and standard deviation (ddof=0);
``spread`` (in training standard deviations) is where a neuron's output is 0.5, i.e. paper 002's
receptive field ``delta = spread / sqrt(ln 2)``.

Design (paper 002 §3, Steps 2-4):

1. Step 2 — a Kohonen self-organising map (``minisom.MiniSom``; paper 002 eqs. 3-6: winner by
   smallest Euclidean distance, winner and neighbours moved towards the sample with a decaying
   learning rate) classifies the standardised inputs. Weights start at randomly drawn training
   inputs; samples are presented in random order; both draws come from ``random_state``.
2. Step 3 — the prototype of every node that wins at least one training input is a candidate
   centre (empty nodes represent no data and are dropped). Chen-Cowan-Grant orthogonal least
   squares (:class:`rlgsim.estimators.rbf_common.ForwardOLS`, modified Gram-Schmidt; paper 002
   eqs. 7-15) orders the candidates by error-reduction ratio and stops once
   ``1 - sum err < rho`` (eq. 16) or ``max_centers`` are chosen.
3. Step 4 — the output layer (weights and bias) is the least-squares solution on the chosen
   Gaussian columns (back substitution in the OLS triangular system).

The bias is in the model from the start (``bias="fixed"``), so the error-reduction ratios and
``rho`` refer to the target's energy about its mean: ``1 - sum err`` is the training residual
energy over ``sum((y - mean y)**2)``, i.e. 1 - R². (Chen et al. 1991 rank against ``y' y``;
for a gyro bias — a small variation on a large offset — that would let the offset dominate
``rho``.) Units: ``y``, ``b``, ``w_j`` in the target's unit; centres in the input units.

Against :class:`rlgsim.estimators.rbf_network.RBFNetwork` (paper 002's claim: the same error with
fewer centres and less time; ``benchmarks/estimators_rbf.py``, ``tests/test_rbf_network.py``):
on paper-002-like data it does reach the same training error with fewer centres, and the saving
comes from ranking with the bias in the model — ``RBFNetwork(centred_ranking=True)`` needs about
as many centres as this network. The Kohonen step's gain is the candidate count (about
``5 sqrt(n)`` prototypes instead of n training inputs), which makes the OLS cheaper for
thousands of samples; for a few hundred, training the map costs more than it saves.
"""

from __future__ import annotations

import math
import numbers
import warnings

import numpy as np
from minisom import MiniSom
from scipy.spatial.distance import cdist
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import ConvergenceWarning
from sklearn.utils import check_random_state

from rlgsim.estimators._validation import check_positive, standardisation, validate_fit_input
from rlgsim.estimators.rbf_common import ForwardOLS, GaussianNetworkOutput, gaussian_design


__all__ = ["ModifiedRBFNetwork"]

class ModifiedRBFNetwork(GaussianNetworkOutput, RegressorMixin, BaseEstimator):
    """Kohonen + OLS RBF network (paper 002's modified RBFNN).

    Parameters
    ----------
    spread : float, default 1.0
        Distance, in standardised input units, at which a neuron's output is 0.5.
    rho : float, default 0.01
        OLS stopping threshold in (0, 1): centres are added until ``1 - sum err < rho``
        (paper 002 eq. 16), i.e. until the training residual energy is below ``rho`` times the
        target's energy about its mean.
    som_shape : (int, int) or None, default None
        Kohonen map size; at most ``som_shape[0] * som_shape[1]`` candidate centres. None
        means a square map of about ``5 * sqrt(n_samples)`` nodes (side
        ``ceil(sqrt(5 * sqrt(n)))``; the rule of thumb of Vesanto et al., SOM Toolbox 2.0
        report A57, 2000, also quoted by ``MiniSom``): 9 x 9 for 288 samples (one 8 h paper-002
        environment at 100 s averages), 15 x 15 for 1728.
    som_sigma : float, default 1.0
        Initial neighbourhood radius of the map (in nodes; ``MiniSom`` ``sigma``).
    som_learning_rate : float, default 0.5
        Initial learning rate ``eta(0)`` (paper 002 eq. 6; ``MiniSom`` ``learning_rate``, decays
        asymptotically).
    som_iterations : int or None, default None
        Number of single-sample map updates; None means ``20 * n_nodes``.
    max_centers : int or None, default None
        Largest number of hidden neurons (paper 002's N); None means no limit beyond the
        number of candidates.
    random_state : int, RandomState instance or None, default None
        Seeds the map's initial weights and sample order; fixes the result.

    Attributes
    ----------
    centers_ : ndarray of shape (n_centers_, n_features_in_)
        Chosen centres in the input units, in OLS order.
    weights_ : ndarray of shape (n_centers_,)
        Output-layer weights (target unit).
    intercept_ : float
        Output-layer bias (target unit).
    n_centers_ : int
        Number of hidden neurons.
    err_ratios_ : ndarray of shape (n_centers_,)
        Error-reduction ratio of each chosen centre (fraction of ``sum((y - mean y)**2)``).
    unexplained_ : float
        ``1 - sum(err_ratios_)`` at the end (< ``rho`` when the threshold was reached).
    candidate_centers_ : ndarray of shape (n_candidates_, n_features_in_)
        Prototypes of the non-empty map nodes, in the input units.
    n_candidates_ : int
        Number of non-empty nodes.
    som_shape_ : (int, int)
        Map size used.
    node_counts_ : ndarray of shape som_shape_
        Training inputs won by each node.
    som_weights_ : ndarray of shape (*som_shape_, n_features_in_)
        Trained map prototypes (standardised units).
    mse_ : float
        Training mean squared error (target unit squared).
    x_mean_, x_scale_ : ndarray of shape (n_features_in_,)
        Standardisation of the inputs (training mean and standard deviation, ddof=0).
    n_features_in_ : int
        Number of inputs.
    """

    def __init__(self, spread: float = 1.0, rho: float = 0.01,
                 som_shape: tuple[int, int] | None = None, som_sigma: float = 1.0,
                 som_learning_rate: float = 0.5, som_iterations: int | None = None,
                 max_centers: int | None = None, random_state=None) -> None:
        self.spread = spread
        self.rho = rho
        self.som_shape = som_shape
        self.som_sigma = som_sigma
        self.som_learning_rate = som_learning_rate
        self.som_iterations = som_iterations
        self.max_centers = max_centers
        self.random_state = random_state

    def _check_params(self, n_samples: int) -> tuple[float, float, int, int, int]:
        spread = check_positive(self.spread, "spread")
        rho = check_positive(self.rho, "rho", upper=1.0)
        shape = self.som_shape
        if shape is None:
            side = math.ceil(math.sqrt(5.0 * math.sqrt(n_samples)))
            shape = (side, side)
        if (not isinstance(shape, (tuple, list)) or len(shape) != 2
                or not all(isinstance(s, numbers.Integral) and not isinstance(s, bool)
                           and s >= 1 for s in shape)):
            raise ValueError(f"som_shape must be None or two integers >= 1, got {shape!r}")
        check_positive(self.som_sigma, "som_sigma")
        check_positive(self.som_learning_rate, "som_learning_rate")
        n_nodes = int(shape[0]) * int(shape[1])
        iterations = self.som_iterations
        if iterations is None:
            iterations = 20 * n_nodes
        else:
            check_positive(iterations, "som_iterations", integer=True)
        check_positive(self.max_centers, "max_centers", integer=True, allow_none=True)
        return spread, rho, int(shape[0]), int(shape[1]), int(iterations)

    def fit(self, X, y):
        """Fit on inputs ``X`` (n, n_features) and target ``y`` (n,).

        Raises ``ValueError`` for NaN/inf, mismatched lengths, fewer than 2 samples, a
        constant input column, or invalid parameters.
        """
        X, y = validate_fit_input(self, X, y)
        spread, rho, nx, ny, iterations = self._check_params(X.shape[0])
        self.x_mean_, self.x_scale_ = standardisation(X)
        Z = (X - self.x_mean_) / self.x_scale_
        n_features = Z.shape[1]

        # Step 2: Kohonen classification of the standardised inputs.
        seed = int(check_random_state(self.random_state).randint(np.iinfo(np.int32).max))
        som = MiniSom(nx, ny, n_features, sigma=float(self.som_sigma),
                      learning_rate=float(self.som_learning_rate), random_seed=seed)
        som.random_weights_init(Z)
        som.train(Z, iterations, random_order=True)
        self.som_shape_ = (nx, ny)
        self.som_weights_ = som.get_weights().copy()
        prototypes = self.som_weights_.reshape(-1, n_features)
        winners = np.argmin(cdist(Z, prototypes, "sqeuclidean"), axis=1)
        counts = np.bincount(winners, minlength=prototypes.shape[0])
        self.node_counts_ = counts.reshape(nx, ny)
        candidates = prototypes[counts > 0]
        self.n_candidates_ = candidates.shape[0]
        self.candidate_centers_ = candidates * self.x_scale_ + self.x_mean_

        # Step 3: OLS selection among the candidates until 1 - sum(err) < rho.
        ols = ForwardOLS(gaussian_design(Z, candidates, spread), y, bias="fixed")
        limit = self.n_candidates_ if self.max_centers is None else min(
            int(self.max_centers), self.n_candidates_)
        while ols.unexplained >= rho and len(ols.selected) < limit:
            if ols.step() is None:
                break

        # Step 4: least-squares output layer on the chosen columns.
        self.weights_, self.intercept_ = ols.coefficients()
        chosen = np.asarray(ols.selected, dtype=int)
        self.centers_ = self.candidate_centers_[chosen].reshape(-1, n_features)
        self.n_centers_ = int(chosen.size)
        self.err_ratios_ = np.asarray(ols.err_ratios)
        self.unexplained_ = ols.unexplained
        r = ols.residual()
        self.mse_ = float(r @ r) / Z.shape[0]
        if self.unexplained_ >= rho:
            warnings.warn(f"ModifiedRBFNetwork: 1 - sum(err) = {self.unexplained_:.3g} did not "
                          f"fall below rho = {rho:.3g} with {self.n_centers_} of "
                          f"{self.n_candidates_} candidate centres; enlarge som_shape, change "
                          "spread or raise max_centers", ConvergenceWarning, stacklevel=2)
        return self
