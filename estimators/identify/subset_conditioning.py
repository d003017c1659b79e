"""The linear subsets of a term selection that pass the collinearity screen
(:func:`conditioned`: every variance inflation factor at most :data:`MAX_VIF`), all subsets of
one size at once.

Why: the best-subset search of :mod:`rlgsim.estimators.identify.term_selection` screens every
subset of up to six of a dozen candidates (some 2,500) again for each nonlinear term it adds,
one small matrix inverse per Python call. Here the subsets of one size are inverted in one
stacked ``numpy.linalg.inv`` (LAPACK's ``gesv`` on each matrix, as for one matrix alone) and
remembered for the correlation matrix they belong to; a singular subset makes the stacked call
fail, and then the stack is halved until it stands alone and is screened as before.
"""

from __future__ import annotations

import itertools
from typing import Sequence

import numpy as np

__all__ = ["MAX_VIF", "conditioned", "passing"]

#: largest variance inflation factor of a subset's terms (partial |r| ≈ 0.995): beyond it the
#: recording cannot tell the terms' coefficients apart and the subset is not considered
MAX_VIF = 100.0


def conditioned(R: dict, combo: Sequence[str]) -> bool:
    """All variance inflation factors of the subset ``combo`` at most :data:`MAX_VIF`."""
    if len(combo) < 2:
        return True
    idx = [R["names"].index(c) for c in combo]
    sub = R["R"][np.ix_(idx, idx)]
    try:
        vif = np.diag(np.linalg.inv(sub))
    except np.linalg.LinAlgError:
        return False
    return bool(np.all(np.isfinite(vif)) and np.all(vif <= MAX_VIF))


def _screen(R: dict, combos: list[tuple[str, ...]], idx: np.ndarray) -> list[bool]:
    """:func:`conditioned` of each subset (rows of ``idx``: their positions in ``R``), the
    stack inverted at once; a stack with a singular matrix (which fails as a whole) halved
    until the singular ones are alone and screened one by one."""
    if len(combos) == 1:
        return [conditioned(R, combos[0])]
    subs = R["R"][idx[:, :, None], idx[:, None, :]]
    try:
        vif = np.diagonal(np.linalg.inv(subs), axis1=1, axis2=2)
    except np.linalg.LinAlgError:
        h = len(combos) // 2
        return _screen(R, combos[:h], idx[:h]) + _screen(R, combos[h:], idx[h:])
    return list(np.all(np.isfinite(vif), axis=1) & np.all(vif <= MAX_VIF, axis=1))


def passing(R: dict, names: list[str], size: int) -> list[tuple[str, ...]]:
    """The subsets of ``size`` of ``names`` (in :func:`itertools.combinations` order) that
    :func:`conditioned` accepts for the correlation matrix ``R`` (a
    :func:`~rlgsim.estimators.identify.term_averaging.corr_matrix`, where the answer is kept)."""
    memo = R.setdefault("passing", {})
    key = (tuple(names), size)
    if key not in memo:
        combos = list(itertools.combinations(names, size))
        if size >= 2 and combos:
            pos = {n: i for i, n in enumerate(R["names"])}
            idx = np.array([[pos[c] for c in combo] for combo in combos])
            combos = [c for c, good in zip(combos, _screen(R, combos, idx)) if good]
        memo[key] = combos
    return memo[key]
