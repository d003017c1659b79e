"""Residual sums of squares of many least-squares fits that share their first columns: the
linear subsets of a term selection (:mod:`rlgsim.estimators.identify.term_selection`'s best
subset, :mod:`rlgsim.estimators.identify.term_averaging`'s subset weights), all subsets of
one size at once.

Why: the best-subset search and the model averaging fit every well-conditioned subset of up to
six of a dozen candidates (some 1,000–2,500 fits of ~720 windows each, again for each
nonlinear term, outlier refit and mode-hop round) — one ``numpy.linalg.lstsq`` per Python call,
some 22,000 calls in a 20 h identification's law fit (~1.2 s).

How (Frisch–Waugh–Lovell: Frisch & Waugh, *Econometrica* 1, 1933; Lovell, *JASA* 58, 1963):
the residual of ``y`` on ``[B, L_S]`` is the residual of ``ỹ`` on ``L̃_S``, the tilde marking
what the shared columns ``B`` leave (one ``lstsq`` for ``y`` and every candidate column at
once). With the candidate columns scaled to unit length, a subset's sum of squares is
``ỹᵀỹ − gᵀG⁻¹g`` (``G = L̃_SᵀL̃_S``, ``g = L̃_Sᵀỹ``), the small systems of one size solved in
one stacked ``numpy.linalg.solve``. Its rounding grows with the condition number of ``G``
over the fraction of ``ỹᵀỹ`` left: the subsets come from the collinearity screen (every
variance inflation factor ≤ 100), and a subset whose ``G`` has a condition number above 1e6,
or a candidate that the shared columns explain (its ``L̃`` below 1e-8 of its length), is fitted
by ``lstsq`` itself. The sums agree with ``lstsq``'s to ~1e-12 relative
(tests/test_identify_maths.py), not bit for bit.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["subset_ssr", "added_column_ssr"]

#: largest condition number of a subset's Gram matrix solved here (beyond: lstsq)
MAX_COND = 1e6


def _lstsq_ssr(y: np.ndarray, X: np.ndarray) -> float:
    r = y - X @ np.linalg.lstsq(X, y, rcond=None)[0]
    return float(r @ r)


def subset_ssr(y: np.ndarray, base: np.ndarray, lcols: dict, combos: Sequence[Sequence[str]]
               ) -> np.ndarray:
    """Residual sum of squares of the least-squares fit of ``y`` (n,) on
    ``[base, lcols[c] for c in combo]`` for each combo (all of one size): (len(combos),)."""
    y = np.asarray(y, dtype=float)
    base = np.asarray(base, dtype=float).reshape(y.size, -1)
    out = np.empty(len(combos))
    if not combos:
        return out
    names = sorted({c for combo in combos for c in combo})
    L = (np.column_stack([np.asarray(lcols[c], dtype=float) for c in names]) if names
         else np.zeros((y.size, 0)))
    A = np.column_stack([y, L])
    At = A - base @ np.linalg.lstsq(base, A, rcond=None)[0]     # what the base leaves
    yt, Lt = At[:, 0], At[:, 1:]
    yy = float(yt @ yt)
    k = len(combos[0])
    if k == 0:
        out[:] = yy
        return out
    norm0 = np.linalg.norm(L, axis=0)
    norm = np.linalg.norm(Lt, axis=0)
    lost = norm <= 1e-8 * np.maximum(norm0, 1e-300)
    Ls = Lt / np.where(lost, 1.0, norm)
    G_all, g_all = Ls.T @ Ls, Ls.T @ yt
    pos = {c: i for i, c in enumerate(names)}
    idx = np.array([[pos[c] for c in combo] for combo in combos])
    G = G_all[idx[:, :, None], idx[:, None, :]]
    g = g_all[idx]
    cond = np.linalg.cond(G)
    ok = np.isfinite(cond) & (cond <= MAX_COND) & ~lost[idx].any(axis=1)
    if ok.any():
        sol = np.linalg.solve(G[ok], g[ok][:, :, None])[:, :, 0]
        out[ok] = yy - np.einsum("bj,bj->b", g[ok], sol)
    for b in np.flatnonzero(~ok):                      # ill-conditioned: lstsq itself
        out[b] = _lstsq_ssr(y, np.column_stack([base] + [lcols[c] for c in combos[b]]))
    return out


def added_column_ssr(y: np.ndarray, base: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Residual sum of squares of the least-squares fit of ``y`` (n,) on ``[base, C[:, j]]``
    for each column ``j`` of ``C`` (n, G) — a nonlinear term's grid of starts: with the base
    projected out (module docstring), ``ỹᵀỹ − (c̃ᵀỹ)²/(c̃ᵀc̃)``; a column the base explains
    (``c̃`` below 1e-6 of its length) by ``lstsq`` itself."""
    y = np.asarray(y, dtype=float)
    base = np.asarray(base, dtype=float).reshape(y.size, -1)
    C = np.asarray(C, dtype=float).reshape(y.size, -1)
    A = np.column_stack([y, C])
    At = A - base @ np.linalg.lstsq(base, A, rcond=None)[0]
    yt, Ct = At[:, 0], At[:, 1:]
    cc = np.einsum("ij,ij->j", Ct, Ct)
    weak = cc <= 1e-12 * np.einsum("ij,ij->j", C, C)
    out = np.empty(C.shape[1])
    ok = ~weak
    out[ok] = float(yt @ yt) - (Ct[:, ok].T @ yt) ** 2 / cc[ok]
    for j in np.flatnonzero(weak):
        out[j] = _lstsq_ssr(y, np.column_stack([base, C[:, j]]))
    return out
