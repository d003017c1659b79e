"""Steps in a regression residual under correlated noise: where does a series jump by an amount
the law cannot explain? (The mode hops of a gyro bias, :mod:`rlgsim.lab.identify.hop_fit`.)

Model: ``y = Xβ + Σ_h δ_h·s_h + e`` with ``e ~ N(0, C)`` (``C`` the modelled covariance of the
window noise, e.g. :mod:`rlgsim.estimators.identify.window_noise`, flicker included) and the
step columns ``s_h[i] = 1`` for ``i ≥ j_h`` (0 before). Everything is whitened by the Cholesky
factor ``L`` of ``C`` (generalised least squares, as the law fit itself). For a candidate step
at ``j`` given the columns already in the model (``X`` and the steps found so far), with ``M``
the whitened residual-maker, the likelihood-ratio test of ``δ = 0`` is the square of

    z_j = s̃_jᵀ M ỹ / √(s̃_jᵀ M s̃_j)          (s̃ = L⁻¹s, ỹ = L⁻¹y)

which is N(0, 1) for each fixed ``j`` when the model holds; divided by √s² when the whitened
residual's variance per degree of freedom s² exceeds 1 (the model is then worse than its
noise), the same guard as the law's standard errors. It is not scaled up when s² < 1: a t
statistic with the scale estimated was tried and gave false steps in 2 of 30 hop-free
recordings (the noise fit at the gyro's sample rate puts too much of the 100 s window noise
into the white part, and rescaling the whole model then underweights the flicker, whose slow
wander looks like a step). The location is unknown, so the largest |z_j| over
the candidates is compared with a Bonferroni threshold ``Φ⁻¹(1 − α/(2·J))`` over the ``J``
candidate positions: the probability of one or more false steps in a record without any is at
most ``α`` (the statistics of neighbouring positions are strongly correlated, so the true level
is lower; Bonferroni is conservative, never liberal). Found steps are added one at a time
(forward selection on the largest |z|, each search given the steps before it — the binary
segmentation of a likelihood-ratio scan, Vostrikova 1981; Bai & Perron 1998 for steps in a
regression), then each found step is tested again given all the others and the weakest one
below the threshold removed, until all hold (backward check: two steps found for one hop in a
slow window collapse to one).

Why not a library: ``ruptures`` (in the package lists) segments a signal under independent
noise with a penalty or a number of breakpoints; here the steps sit on top of a regression law
and under flicker noise whose memory outlasts the record, so the test has to be the whitened
regression test above, with a false-alarm level that follows from the noise model. It is a few
lines of linear algebra; ruptures would add a dependency and still need this.

Units are the caller's (the target's units for sizes; indices into ``y``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from scipy.stats import norm

from rlgsim.estimators.identify.whitening import jittered_cholesky

__all__ = ["StepFit", "detect_steps", "bonferroni_threshold", "step_columns"]


@dataclass(frozen=True)
class StepFit:
    """Steps found: ``index`` (first element after each step, ascending), ``size`` and
    ``se`` (generalised least squares with the law's columns and every step), ``z`` each
    step's statistic given all the others, the ``threshold`` and level ``alpha`` used, the
    number of candidate positions, and ``scan`` the last |z| scan (max over positions)."""

    index: tuple[int, ...]
    size: tuple[float, ...]
    se: tuple[float, ...]
    z: tuple[float, ...]
    threshold: float
    alpha: float
    candidates: int
    scan_max_z: float


def bonferroni_threshold(alpha: float, candidates: int) -> float:
    """Two-sided Bonferroni threshold on |z| for ``candidates`` positions at family level
    ``alpha``."""
    return float(norm.isf(alpha / (2.0 * max(int(candidates), 1))))


def step_columns(n: int, positions: np.ndarray) -> np.ndarray:
    """(n, len(positions)) step columns: ``1`` at rows ``i ≥ j`` for each position ``j``."""
    i = np.arange(n)[:, None]
    return (i >= np.asarray(positions, dtype=int)[None, :]).astype(float)


def _scan(yw: np.ndarray, Xw: np.ndarray, Sw: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """z of every candidate column of ``Sw`` given ``Xw`` (whitened), the step sizes, their
    standard errors and s² (whitened residual variance per degree of freedom, at least 1)."""
    Q, _ = np.linalg.qr(Xw)
    r = yw - Q @ (Q.T @ yw)
    dof = max(yw.size - Xw.shape[1], 1)
    s2 = max(float(r @ r) / dof, 1.0)
    MS = Sw - Q @ (Q.T @ Sw)
    den = np.einsum("ij,ij->j", MS, MS)
    num = MS.T @ r
    with np.errstate(invalid="ignore", divide="ignore"):
        size = np.where(den > 1e-300, num / den, 0.0)
        se = np.where(den > 1e-300, np.sqrt(s2 / den), np.inf)
        z = np.where(den > 1e-300, num / np.sqrt(den * s2), 0.0)
    return z, size, se, s2


def detect_steps(y: np.ndarray, X: np.ndarray, cov: np.ndarray, *, alpha: float = 0.01,
                 min_segment: int = 2, max_steps: int = 30) -> StepFit:
    """Steps of ``y`` (n,) beyond the law columns ``X`` (n, p; the intercept included) under
    the noise covariance ``cov`` (n, n) at family false-alarm level ``alpha`` (module
    docstring). Candidate positions keep ``min_segment`` elements on each side."""
    y = np.asarray(y, dtype=float)
    X = np.asarray(X, dtype=float).reshape(y.size, -1)
    n = y.size
    positions = np.arange(min_segment, n - min_segment + 1)
    thr = bonferroni_threshold(alpha, positions.size)
    if positions.size == 0:
        return StepFit((), (), (), (), thr, alpha, 0, 0.0)
    L = jittered_cholesky(np.asarray(cov, dtype=float))
    yw = solve_triangular(L, y, lower=True)
    Xw = solve_triangular(L, X, lower=True)
    Sw = solve_triangular(L, step_columns(n, positions), lower=True)
    chosen: list[int] = []                       # columns of Sw (indices into positions)
    scan_max = 0.0
    while len(chosen) < max_steps:
        base = np.column_stack([Xw] + [Sw[:, c] for c in chosen])
        z, _, _, _ = _scan(yw, base, Sw)
        z[chosen] = 0.0
        j = int(np.argmax(np.abs(z)))
        scan_max = float(abs(z[j]))
        if scan_max < thr:
            break
        chosen.append(j)
    while chosen:                                # backward check: every step given the others
        zs = []
        for c in chosen:
            base = np.column_stack([Xw] + [Sw[:, o] for o in chosen if o != c])
            z, _, _, _ = _scan(yw, base, Sw[:, [c]])
            zs.append(abs(float(z[0])))
        k = int(np.argmin(zs))
        if zs[k] >= thr:
            break
        chosen.pop(k)
    chosen.sort()
    sizes, ses, zz = [], [], []
    for c in chosen:
        base = np.column_stack([Xw] + [Sw[:, o] for o in chosen if o != c])
        z, size, se, _ = _scan(yw, base, Sw[:, [c]])
        sizes.append(float(size[0]))
        ses.append(float(se[0]))
        zz.append(float(z[0]))
    return StepFit(index=tuple(int(positions[c]) for c in chosen), size=tuple(sizes),
                   se=tuple(ses), z=tuple(zz), threshold=thr, alpha=alpha,
                   candidates=int(positions.size), scan_max_z=scan_max)
