"""Compiled step loop of the calibration filter (:func:`rlgsim.estimators.kalman_calibration.
run_filter`; numba).

The equations are filterpy's ``KalmanFilter.predict`` and ``update`` in Joseph form, written
for the filter's structure exactly as ``run_filter`` documents it: the state is in the internal
order (the ``nd`` rows of F that are not identity rows first), so the predict is

    P ← F P Fᵀ + Q = [[F_d P Fᵀ_d, F_d P_{d,r}], [P_{r,d} F_dᵀ ...]]

with F_d the first ``nd`` rows, and H = [0 I 0] selects the internal rows 3:6, so the update is
rank-3 algebra. What the loop adds to numpy's version: no per-step interpreter overhead (~20
array calls per step, 2 400 steps per 40-min window), the zero columns of F_d skipped (of the
51-state filter's 24 moving rows, 18 are the bias-wander rows with one to three non-zeros), and
the symmetry of P used for the column half of F P Fᵀ (P_{r,d} Fᵀ_d is the transpose of the rows
just computed). Because that relies on P being symmetric, P is symmetrised after every update
(the average with its transpose: it removes only the rounding skew of the Joseph form, which
otherwise grows through the column half at the turns where P's condition number reaches 1e11).
The sums run in another order than BLAS, so results equal numpy's to rounding
(tests/test_calibration.py pins the estimates to those of filterpy's dense version).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _predict_state(f_dyn, k, nz_idx, nz_cnt, x, xt):  # pragma: no cover - compiled
    """x ← F_k x in place: the ``nd`` moving rows of F over their non-zero columns (``xt``, nd,
    is scratch); the identity rows leave their states as they are."""
    nd = f_dyn.shape[1]
    for r in range(nd):
        acc = 0.0
        for ii in range(nz_cnt[r]):
            c = nz_idx[r, ii]
            acc += f_dyn[k, r, c] * x[c]
        xt[r] = acc
    for r in range(nd):
        x[r] = xt[r]


@njit(cache=True, nogil=True, inline="always")
def _predict_covariance(f_dyn: np.ndarray, k: int, nz_idx: np.ndarray, nz_cnt: np.ndarray,
                        P: np.ndarray, T: np.ndarray) -> None:  # pragma: no cover - compiled
    """P ← F_k P F_kᵀ in place (no Q yet): T = F_d P over the moving rows' non-zero columns
    (``T`` (nd, n_x) is scratch), the (d, d) block T F_dᵀ computed once per symmetric pair, the
    (d, rest) blocks copied from T; the identity rows' (rest, rest) block is unchanged."""
    nd = f_dyn.shape[1]
    n_x = f_dyn.shape[2]
    for r in range(nd):                       # T = F_d P (the moving rows)
        for m in range(n_x):
            T[r, m] = 0.0
        for ii in range(nz_cnt[r]):
            c = nz_idx[r, ii]
            a = f_dyn[k, r, c]
            for m in range(n_x):
                T[r, m] += a * P[c, m]
    for r in range(nd):                       # block (d, d): T F_dᵀ, symmetric
        for i in range(r + 1):
            acc = 0.0
            for ii in range(nz_cnt[r]):
                c = nz_idx[r, ii]
                acc += T[i, c] * f_dyn[k, r, c]
            P[i, r] = acc
            P[r, i] = acc
    for i in range(nd):                       # blocks (d, rest) and (rest, d)
        for m in range(nd, n_x):
            P[i, m] = T[i, m]
            P[m, i] = T[i, m]


@njit(cache=True, nogil=True, inline="always")
def _add_process_noise(qs: np.ndarray, k: int, q_dd: np.ndarray, Q: np.ndarray, full_q: bool,
                       P: np.ndarray) -> None:  # pragma: no cover - compiled
    """P += Q_k: the step's (6, 6) navigation noise ``qs[k]`` placed into ``q_dd`` (nd, nd)
    and added over the moving block, or with ``full_q`` into ``Q`` (n_x, n_x), added whole."""
    for a in range(6):
        for b in range(6):
            q_dd[a, b] = qs[k, a, b]
    if full_q:
        for a in range(6):
            for b in range(6):
                Q[a, b] = qs[k, a, b]
        for i in range(P.shape[0]):
            for m in range(P.shape[0]):
                P[i, m] += Q[i, m]
    else:
        for i in range(q_dd.shape[0]):
            for m in range(q_dd.shape[0]):
                P[i, m] += q_dd[i, m]


@njit(cache=True, nogil=True, inline="always")
def _innovation_inverse(P: np.ndarray, r2: float,
                        si: np.ndarray) -> None:  # pragma: no cover - compiled
    """S⁻¹ into ``si`` (3, 3) for S = H P Hᵀ + r2 I = P[3:6, 3:6] + r2 I (the adjugate over
    the determinant, expanded along the first column)."""
    s00 = P[3, 3] + r2
    s11 = P[4, 4] + r2
    s22 = P[5, 5] + r2
    s01, s02, s12 = P[3, 4], P[3, 5], P[4, 5]
    s10, s20, s21 = P[4, 3], P[5, 3], P[5, 4]
    c00 = s11 * s22 - s12 * s21
    c01 = s02 * s21 - s01 * s22
    c02 = s01 * s12 - s02 * s11
    det = s00 * c00 + s10 * c01 + s20 * c02
    si[0, 0] = c00 / det
    si[0, 1] = c01 / det
    si[0, 2] = c02 / det
    si[1, 0] = (s12 * s20 - s10 * s22) / det
    si[1, 1] = (s00 * s22 - s02 * s20) / det
    si[1, 2] = (s02 * s10 - s00 * s12) / det
    si[2, 0] = (s10 * s21 - s11 * s20) / det
    si[2, 1] = (s01 * s20 - s00 * s21) / det
    si[2, 2] = (s00 * s11 - s01 * s10) / det


@njit(cache=True, nogil=True, inline="always")
def _joseph_update(P: np.ndarray, K: np.ndarray, r2: float, prow: np.ndarray,
                   B: np.ndarray) -> None:  # pragma: no cover - compiled
    """P ← (I − K H) P (I − K H)ᵀ + K R Kᵀ in place, R = r2 I and H = [0 I 0] (rows 3:6), as
    A = P − K H P, B = r2 K − A Hᵀ, P = A + B Kᵀ (``prow`` (3, n_x), ``B`` (n_x, 3) scratch);
    then P symmetrised (the average with its transpose drops the Joseph form's rounding skew)."""
    n_x = P.shape[0]
    for a in range(3):
        for m in range(n_x):
            prow[a, m] = P[3 + a, m]
    for i in range(n_x):                      # A = P − K H P  (in place)
        k0, k1, k2 = K[i, 0], K[i, 1], K[i, 2]
        for m in range(n_x):
            P[i, m] -= k0 * prow[0, m] + k1 * prow[1, m] + k2 * prow[2, m]
    for i in range(n_x):                      # B = r2 K − A Hᵀ
        for b in range(3):
            B[i, b] = r2 * K[i, b] - P[i, 3 + b]
    for i in range(n_x):                      # P = A + B Kᵀ
        b0, b1, b2 = B[i, 0], B[i, 1], B[i, 2]
        for m in range(n_x):
            P[i, m] += b0 * K[m, 0] + b1 * K[m, 1] + b2 * K[m, 2]
    for i in range(n_x):                      # P is symmetric: drop the rounding skew
        for m in range(i):
            a = 0.5 * (P[i, m] + P[m, i])
            P[i, m] = a
            P[m, i] = a


@njit(cache=True, nogil=True)
def filter_loop(f_dyn, nz_idx, nz_cnt, qs, q_dd, Q, full_q, mask, z_all, r2, P, x, gains,
                s_inv, nis):  # pragma: no cover - compiled; tested through run_filter
    """Run the predict/update steps in place on ``P`` (n_x, n_x) and ``x`` (n_x,), internal
    order. ``f_dyn`` (K, nd, n_x) moving rows of F per step; ``nz_idx``/``nz_cnt`` their
    non-zero columns; ``qs`` (K, 6, 6) navigation process noise per step placed into ``q_dd``
    (nd, nd) (or, with ``full_q``, into ``Q`` (n_x, n_x), added whole); ``mask`` (K,) a
    measurement at the step end; ``z_all`` (K, 3) measured velocity [mm/s]; ``r2`` its
    variance. Fills ``gains`` (M, n_x, 3), ``s_inv`` (M, 3, 3), ``nis`` (M,)."""
    n_steps, nd, n_x = f_dyn.shape
    T = np.empty((nd, n_x))
    xt = np.empty(nd)
    K = np.empty((n_x, 3))
    prow = np.empty((3, n_x))
    B = np.empty((n_x, 3))
    si = np.empty((3, 3))
    j = 0
    for k in range(n_steps):
        # ---- predict: x ← F x; P ← F P Fᵀ + Q
        _predict_state(f_dyn, k, nz_idx, nz_cnt, x, xt)
        _predict_covariance(f_dyn, k, nz_idx, nz_cnt, P, T)
        _add_process_noise(qs, k, q_dd, Q, full_q, P)
        if not mask[k]:
            continue
        # ---- update with H = [0 I 0] (internal rows 3:6), Joseph form
        _innovation_inverse(P, r2, si)
        for i in range(n_x):                      # K = P Hᵀ S⁻¹
            for b in range(3):
                K[i, b] = P[i, 3] * si[0, b] + P[i, 4] * si[1, b] + P[i, 5] * si[2, b]
        y0 = z_all[k, 0] - x[3]
        y1 = z_all[k, 1] - x[4]
        y2 = z_all[k, 2] - x[5]
        for i in range(n_x):
            x[i] += K[i, 0] * y0 + K[i, 1] * y1 + K[i, 2] * y2
        _joseph_update(P, K, r2, prow, B)
        for i in range(n_x):
            for b in range(3):
                gains[j, i, b] = K[i, b]
        for a in range(3):
            for b in range(3):
                s_inv[j, a, b] = si[a, b]
        nis[j] = (y0 * (si[0, 0] * y0 + si[0, 1] * y1 + si[0, 2] * y2)
                  + y1 * (si[1, 0] * y0 + si[1, 1] * y1 + si[1, 2] * y2)
                  + y2 * (si[2, 0] * y0 + si[2, 1] * y1 + si[2, 2] * y2))
        j += 1
    return j


@njit(cache=True, nogil=True)
def rerun_loop(f_dyn, nz_idx, nz_cnt, gains, mask, z_all, x, ys):  # pragma: no cover
    """The fixed-gain pass of :func:`~rlgsim.estimators.kalman_calibration.rerun_filter`:
    x_k = F_k x_{k−1} + K_k (z_k − H F_k x_{k−1}) in place on ``x`` (internal order); the
    innovations go to ``ys`` (M, 3). Returns the number of measurements used."""
    n_steps, nd, n_x = f_dyn.shape
    xt = np.empty(nd)
    j = 0
    for k in range(n_steps):
        _predict_state(f_dyn, k, nz_idx, nz_cnt, x, xt)
        if mask[k]:
            y0 = z_all[k, 0] - x[3]
            y1 = z_all[k, 1] - x[4]
            y2 = z_all[k, 2] - x[5]
            for i in range(n_x):
                x[i] += gains[j, i, 0] * y0 + gains[j, i, 1] * y1 + gains[j, i, 2] * y2
            ys[j, 0] = y0
            ys[j, 1] = y1
            ys[j, 2] = y2
            j += 1
    return j


@njit(cache=True, nogil=True)
def input_transition(e_j, c, dtheta, dv, per_sub, h, gyro_mis, accel_mis):  # pragma: no cover
    """Φ_ξp (K, 6, 24) = Σ_j expm(M (T − τ_j)) ∫_j B dt of
    :func:`~rlgsim.estimators.kalman_calibration._transition_pieces`, with the sub-step sums of
    the increments (Σ Δθ, Σ Δv⁺, Σ Δv⁻) taken here: ``e_j`` (m, 6, 6) the exponentials,
    ``c`` (K·m, 3, 3) the attitude C_b^n at each sub-step middle, ``dtheta``/``dv`` (≥ K·m·
    per_sub, 3) the increments, ``h`` the sub-step [s], ``gyro_mis``/``accel_mis`` (6, 2)/(3, 2)
    the misalignment states' (row, column) of E_g and E_a. ∫_j B dt per sub-step (6, 24):
    φ rows −C [h I | diag ΣΔθ | Γ-map(ΣΔθ)], δv rows C [h I | diag ΣΔv⁺ | diag ΣΔv⁻ |
    L-map(ΣΔv)]."""
    m = e_j.shape[0]
    n_sub = c.shape[0]
    n_steps = n_sub // m
    out = np.zeros((n_steps, 6, 24))
    b = np.zeros((6, 24))
    th = np.empty(3)
    vp = np.empty(3)
    vn = np.empty(3)
    for s in range(n_sub):
        for a in range(3):
            th[a] = 0.0
            vp[a] = 0.0
            vn[a] = 0.0
        for q in range(s * per_sub, (s + 1) * per_sub):
            for a in range(3):
                th[a] += dtheta[q, a]
                u = dv[q, a]
                if u > 0.0:
                    vp[a] += u
                else:
                    vn[a] += u
        for r in range(3):
            for a in range(3):
                b[r, a] = -c[s, r, a] * h
                b[r, 3 + a] = -c[s, r, a] * th[a]
                b[3 + r, 12 + a] = c[s, r, a] * h
                b[3 + r, 15 + a] = c[s, r, a] * vp[a]
                b[3 + r, 18 + a] = c[s, r, a] * vn[a]
            for col in range(gyro_mis.shape[0]):
                b[r, 6 + col] = -c[s, r, gyro_mis[col, 0]] * th[gyro_mis[col, 1]]
            for col in range(accel_mis.shape[0]):
                j = accel_mis[col, 1]
                b[3 + r, 21 + col] = c[s, r, accel_mis[col, 0]] * (vp[j] + vn[j])
        k = s // m
        jj = s - k * m
        for r in range(6):
            for q in range(6):
                e = e_j[jj, r, q]
                if e == 0.0:
                    continue
                for col in range(24):
                    out[k, r, col] += e * b[q, col]
    return out
