"""Particle swarm optimisation (global best) with linearly decreasing inertia, vectorised.

Sources: Kennedy & Eberhart 1995 (the swarm); Shi & Eberhart 1998, "A modified particle swarm
optimizer" (inertia weight) and 1999, "Empirical study of particle swarm optimization" (inertia
decreasing linearly from 0.9 to 0.4, c1 = c2 = 2); paper 003 §3.2 eq. 8-10 (the velocity clamp
|v| <= v_max and the inertia schedule used to tune the SVM).

Update of particle i, dimension d, iteration t = 0 .. T-1 (paper 003 eq. 8-9):

    v <- w(t) v + c1 r1 (p_i - x) + c2 r2 (g - x),   r1, r2 ~ U(0, 1) per particle and dimension
    v <- clip(v, -v_max, v_max),                      v_max = vmax_fraction (UB - LB) per dimension
    x <- x + v
    w(t) = w_start - (w_start - w_end) t / (T - 1)    (0.9 on the first, 0.4 on the last iteration)

Boundary rule (no wrap-around): a component that leaves the box is clipped to the violated bound
and its velocity is set to zero (``boundary="absorb"``, the default) or reversed
(``boundary="reflect"``), so the particle is never teleported to the other side.

Personal bests p_i move only on strict improvement; the global best g is the best position ever
evaluated. Initial positions are uniform in the box and initial velocities uniform in
[-v_max, v_max] (paper 003 step 3.1: "randomly initialize the initial velocity and position of
the particle in the limited range").

Why hand-written: scikit-learn and SciPy have no PSO; the PSO packages (pyswarms, niapy, ...)
either wrap particles around, reflect positions, or lack an exact evaluation budget and a
vectorised, reproducible draw order, and adding one for ~60 lines is not worth the dependency.

Budget: with ``max_evals`` the number of iterations is T = min(max_iter, ceil((max_evals - N)/N))
and the inertia schedule runs over that T; the last iteration is truncated to the budget.
"""

from __future__ import annotations

import math

import numpy as np

from rlgsim.estimators.optimize.result import Evaluator, Fitness, OptimizeResult, check_run

BOUNDARY_RULES = ("absorb", "reflect")


def inertia_weight(t: int, T: int, w_start: float = 0.9, w_end: float = 0.4) -> float:
    """Linearly decreasing inertia (Shi & Eberhart 1998; paper 003 eq. 10): w_start at t = 0,
    w_end at t = T - 1."""
    if T <= 1:
        return float(w_start)
    return float(w_start - (w_start - w_end) * t / (T - 1))


def velocity_update(V: np.ndarray, X: np.ndarray, P: np.ndarray, g: np.ndarray, w: float,
                    c1: float, c2: float, r1: np.ndarray, r2: np.ndarray,
                    vmax: np.ndarray) -> np.ndarray:
    """Paper 003 eq. 8-9 with the clamp: clip(w V + c1 r1 (P - X) + c2 r2 (g - X), -vmax, vmax)."""
    V = w * V + c1 * r1 * (P - X) + c2 * r2 * (g[None, :] - X)
    return np.clip(V, -vmax, vmax)


def apply_boundary(X: np.ndarray, V: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                   rule: str = "absorb") -> tuple[np.ndarray, np.ndarray]:
    """Clip positions into the box; zero (``absorb``) or reverse (``reflect``) the velocity
    components that hit a bound. Never wraps around."""
    out = (X < lower) | (X > upper)
    X = np.clip(X, lower, upper)
    V = V.copy()
    if rule == "absorb":
        V[out] = 0.0
    else:
        V[out] = -V[out]
    return X, V


def particle_swarm(fun: Fitness, bounds, n_particles: int = 30, max_iter: int | None = 100,
                   max_evals: int | None = None, w_start: float = 0.9, w_end: float = 0.4,
                   c1: float = 2.0, c2: float = 2.0, vmax_fraction: float = 0.2,
                   boundary: str = "absorb", random_state=None,
                   vectorized: bool = True) -> OptimizeResult:
    """Minimise ``fun`` over the box ``bounds`` with inertia-weight particle swarm optimisation.

    Parameters
    ----------
    fun : fitness; with ``vectorized=True`` (default) ``fun(P)`` maps ``(m, d)`` positions to
        ``m`` values, else ``fun(p)`` maps one position ``(d,)`` to a float.
    bounds : sequence of ``(low, high)`` per dimension.
    n_particles : swarm size N.
    max_iter : iterations T after the initial swarm; ``None`` for a budget-only run.
    max_evals : evaluation budget or ``None`` (at least one of ``max_iter``/``max_evals``).
    w_start, w_end : inertia at the first and last iteration (0.9 -> 0.4).
    c1, c2 : cognitive and social acceleration coefficients (2, 2 — Shi & Eberhart 1999).
    vmax_fraction : velocity clamp as a fraction of each dimension's range (UB - LB).
    boundary : ``"absorb"`` (clip, zero the velocity component) or ``"reflect"`` (clip, reverse
        it).
    random_state : seed (int, ``None`` or ``numpy.random.Generator``).
    """
    lower, upper, n, T, budget = check_run(bounds, n_particles, "n_particles", max_iter, max_evals)
    dim = lower.size
    if boundary not in BOUNDARY_RULES:
        raise ValueError(f"boundary must be one of {BOUNDARY_RULES}, got {boundary!r}")
    for name, val in (("w_start", w_start), ("w_end", w_end), ("c1", c1), ("c2", c2)):
        if not (np.isfinite(val) and val >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {val!r}")
    if not (np.isfinite(vmax_fraction) and 0 < vmax_fraction <= 1):
        raise ValueError(f"vmax_fraction must be in (0, 1], got {vmax_fraction!r}")
    if budget is not None:
        t_budget = max(0, math.ceil((budget - n) / n))
        T = t_budget if T is None else min(T, t_budget)

    rng = np.random.default_rng(random_state)
    evaluate = Evaluator(fun, dim, budget, vectorized)
    vmax = vmax_fraction * (upper - lower)
    X = lower + rng.random((n, dim)) * (upper - lower)
    V = rng.uniform(-1.0, 1.0, (n, dim)) * vmax
    f = evaluate(X)
    if f.size < n:
        X, V, n = X[:f.size], V[:f.size], f.size
    P, fP = X.copy(), f.copy()
    curve, nfev_curve = [evaluate.best_f], [evaluate.nfev]
    t = 0
    while t < T and not evaluate.exhausted:
        r1 = rng.random((n, dim))
        r2 = rng.random((n, dim))
        w = inertia_weight(t, T, w_start, w_end)
        V = velocity_update(V, X, P, evaluate.best_x, w, c1, c2, r1, r2, vmax)
        X, V = apply_boundary(X + V, V, lower, upper, boundary)
        f = evaluate(X)
        k = f.size
        better = f < fP[:k]
        idx = np.flatnonzero(better)
        P[idx], fP[idx] = X[idx], f[idx]
        t += 1
        curve.append(evaluate.best_f)
        nfev_curve.append(evaluate.nfev)
    message = ("evaluation budget exhausted" if budget is not None and evaluate.exhausted
               else "max_iter reached")
    return OptimizeResult(x=evaluate.best_x.copy(), fun=float(evaluate.best_f),
                          nfev=evaluate.nfev, nit=t, best_curve=np.asarray(curve),
                          nfev_curve=np.asarray(nfev_curve, dtype=int), message=message,
                          method="pso")
