"""Harris hawks optimisation (HHO), exactly as Heidari et al. 2019, vectorised over the hawks.

Source: A. A. Heidari, S. Mirjalili, H. Faris, I. Aljarah, M. Mafarja, H. Chen, "Harris hawks
optimization: Algorithm and applications", Future Generation Computer Systems 97 (2019) 849-872
(equation numbers below are that paper's); used by paper 000 §3.2 (30 hawks, 500 iterations) to
tune the RVR kernel width.

Why hand-written: the common Python packages (niapy, mealpy, opytimizer, ...) differ from the
paper in details that matter here (the mean position taken as a scalar, one Lévy draw shared by
all dimensions, dives accepted without comparing fitness, no evaluation budget), and none is
vectorised over the population with a reproducible per-iteration draw order. Every update rule
is a pure function of (positions, rabbit, E, J, random draws) below, each unit-tested against
its formula.

One iteration (t = 0 .. T-1) with the population ``X`` (N x D), its fitness, the rabbit (best
position so far) and the mean position vector X_m = (1/N) sum_i X_i (eq. 2):

* escape energy per hawk: E = 2 E0 (1 - t/T), E0 ~ U(-1, 1) drawn per hawk per iteration (eq. 3);
* |E| >= 1, exploration (eq. 1), q ~ U(0, 1):
  q >= 0.5: X <- X_rand - r1 |X_rand - 2 r2 X|   (perch relative to a random hawk),
  q <  0.5: X <- (X_rabbit - X_m) - r3 (LB + r4 (UB - LB))   (perch on a random tall tree);
* |E| < 1, exploitation, r ~ U(0, 1) the prey's escape chance, J = 2 (1 - r5) its jump strength:
  r >= 0.5, |E| >= 0.5 soft besiege (eq. 4-5): X <- (X_rabbit - X) - E |J X_rabbit - X|;
  r >= 0.5, |E| <  0.5 hard besiege (eq. 6):   X <- X_rabbit - E |X_rabbit - X|;
  r <  0.5, |E| >= 0.5 soft besiege with progressive rapid dives (eq. 7-10):
      Y = X_rabbit - E |J X_rabbit - X|,  Z = Y + S * LF(D);
  r <  0.5, |E| <  0.5 hard besiege with progressive rapid dives (eq. 11-13):
      Y = X_rabbit - E |J X_rabbit - X_m|,  Z = Y + S * LF(D);
  a dive moves the hawk to Y if F(Y) < F(X), else to Z if F(Z) < F(X), else not at all
  (eq. 10); Z is evaluated only when Y is rejected, as in the authors' code;
* S ~ U(0, 1)^D and the Lévy flight LF(D) are drawn per dimension; LF by Mantegna's algorithm
  with beta = 1.5 (eq. 9): LF = 0.01 u sigma / |v|^(1/beta), u, v ~ N(0, 1),
  sigma = (Gamma(1+beta) sin(pi beta/2) / (Gamma((1+beta)/2) beta 2^((beta-1)/2)))^(1/beta).
  (The paper's text calls u, v "random values inside (0,1)"; the authors' code and Mantegna's
  algorithm draw them from the standard normal, which is what is done here.)

All random numbers (E0, q, r, r1..r5, the random hawk, S, u, v) are drawn for every hawk in
every iteration in a fixed order, so a run is reproducible from ``random_state`` whatever rules
fire. Hawks are updated synchronously from the population at the start of the iteration (the
paper's formulation; the authors' sequential loop lets X_m drift within an iteration). New
positions, Y and Z are clipped to the bounds before they are evaluated.

Budget: with ``max_iter`` alone the schedule is exactly the paper's t/T. With an evaluation
budget ``max_evals`` (for comparisons at equal budgets) the escape-energy schedule runs on the
fraction of the budget already spent, max(t/T, nfev/max_evals), so the exploitation phase is
reached whatever the number of dives; the run stops when the budget is exhausted (the last batch
is truncated, never exceeded).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from rlgsim.estimators.optimize.result import Evaluator, Fitness, OptimizeResult, check_run

LEVY_BETA = 1.5

# Phase codes returned by :func:`select_phase`.
EXPLORE_RANDOM_HAWK = 0   # |E| >= 1, q >= 0.5
EXPLORE_MEAN = 1          # |E| >= 1, q < 0.5
SOFT_BESIEGE = 2          # |E| < 1, r >= 0.5, |E| >= 0.5
HARD_BESIEGE = 3          # |E| < 1, r >= 0.5, |E| < 0.5
SOFT_DIVES = 4            # |E| < 1, r < 0.5, |E| >= 0.5
HARD_DIVES = 5            # |E| < 1, r < 0.5, |E| < 0.5
PHASE_NAMES = ("explore_random_hawk", "explore_mean", "soft_besiege", "hard_besiege",
               "soft_besiege_dives", "hard_besiege_dives")


# --------------------------------------------------------------------------- pure update rules
def escape_energy(E0: np.ndarray, progress: float) -> np.ndarray:
    """Escaping energy of the prey, E = 2 E0 (1 - t/T) (eq. 3), with ``progress`` = t/T."""
    return 2.0 * np.asarray(E0, dtype=float) * (1.0 - progress)


def jump_strength(r5: np.ndarray) -> np.ndarray:
    """Random jump strength of the prey, J = 2 (1 - r5), r5 ~ U(0, 1) (below eq. 5)."""
    return 2.0 * (1.0 - np.asarray(r5, dtype=float))


def select_phase(E: np.ndarray, q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Which rule each hawk uses (codes ``EXPLORE_RANDOM_HAWK`` .. ``HARD_DIVES``), from E, q, r."""
    aE = np.abs(E)
    phase = np.where(
        aE >= 1.0,
        np.where(q >= 0.5, EXPLORE_RANDOM_HAWK, EXPLORE_MEAN),
        np.where(r >= 0.5,
                 np.where(aE >= 0.5, SOFT_BESIEGE, HARD_BESIEGE),
                 np.where(aE >= 0.5, SOFT_DIVES, HARD_DIVES)))
    return phase.astype(np.int8)


def explore_random_hawk(X: np.ndarray, X_rand: np.ndarray, r1: np.ndarray,
                        r2: np.ndarray) -> np.ndarray:
    """Eq. 1, q >= 0.5: X(t+1) = X_rand - r1 |X_rand - 2 r2 X|  (r1, r2 one per hawk)."""
    r1 = np.asarray(r1, dtype=float)[:, None]
    r2 = np.asarray(r2, dtype=float)[:, None]
    return X_rand - r1 * np.abs(X_rand - 2.0 * r2 * X)


def explore_mean(rabbit: np.ndarray, X_mean: np.ndarray, r3: np.ndarray, r4: np.ndarray,
                 lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Eq. 1, q < 0.5: X(t+1) = (X_rabbit - X_m) - r3 (LB + r4 (UB - LB)); X_m is the mean
    position *vector* (eq. 2); r3, r4 one per hawk."""
    r3 = np.asarray(r3, dtype=float)[:, None]
    r4 = np.asarray(r4, dtype=float)[:, None]
    return (rabbit - X_mean)[None, :] - r3 * (lower + r4 * (upper - lower))


def soft_besiege(X: np.ndarray, rabbit: np.ndarray, E: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Eq. 4-5: X(t+1) = ΔX - E |J X_rabbit - X|, ΔX = X_rabbit - X."""
    E = np.asarray(E, dtype=float)[:, None]
    J = np.asarray(J, dtype=float)[:, None]
    return (rabbit - X) - E * np.abs(J * rabbit - X)


def hard_besiege(X: np.ndarray, rabbit: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Eq. 6: X(t+1) = X_rabbit - E |ΔX|, ΔX = X_rabbit - X."""
    E = np.asarray(E, dtype=float)[:, None]
    return rabbit - E * np.abs(rabbit - X)


def soft_dive_y(X: np.ndarray, rabbit: np.ndarray, E: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Eq. 7: first dive candidate of the soft besiege, Y = X_rabbit - E |J X_rabbit - X|."""
    E = np.asarray(E, dtype=float)[:, None]
    J = np.asarray(J, dtype=float)[:, None]
    return rabbit - E * np.abs(J * rabbit - X)


def hard_dive_y(X_mean: np.ndarray, rabbit: np.ndarray, E: np.ndarray,
                J: np.ndarray) -> np.ndarray:
    """Eq. 12: first dive candidate of the hard besiege, Y = X_rabbit - E |J X_rabbit - X_m|,
    with X_m the mean position vector (one row per hawk in ``E``/``J``)."""
    E = np.asarray(E, dtype=float)[:, None]
    J = np.asarray(J, dtype=float)[:, None]
    return rabbit - E * np.abs(J * rabbit - X_mean[None, :])


def dive_z(Y: np.ndarray, S: np.ndarray, levy: np.ndarray) -> np.ndarray:
    """Eq. 8 / 13: second dive candidate, Z = Y + S x LF(D) (element-wise, per dimension)."""
    return Y + S * levy


def levy_sigma(beta: float = LEVY_BETA) -> float:
    """Mantegna's sigma_u for index ``beta`` (eq. 9); 0.696574... for beta = 1.5."""
    num = math.gamma(1.0 + beta) * math.sin(math.pi * beta / 2.0)
    den = math.gamma((1.0 + beta) / 2.0) * beta * 2.0 ** ((beta - 1.0) / 2.0)
    return (num / den) ** (1.0 / beta)


def levy_flight(u: np.ndarray, v: np.ndarray, beta: float = LEVY_BETA) -> np.ndarray:
    """Eq. 9: LF = 0.01 u sigma / |v|^(1/beta) from standard-normal draws ``u``, ``v`` (one per
    dimension per hawk)."""
    return 0.01 * np.asarray(u) * levy_sigma(beta) / np.abs(np.asarray(v)) ** (1.0 / beta)


def accept_dive(f_x: np.ndarray, f_y: np.ndarray, f_z: np.ndarray) -> np.ndarray:
    """Eq. 10: 0 keep X, 1 move to Y (F(Y) < F(X)), 2 move to Z (F(Y) >= F(X) and F(Z) < F(X))."""
    f_x, f_y, f_z = (np.asarray(a, dtype=float) for a in (f_x, f_y, f_z))
    return np.where(f_y < f_x, 1, np.where(f_z < f_x, 2, 0)).astype(np.int8)


# --------------------------------------------------------------------------------- the driver
class _Draws(NamedTuple):
    """One iteration's random numbers, every one drawn for every hawk (n hawks, d dims)."""
    E0: np.ndarray          # (n,) U(-1, 1), eq. 3
    q: np.ndarray           # (n,) U(0, 1), exploration rule
    r: np.ndarray           # (n,) U(0, 1), the prey's escape chance
    r1: np.ndarray          # (n,) r1..r5 U(0, 1)
    r2: np.ndarray
    r3: np.ndarray
    r4: np.ndarray
    r5: np.ndarray
    rand_idx: np.ndarray    # (n,) the random hawk of eq. 1
    S: np.ndarray           # (n, d) U(0, 1), eq. 8
    u: np.ndarray           # (n, d) N(0, 1), Lévy numerator (eq. 9)
    v: np.ndarray           # (n, d) N(0, 1), Lévy denominator (eq. 9)


def _draw(rng: np.random.Generator, n: int, dim: int) -> _Draws:
    """All of one iteration's draws in the fixed order (E0, q, r, r1..r5, random hawk, S, u,
    v) that makes a run reproducible from its seed whatever rules then fire."""
    E0 = rng.uniform(-1.0, 1.0, n)
    q = rng.random(n)
    r = rng.random(n)
    r1, r2, r3, r4, r5 = rng.random((5, n))
    rand_idx = rng.integers(0, n, n)
    S = rng.random((n, dim))
    u = rng.standard_normal((n, dim))
    v = rng.standard_normal((n, dim))
    return _Draws(E0, q, r, r1, r2, r3, r4, r5, rand_idx, S, u, v)


def _propose(X: np.ndarray, rabbit: np.ndarray, d: _Draws, E: np.ndarray, J: np.ndarray,
             phase: np.ndarray, lower: np.ndarray,
             upper: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every hawk's new position by its rule (eqs. 1, 4-7, 12), the dives' second candidate Z
    (eqs. 8, 13), both clipped to the bounds, and the mask of the diving hawks."""
    X_mean = X.mean(axis=0)
    new = X.copy()
    m = phase == EXPLORE_RANDOM_HAWK
    new[m] = explore_random_hawk(X[m], X[d.rand_idx[m]], d.r1[m], d.r2[m])
    m = phase == EXPLORE_MEAN
    new[m] = explore_mean(rabbit, X_mean, d.r3[m], d.r4[m], lower, upper)
    m = phase == SOFT_BESIEGE
    new[m] = soft_besiege(X[m], rabbit, E[m], J[m])
    m = phase == HARD_BESIEGE
    new[m] = hard_besiege(X[m], rabbit, E[m])
    m = phase == SOFT_DIVES
    new[m] = soft_dive_y(X[m], rabbit, E[m], J[m])
    m = phase == HARD_DIVES
    new[m] = hard_dive_y(X_mean, rabbit, E[m], J[m])
    dive = (phase == SOFT_DIVES) | (phase == HARD_DIVES)
    Z = dive_z(new, d.S, levy_flight(d.u, d.v))        # used only for the diving hawks
    np.clip(new, lower, upper, out=new)
    np.clip(Z, lower, upper, out=Z)
    return new, Z, dive


def _move(evaluate: Evaluator, X: np.ndarray, fX: np.ndarray, new: np.ndarray, Z: np.ndarray,
          dive: np.ndarray, counts: dict[str, int]) -> None:
    """Evaluate and accept in place on ``X``/``fX``: one batch of the moved hawks' new positions
    and the dives' Y in hawk order (hawks beyond the budget stay), then Z where Y is rejected,
    and each dive's choice by eq. 10 (counted in ``counts``)."""
    f_new = evaluate(new)
    done = f_new.size                           # hawks beyond `done` ran out of budget
    idx = np.arange(done)
    direct = idx[~dive[:done]]
    X[direct], fX[direct] = new[direct], f_new[direct]
    divers = idx[dive[:done]]
    f_x, f_y = fX[divers], f_new[divers]
    f_z = np.full(divers.size, np.inf)          # Z is evaluated only where Y is rejected
    need_z = np.flatnonzero(f_y >= f_x)
    if need_z.size:
        got = evaluate(Z[divers[need_z]])
        f_z[need_z[:got.size]] = got
    decision = accept_dive(f_x, f_y, f_z)
    take_y, take_z = divers[decision == 1], divers[decision == 2]
    X[take_y], fX[take_y] = new[take_y], f_y[decision == 1]
    X[take_z], fX[take_z] = Z[take_z], f_z[decision == 2]
    counts["dives_kept_y"] += int(take_y.size)
    counts["dives_kept_z"] += int(take_z.size)


def harris_hawks(fun: Fitness, bounds, n_hawks: int = 30, max_iter: int | None = 500,
                 max_evals: int | None = None, random_state=None,
                 vectorized: bool = True) -> OptimizeResult:
    """Minimise ``fun`` over the box ``bounds`` with Harris hawks optimisation.

    Parameters
    ----------
    fun : fitness; with ``vectorized=True`` (default) ``fun(P)`` maps positions of shape
        ``(m, d)`` to ``m`` values, else ``fun(p)`` maps one position of shape ``(d,)`` to a float.
    bounds : sequence of ``(low, high)`` per dimension (LB, UB of eq. 1); positions are clipped
        into it.
    n_hawks : population size N (paper 000: 30).
    max_iter : number of iterations T (paper 000: 500); ``None`` for a budget-only run.
    max_evals : evaluation budget, or ``None``; at least one of ``max_iter``/``max_evals``.
    random_state : seed (int, ``None`` or ``numpy.random.Generator``).

    Returns
    -------
    OptimizeResult with the rabbit (best position), its fitness, evaluation count, the
    best-so-far curve and per-rule counts.
    """
    lower, upper, n, T, budget = check_run(bounds, n_hawks, "n_hawks", max_iter, max_evals)
    dim = lower.size
    rng = np.random.default_rng(random_state)
    evaluate = Evaluator(fun, dim, budget, vectorized)

    X = lower + rng.random((n, dim)) * (upper - lower)
    fX = evaluate(X)
    if fX.size < n:                                  # budget smaller than the population
        X, fX = X[:fX.size], fX
        n = fX.size
    curve, nfev_curve = [evaluate.best_f], [evaluate.nfev]
    counts = {name: 0 for name in PHASE_NAMES}
    counts.update(dives_kept_y=0, dives_kept_z=0)
    t = 0
    while (T is None or t < T) and not evaluate.exhausted:
        progress = 0.0
        if T is not None:
            progress = t / T
        if budget is not None:
            progress = max(progress, evaluate.nfev / budget)
        rabbit = evaluate.best_x
        d = _draw(rng, n, dim)
        E = escape_energy(d.E0, progress)
        J = jump_strength(d.r5)
        phase = select_phase(E, d.q, d.r)
        for code, name in enumerate(PHASE_NAMES):
            counts[name] += int(np.count_nonzero(phase == code))
        new, Z, dive = _propose(X, rabbit, d, E, J, phase, lower, upper)
        _move(evaluate, X, fX, new, Z, dive, counts)
        t += 1
        curve.append(evaluate.best_f)
        nfev_curve.append(evaluate.nfev)
    message = ("max_iter reached" if T is not None and t >= T
               else "evaluation budget exhausted")
    return OptimizeResult(x=evaluate.best_x.copy(), fun=float(evaluate.best_f),
                          nfev=evaluate.nfev, nit=t, best_curve=np.asarray(curve),
                          nfev_curve=np.asarray(nfev_curve, dtype=int), message=message,
                          method="hho", counts=counts)
