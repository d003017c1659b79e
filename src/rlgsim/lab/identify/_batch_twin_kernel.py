"""Compiled step loop of several parameter sets of one heater network (numba, ``nogil``): the
recurrence of :func:`rlgsim.lab.identify.batch_twin.twin_readings_batch` (the thermal fit's
finite-difference Jacobian) over every step and every set in one call.

Why compiled code: a heater's PI controller reads its sensor at each grid point and its power
feeds the next step, so the recurrence cannot be vectorised over the steps; the NumPy loop
(:func:`rlgsim.lab.identify.batch_twin._loop_numpy`, kept as the reference) pays ~10 ufunc
calls of interpreter overhead per step whatever the number of sets — for the 20 h
identification of ``benchmarks/bench_identify.py`` 7,218 steps × some 200 Jacobians — while the
arithmetic is a few hundred flops per step and set.

The same operations as the NumPy loop per set ``b``, step ``k`` and mode ``i`` (without
``fastmath``)::

    powered steps: ts_j = Σ_i rs_ji·w_i;  sp_j = sp0_j + tg_j·(Σ_i rt_ji·w_i)   (state before the step)
    g_ik = Σ_t c_ti·x_tk (setpoint, its step, power, boundaries: summed in that order)
    w_i ← μ_i·w_i + g_ik
    powered: e = sp_j − ts_j;  v = kp_j·e + I_j;  P_j = min(max(v, 0), Pmax_j);
             I_j = (I_j + ki_j·e) + aw_j·(P_j − v);  w_i ← w_i + Σ_j c_ij·P_j
    unpowered: I_j = 0

The sums over ``i`` and ``j`` are in index order here; the NumPy loop's block-diagonal BLAS
products sum the same non-zero terms in the library's order, so the two agree to rounding
(tests/test_identify_maths.py: ~1e-12 relative), not bit for bit. Each set is stepped on its
own, so a set's result does not depend on the others in the batch.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def batch_heater_loop(mu, w0, coef, inputs, src, on, ch, rs, rt, track, kp, ki, aw, pmax, sp0, tg,
                      integ, W):                              # pragma: no cover (compiled)
    """The recurrence (module docstring) of ``B`` sets over ``m`` steps into ``W`` (B, m, n), row
    ``k`` the modal state after step ``k``. ``mu`` (B, n) modal factors; ``w0`` (B, n) initial
    modal states; the modal forcing ``g_ik = Σ_t coef[b, t, i]·inputs[src[b], t, k]`` summed in
    the order of ``t`` (``coef`` (B, nt, n); ``inputs`` (U, nt, m) shared by the sets, ``src``
    (B,) each set's row); ``on`` (m,) bool powered; ``ch`` (B, n, H) heater input columns (× P
    [W]); ``rs``/``rt`` (B, H, n) sensor / tracked-node read-out rows; ``track`` bool; ``kp,
    ki, aw, pmax, sp0, tg`` (B, H) controller constants; ``integ`` (B, H) integrator states
    (updated in place)."""
    B, nt, n = coef.shape
    m = inputs.shape[2]
    H = kp.shape[1]
    ts = np.empty(H)
    sp = np.empty(H)
    P = np.empty(H)
    x = np.empty(n)
    for b in range(B):
        r = src[b]
        for i in range(n):
            x[i] = w0[b, i]
        for k in range(m):
            powered = on[k]
            if powered:
                for j in range(H):
                    s = 0.0
                    for i in range(n):
                        s += rs[b, j, i] * x[i]
                    ts[j] = s
                    if track:
                        t = 0.0
                        for i in range(n):
                            t += rt[b, j, i] * x[i]
                        sp[j] = sp0[b, j] + t * tg[b, j]
                    else:
                        sp[j] = sp0[b, j]
            for i in range(n):
                gi = coef[b, 0, i] * inputs[r, 0, k]
                for t in range(1, nt):
                    gi = gi + coef[b, t, i] * inputs[r, t, k]
                x[i] = mu[b, i] * x[i] + gi
            if powered:
                for j in range(H):
                    e = sp[j] - ts[j]
                    v = kp[b, j] * e + integ[b, j]
                    p = v if v > 0.0 else 0.0
                    p = pmax[b, j] if p > pmax[b, j] else p
                    integ[b, j] = (integ[b, j] + ki[b, j] * e) + aw[b, j] * (p - v)
                    P[j] = p
                for i in range(n):
                    h = 0.0
                    for j in range(H):
                        h += ch[b, i, j] * P[j]
                    x[i] = x[i] + h
            else:
                for j in range(H):
                    integ[b, j] = 0.0
            for i in range(n):
                W[b, k, i] = x[i]
