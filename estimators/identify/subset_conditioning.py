"""The linear subsets of a term selection that pass the collinearity screen
(:func:`rlgsim.estimators.identify.term_averaging.conditioned`: every variance inflation
factor at most ``MAX_VIF``), all subsets of one size at once.

Why: the best-subset search of :mod:`rlgsim.estimators.identify.term_selection` screens every
subset of up to six of a dozen candidates (some 2,500) again for each nonlinear term it adds,
one small matrix inverse per Python call. Here the subsets of one size are inverted in one
stacked ``numpy.linalg.inv`` (LAPACK's ``gesv`` on each matrix, as for one matrix alone) and
remembered for the correlation matrix they belong to; a singular subset makes the stacked call
fail, and then each subset is screened on its own as before.
"""

from __future__ import annotations

import itertools

import numpy as np

from rlgsim.estimators.identify.term_averaging import MAX_VIF, conditioned

__all__ = ["passing"]


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
            subs = R["R"][idx[:, :, None], idx[:, None, :]]
            try:
                vif = np.diagonal(np.linalg.inv(subs), axis1=1, axis2=2)
                ok = np.all(np.isfinite(vif), axis=1) & np.all(vif <= MAX_VIF, axis=1)
                combos = [c for c, good in zip(combos, ok) if good]
            except np.linalg.LinAlgError:
                combos = [c for c in combos if conditioned(R, c)]
        memo[key] = combos
    return memo[key]
