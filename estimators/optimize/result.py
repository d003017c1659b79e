"""What every optimiser returns, and the bookkeeping they share (run settings, budget,
evaluation).

The optimisers in this package minimise a *vectorised* fitness: ``fun(P)`` takes a batch of
positions ``P`` of shape ``(m, d)`` and returns ``m`` fitness values (``vectorized=False`` wraps a
function of one position instead). Every call is counted; a budget ``max_evals`` caps the count
exactly (the last batch is truncated rather than overshooting), so two optimisers can be compared
at equal evaluation budgets. NaN fitness values are treated as +inf (worst), so a failed model
fit inside a fitness never becomes the optimum.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from rlgsim.estimators._validation import check_bounds, check_positive

Fitness = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class OptimizeResult:
    """Outcome of one optimiser run.

    Attributes
    ----------
    x : best position found, shape ``(d,)`` (in the units of the bounds).
    fun : fitness at ``x`` (the best value ever evaluated).
    nfev : number of fitness evaluations spent (one per position, batches count per row).
    nit : number of completed iterations (generations) after the initial population.
    best_curve : best-so-far fitness after the initial population and after each iteration,
        shape ``(nit + 1,)``; non-increasing.
    nfev_curve : cumulative ``nfev`` at the same points, shape ``(nit + 1,)``; plot
        ``best_curve`` against it to compare optimisers at equal budgets.
    message : why the run stopped.
    method : ``"hho"`` or ``"pso"``.
    counts : per-method diagnostics (for HHO: how often each update rule fired and how many
        rapid dives were kept).
    """

    x: np.ndarray
    fun: float
    nfev: int
    nit: int
    best_curve: np.ndarray
    nfev_curve: np.ndarray
    message: str
    method: str
    counts: dict[str, int] = field(default_factory=dict)


def check_run(bounds, n_agents, agents_name: str, max_iter, max_evals
              ) -> tuple[np.ndarray, np.ndarray, int, int | None, int | None]:
    """The checked settings of one run: ``(lower, upper, n_agents, max_iter, max_evals)``.

    Box bounds as in :func:`rlgsim.estimators._validation.check_bounds`, a population of at
    least 2 (``agents_name`` names it in the message), iterations and evaluation budget each an
    integer >= 1 or ``None``, not both ``None``; else ``ValueError``.
    """
    lower, upper = check_bounds(bounds)
    n = check_positive(n_agents, agents_name, integer=True, minimum=2)
    T = check_positive(max_iter, "max_iter", integer=True, allow_none=True)
    budget = check_positive(max_evals, "max_evals", integer=True, allow_none=True)
    if T is None and budget is None:
        raise ValueError("give max_iter, max_evals or both; with neither the run never ends")
    return lower, upper, n, T, budget


class Evaluator:
    """Counts evaluations, enforces the budget and remembers the best point ever evaluated."""

    def __init__(self, fun: Fitness, dim: int, max_evals: int | None, vectorized: bool = True):
        self.fun = fun
        self.dim = dim
        self.max_evals = max_evals
        self.vectorized = vectorized
        self.nfev = 0
        self.best_x: np.ndarray | None = None
        self.best_f = np.inf

    @property
    def remaining(self) -> int | float:
        return np.inf if self.max_evals is None else self.max_evals - self.nfev

    @property
    def exhausted(self) -> bool:
        return self.remaining <= 0

    def __call__(self, P: np.ndarray) -> np.ndarray:
        """Evaluate the rows of ``P`` that the budget allows (a prefix); return their fitness."""
        P = np.atleast_2d(P)
        k = int(min(P.shape[0], self.remaining))
        if k <= 0:
            return np.empty(0)
        P = P[:k]
        if self.vectorized:
            f = np.asarray(self.fun(P), dtype=float).reshape(-1)
        else:
            f = np.array([float(self.fun(p)) for p in P])
        if f.shape != (k,):
            raise ValueError(f"fitness returned {f.size} values for {k} positions; a vectorised "
                             "fitness must map an (m, d) array to m values")
        f = np.where(np.isnan(f), np.inf, f)
        self.nfev += k
        i = int(np.argmin(f))
        if f[i] < self.best_f or self.best_x is None:
            self.best_f = float(f[i])
            self.best_x = P[i].copy()
        return f
