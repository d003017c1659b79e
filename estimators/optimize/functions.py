"""Standard test functions for the optimisers (vectorised: ``(m, d)`` positions -> ``m`` values).

Definitions, domains and optima as in Heidari et al. 2019, Table 1 (F1 sphere on [-100, 100]^d,
F5 Rosenbrock on [-30, 30]^d, F9 Rastrigin on [-5.12, 5.12]^d); all have minimum value 0. The
shifted sphere moves the optimum off the origin, to check that an optimiser is not merely drawn
to the centre of the box (HHO's exploration and besiege rules are known to favour the origin).
"""

from __future__ import annotations

import numpy as np


def sphere(P: np.ndarray) -> np.ndarray:
    """F1: sum x_i^2; minimum 0 at x = 0."""
    P = np.atleast_2d(P)
    return np.sum(P * P, axis=1)


def rastrigin(P: np.ndarray) -> np.ndarray:
    """F9: sum (x_i^2 - 10 cos(2 pi x_i) + 10); minimum 0 at x = 0."""
    P = np.atleast_2d(P)
    return np.sum(P * P - 10.0 * np.cos(2.0 * np.pi * P) + 10.0, axis=1)


def rosenbrock(P: np.ndarray) -> np.ndarray:
    """F5: sum_{i<d} 100 (x_{i+1} - x_i^2)^2 + (x_i - 1)^2; minimum 0 at x = 1."""
    P = np.atleast_2d(P)
    return np.sum(100.0 * (P[:, 1:] - P[:, :-1] ** 2) ** 2 + (P[:, :-1] - 1.0) ** 2, axis=1)


def shifted_sphere(shift: np.ndarray):
    """Sphere with its minimum 0 moved to ``shift``."""
    shift = np.asarray(shift, dtype=float)

    def f(P: np.ndarray) -> np.ndarray:
        return sphere(np.atleast_2d(P) - shift)
    return f


#: name -> (function, (low, high) per dimension, optimum position for dimension d)
DOMAINS = {
    "sphere": (sphere, (-100.0, 100.0), lambda d: np.zeros(d)),
    "rastrigin": (rastrigin, (-5.12, 5.12), lambda d: np.zeros(d)),
    "rosenbrock": (rosenbrock, (-30.0, 30.0), lambda d: np.ones(d)),
}
