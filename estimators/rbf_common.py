"""Pieces shared by the two RBF networks: the Gaussian hidden layer, its forward pass and
orthogonal-least-squares (OLS) forward selection of centres.

Used by :mod:`rlgsim.estimators.rbf_network` (the traditional, MATLAB ``newrb``-style network) and
:mod:`rlgsim.estimators.rbf_modified` (the Kohonen + OLS network of paper 002).

Gaussian hidden layer
    ``phi_ij = exp(-ln 2 * ||x_i - c_j||**2 / spread**2)``: a neuron's output is 1 at its centre
    and 0.5 at distance ``spread`` (MATLAB ``radbas(dist(x, c) * b)`` with
    ``b = sqrt(-ln 0.5) / spread``, the ``newrb``/``newrbe`` convention). It is paper 002
    eq. (2), ``phi = exp(-||x - c||**2 / delta**2)``, with receptive field
    ``delta = spread / sqrt(ln 2)``. Distances are taken between *standardised* inputs (each
    column minus its training mean, divided by its training standard deviation), so ``spread`` is
    in units of standard deviations of the training inputs and inputs with different units
    (°C, K/s) count alike.

OLS forward selection
    Chen, Cowan & Grant (1991), "Orthogonal least squares learning algorithm for radial basis
    function networks", IEEE Trans. Neural Networks 2(2):302-309, eqs. (13)-(17) — paper 002
    eqs. (7)-(16). Candidates are the columns ``p_i`` of a hidden-layer design matrix; at step
    ``k`` every remaining candidate is made orthogonal to the regressors already chosen,
    ``w_k(i) = p_i - sum_j a_jk(i) w_j``, ``a_jk(i) = w_j' p_i / (w_j' w_j)`` (paper 002
    eq. 11), its coefficient is ``g_k(i) = w_k(i)' d / (w_k(i)' w_k(i))`` and its error-reduction
    ratio ``err_k(i) = g_k(i)**2 w_k(i)' w_k(i) / (d' d)`` (eqs. 12-13); the candidate with the
    largest ratio is chosen (eqs. 14-15) until ``1 - sum_k err_k < rho`` (eq. 16). The
    orthogonalisation is the *modified* Gram-Schmidt form (Chen, Billings & Luo 1989, Int. J.
    Control 50(5):1873-1896, §4): each remaining candidate and the target are deflated by every
    newly chosen ``w_k`` as soon as it is chosen, which is numerically safer than the classical
    form and costs the same. The weights follow from the unit upper-triangular system
    ``A theta = g`` (back substitution), and equal the least-squares solution on the chosen
    columns. A candidate whose orthogonalised energy has fallen below ``tol`` times its own
    energy (numerically dependent on the chosen ones) is no longer eligible (Chen et al. 1991
    §III).

    Output-layer bias. Three treatments, all through the same machinery:

    * ``bias="fixed"`` — the constant regressor is in the model before any centre is chosen
      (it is orthogonalised first, i.e. the target and candidates are centred). Error-reduction
      ratios are then fractions of the target's energy about its mean, ``sum((d - mean d)**2)``,
      so ``1 - sum err`` is the residual energy over that energy (= 1 - training R²). Used by
      the modified network: a gyro bias is a small variation on a large offset, and ``rho``
      must refer to the variation.
    * ``bias="after"`` — MATLAB ``newrb``: candidates are ranked against the raw target
      (``e = (P' d)**2 / (d' d * P' P)``, no bias), but the output layer has a bias; the
      constant column is carried along (orthogonalised against every chosen ``w_k``, never
      chosen) so the least-squares fit *with* bias and its error are available at every step.
      Ratios are fractions of ``d' d``.
    * ``bias=None`` — Chen et al. 1991 as printed: no bias, ratios are fractions of ``d' d``.

Why hand-written: scikit-learn's ``OrthogonalMatchingPursuit`` ranks atoms by their
correlation with the residual (unit-norm *original* columns), not by the error-reduction ratio
of the *orthogonalised* columns, and has no ``rho`` stopping rule or error-reduction ratios;
no maintained package ships Chen-Cowan-Grant OLS.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import solve_triangular
from scipy.linalg.blas import dger
from sklearn.utils.validation import check_is_fitted, validate_data

from rlgsim.estimators.kernels import gaussian, kernel_expansion, squared_distances

#: ``-ln 0.5``: a Gaussian neuron outputs 0.5 at distance ``spread`` from its centre (newrb).
LN2 = math.log(2.0)

_BIAS_MODES = ("fixed", "after", None)


def gaussian_design(Z: np.ndarray, centers: np.ndarray, spread: float) -> np.ndarray:
    """Hidden-layer outputs ``exp(-ln2 * ||z_i - c_j||**2 / spread**2)``, shape (n, m).

    ``Z`` (n, d) and ``centers`` (m, d) are in the same (standardised) coordinates; ``spread``
    is the distance at which a neuron's output is 0.5 (paper 002 eq. 2 with
    ``delta = spread / sqrt(ln 2)``; MATLAB ``radbas``).
    """
    Z = np.asarray(Z, dtype=float)
    centers = np.asarray(centers, dtype=float)
    if centers.shape[0] == 0:
        return np.empty((Z.shape[0], 0))
    return gaussian(squared_distances(Z, centers), LN2 / spread**2)


class ForwardOLS:
    """Orthogonal-least-squares forward selection of columns of ``P`` to fit ``d``.

    Call :meth:`step` repeatedly; each call chooses the eligible candidate with the largest
    error-reduction ratio and returns its column index (or ``None`` once no eligible candidate
    is left). See the module docstring for the equations and the ``bias`` modes.

    Parameters
    ----------
    P : (n, Q) array
        Candidate regressors (hidden-layer outputs for each candidate centre).
    d : (n,) array
        Target.
    bias : {"fixed", "after", None}
        Treatment of the output-layer bias (module docstring).
    tol : float
        A candidate is eligible only while its orthogonalised energy exceeds ``tol`` times its
        original energy.

    Attributes
    ----------
    selected : list of int
        Chosen column indices, in order of choice.
    err_ratios : list of float
        Error-reduction ratio of each chosen column (fraction of :attr:`target_energy`).
    target_energy : float
        ``d' d`` (``bias`` "after" or None) or ``sum((d - mean d)**2)`` (``bias="fixed"``).
    """

    def __init__(self, P: np.ndarray, d: np.ndarray, *, bias: str | None = "fixed",
                 tol: float = 1e-10) -> None:
        if bias not in _BIAS_MODES:
            raise ValueError(f"bias must be one of {_BIAS_MODES}, got {bias!r}")
        P = np.asarray(P, dtype=float)
        d = np.asarray(d, dtype=float)
        if P.ndim != 2 or d.ndim != 1 or P.shape[0] != d.shape[0]:
            raise ValueError(f"P must be (n, Q) and d (n,), got {P.shape} and {d.shape}")
        n, q = P.shape
        self.bias = bias
        self.tol = float(tol)
        self.n_candidates = q
        # Working copy, Fortran order so that the rank-one deflation runs in place (BLAS dger).
        # Column q is the constant regressor in "after" mode (carried, never chosen).
        extra = 1 if bias == "after" else 0
        self._W = np.empty((n, q + extra), order="F")
        self._W[:, :q] = P
        if extra:
            self._W[:, q] = 1.0
        self._energy0 = np.einsum("ij,ij->j", self._W, self._W)
        self._r = d.copy()
        self._eligible = self._energy0[:q] > 0.0
        # Basis in order: [ones if fixed] + chosen; each entry (a-row over all columns, g, w'w).
        self._a_rows: list[np.ndarray] = []
        self._g: list[float] = []
        self.selected: list[int] = []
        self.err_ratios: list[float] = []
        if bias == "fixed":
            mean_cols = self._W.mean(axis=0)
            self._a_rows.append(mean_cols)
            self._g.append(float(d.mean()))
            ones = np.ones(n)
            dger(-1.0, ones, mean_cols, a=self._W, overwrite_a=1)
            self._r -= d.mean()
        self._energy = self._current_energy()
        self._eligible &= self._energy[:q] > self.tol * self._energy0[:q]
        self.target_energy = float(self._r @ self._r)

    # -- state -----------------------------------------------------------------------------
    def _current_energy(self) -> np.ndarray:
        return np.einsum("ij,ij->j", self._W, self._W)

    @property
    def unexplained(self) -> float:
        """``1 - sum(err_ratios)``: paper 002 eq. (16) / Chen et al. 1991 eq. (17) left side."""
        if self.target_energy == 0.0:
            return 0.0
        return 1.0 - float(np.sum(self.err_ratios))

    def residual(self) -> np.ndarray:
        """Target minus its projection on the chosen columns (and the bias if ``"fixed"``)."""
        return self._r.copy()

    def residual_with_bias(self) -> np.ndarray:
        """Residual of the least-squares fit on the chosen columns *plus* a bias column."""
        if self.bias == "fixed":
            return self._r.copy()
        if self.bias is None:
            raise ValueError("residual_with_bias needs bias='fixed' or 'after'")
        u = self._W[:, -1]
        uu = float(u @ u)
        if uu <= self.tol * self._energy0[-1]:     # constant is (numerically) in the span
            return self._r.copy()
        return self._r - (float(u @ self._r) / uu) * u

    # -- one step --------------------------------------------------------------------------
    def step(self) -> int | None:
        """Choose the next column (largest error-reduction ratio); ``None`` if none is left."""
        q = self.n_candidates
        if not np.any(self._eligible):
            return None
        cand = self._W[:, :q]
        energy = self._energy[:q]
        num = (self._r @ cand) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(self._eligible, num / np.where(self._eligible, energy, 1.0), -np.inf)
        i = int(np.argmax(ratio))
        w = self._W[:, i].copy()
        ww = float(w @ w)
        g = float(w @ self._r) / ww
        err = g * g * ww / self.target_energy if self.target_energy > 0 else 0.0
        # Modified Gram-Schmidt: deflate every remaining column (and the target) by w now.
        a = (w @ self._W) / ww                      # paper 002 eq. (11), a_jk for all columns
        dger(-1.0, w, a, a=self._W, overwrite_a=1)
        self._r -= g * w
        self._a_rows.append(a)
        self._g.append(g)
        self.selected.append(i)
        self.err_ratios.append(err)
        self._eligible[i] = False
        self._energy = self._current_energy()
        self._eligible &= self._energy[:q] > self.tol * self._energy0[:q]
        return i

    # -- weights ---------------------------------------------------------------------------
    def coefficients(self) -> tuple[np.ndarray, float]:
        """Least-squares output weights of the chosen columns and the bias.

        Back substitution in ``A theta = g`` (Chen et al. 1991 eq. 15). The bias is 0 for
        ``bias=None``, and for ``"after"`` when the constant is numerically in the span of the
        chosen columns.
        """
        cols = list(self.selected)
        g = list(self._g)
        rows = list(self._a_rows)
        # Column index (into the working matrix) of each basis vector, in basis order.
        basis_cols: list[int | None] = ([None] if self.bias == "fixed" else []) + cols
        use_ones_last = False
        if self.bias == "after":
            u = self._W[:, -1]
            uu = float(u @ u)
            if uu > self.tol * self._energy0[-1]:
                use_ones_last = True
                g.append(float(u @ self._r) / uu)
                basis_cols.append(self.n_candidates)
        m = len(basis_cols)
        if m == 0:
            return np.empty(0), 0.0
        A = np.eye(m)
        for j in range(m):
            for k in range(j + 1, m):
                A[j, k] = rows[j][basis_cols[k]]
        theta = solve_triangular(A, np.asarray(g), unit_diagonal=True)
        if self.bias == "fixed":
            return theta[1:], float(theta[0])
        if use_ones_last:
            return theta[:-1], float(theta[-1])
        return theta, 0.0


class GaussianNetworkOutput:
    """The forward pass shared by both RBF networks: standardised inputs through the Gaussian
    hidden layer (``centers_``, ``spread``) and the linear output layer (``weights_``,
    ``intercept_``). Mixed into the estimators before ``RegressorMixin``."""

    def predict(self, X) -> np.ndarray:
        """Network output for inputs ``X`` (n, n_features), in the target's unit."""
        check_is_fitted(self)
        X = validate_data(self, X, reset=False, dtype=np.float64)
        Z = (X - self.x_mean_) / self.x_scale_
        C = (self.centers_ - self.x_mean_) / self.x_scale_
        spread = float(self.spread)
        return kernel_expansion(Z, C, self.weights_, self.intercept_,
                                lambda A, B: gaussian_design(A, B, spread))
