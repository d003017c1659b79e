"""Compiled DOP853 of a route's position (numba): leg by leg, the geodetic position (L, λ, h)
from the legs' velocity, straight into the dense rows the block kernels read.

Why by hand: scipy's :class:`~scipy.integrate.DOP853` takes each of its ~1000 steps of a 4-h
route through Python (~100 µs a step, the right-hand side a Python call per stage): ~0.1 s of
CPU before the first block of a vehicle's run, on the main thread. This is the same method, step
for step — Hairer, Nørsett & Wanner (1993), *Solving Ordinary Differential Equations I*,
§II.5 and §II.10 (DOP853's 12 stages, its 5th- and 3rd-order error estimators, the 7th-order
dense output of three extra stages) as scipy's ``rk.py`` implements it: the same Butcher tableau
(read from scipy's ``dop853_coefficients``, never re-typed), the same initial step
(``select_initial_step``, Hairer et al. §II.4), the same step-size controller (scipy's SAFETY,
MIN_FACTOR, MAX_FACTOR) and the same interpolant rows. The right-hand side is
:func:`rlgsim.sim.motion._trajectory_kernel.position_rate_at`'s formulas, compiled in.

**Not bit for bit scipy's.** scipy forms the stage sums Σ a_ij k_j with NumPy's ``dot`` — a BLAS
call whose order of summation and use of fused multiply–adds depend on the CPU's kernel (the
positions of a route differed from one machine to another at the last bit). Here every sum runs
in stage order without fused operations, on any machine. The two differ by rounding in each
stage, which the controller turns into step sizes differing by rounding: the positions agree
with scipy's to well inside the integration's own tolerance (rtol 1e-13, atol 1e-15 rad / 1e-9
m per step; tests/test_trajectory.py checks the bound, 2 × steps × the tolerance scale).

Status codes of :func:`dop853_leg`: 0 done; 1 the polar event's sign changed (|L| reached
:data:`rlgsim.sim.motion.trajectory.MAX_LATITUDE_RAD`) or the step fell below scipy's minimum
step — then the caller hands the leg to ``solve_ivp``, which decides and words it as before.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.integrate._ivp import dop853_coefficients as _dc
from scipy.integrate._ivp import rk as _rk

from rlgsim.sim.motion._trajectory_kernel import _position_rate, _state

#: scipy's DOP853 tableau and controller, as its solver uses them (rk.DOP853)
N_STAGES = _dc.N_STAGES
TAB_A = np.ascontiguousarray(_dc.A, dtype=float)            # (16, 16): stages and extra stages
TAB_B = np.ascontiguousarray(_dc.B, dtype=float)
TAB_C = np.ascontiguousarray(_dc.C, dtype=float)
TAB_E3 = np.ascontiguousarray(_dc.E3, dtype=float)
TAB_E5 = np.ascontiguousarray(_dc.E5, dtype=float)
TAB_D = np.ascontiguousarray(_dc.D, dtype=float)
#: SAFETY, MIN_FACTOR, MAX_FACTOR, the error exponent −1/(7 + 1) and the estimator's order
CONTROL = np.array([_rk.SAFETY, _rk.MIN_FACTOR, _rk.MAX_FACTOR,
                    -1.0 / (_rk.DOP853.error_estimator_order + 1),
                    float(_rk.DOP853.error_estimator_order)])
#: columns of a dense row: t_old, h, the seven rows F_0 … F_6 (three components each), y_old
ROW = 2 + 3 * _dc.INTERPOLATOR_POWER + 3


@njit(cache=True, nogil=True)
def _rhs(coef, dcoef, j, tau, y0, y1, y2, w, e2, a_axis, out):  # pragma: no cover
    """(L̇, λ̇, ḣ) of leg ``j`` at leg time ``tau`` and position (y0, y1, y2) → ``out`` (3,)
    (a row of the stages: one compiled specialisation, where a literal row index made one
    per literal)."""
    _state(coef, dcoef, j, tau, w)
    r0, r1, r2 = _position_rate(y0, y2, w[12], w[13], w[14], e2, a_axis)
    out[0], out[1], out[2] = r0, r1, r2


@njit(cache=True, nogil=True, inline="always")
def _rms(x0, x1, x2):  # pragma: no cover - compiled
    """scipy's ``norm``: sqrt(x·x)/sqrt(3)."""
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2) / 3.0 ** 0.5


@njit(cache=True, nogil=True)
def _first_step(coef, dcoef, j, t_bound, y, f0, rtol, atol, w, e2, a_axis, k,
                order):  # pragma: no cover - compiled
    """scipy's ``select_initial_step`` (Hairer et al. §II.4) from leg time 0 (``k`` (3,)
    scratch)."""
    s0 = atol[0] + abs(y[0]) * rtol
    s1 = atol[1] + abs(y[1]) * rtol
    s2 = atol[2] + abs(y[2]) * rtol
    d0 = _rms(y[0] / s0, y[1] / s1, y[2] / s2)
    d1 = _rms(f0[0] / s0, f0[1] / s1, f0[2] / s2)
    h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
    h0 = min(h0, t_bound)
    _rhs(coef, dcoef, j, h0, y[0] + h0 * f0[0], y[1] + h0 * f0[1], y[2] + h0 * f0[2], w, e2,
         a_axis, k)
    d2 = _rms((k[0] - f0[0]) / s0, (k[1] - f0[1]) / s1, (k[2] - f0[2]) / s2) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return min(100.0 * h0, h1, t_bound)


@njit(cache=True, nogil=True)
def _stage_input(k, a, s, h, y, out):  # pragma: no cover - compiled
    """y + (Σ_(i<s) a_i k_i)·h → out (3,), the sum in stage order."""
    for c in range(3):
        acc = 0.0
        for i in range(s):
            acc += k[i, c] * a[i]
        out[c] = y[c] + acc * h


@njit(cache=True, nogil=True)
def _rk_step(coef, dcoef, j, t, y, h, k, w, e2, a_axis, y_new, tmp, tab_a, tab_b,
             tab_c):  # pragma: no cover - compiled
    """One DOP853 step of ``h`` from (t, y), k[0] = f(t, y) given: stages 1 … 11 into k,
    the 8th-order solution into ``y_new``, f(t + h, y_new) into k[12] (scipy's rk_step)."""
    for s in range(1, N_STAGES):
        _stage_input(k, tab_a[s], s, h, y, tmp)
        _rhs(coef, dcoef, j, t + tab_c[s] * h, tmp[0], tmp[1], tmp[2], w, e2, a_axis, k[s])
    for c in range(3):
        acc = 0.0
        for i in range(N_STAGES):
            acc += k[i, c] * tab_b[i]
        y_new[c] = y[c] + h * acc
    _rhs(coef, dcoef, j, t + h, y_new[0], y_new[1], y_new[2], w, e2, a_axis, k[N_STAGES])


@njit(cache=True, nogil=True)
def _error_norm(k, h, scale, e3, e5):  # pragma: no cover - compiled
    """scipy DOP853's ``_estimate_error_norm`` of the stages ``k`` (13, 3)."""
    n5 = n3 = 0.0
    for c in range(3):
        a5 = a3 = 0.0
        for i in range(N_STAGES + 1):
            a5 += k[i, c] * e5[i]
            a3 += k[i, c] * e3[i]
        a5 /= scale[c]
        a3 /= scale[c]
        n5 += a5 * a5
        n3 += a3 * a3
    n5 = np.sqrt(n5) ** 2
    n3 = np.sqrt(n3) ** 2
    if n5 == 0.0 and n3 == 0.0:
        return 0.0
    return abs(h) * n5 / np.sqrt((n5 + 0.01 * n3) * 3.0)


@njit(cache=True, nogil=True)
def _dense_row(coef, dcoef, j, t_old, h, y_old, y, f_new, k, w, e2, a_axis, tmp, tab_a,
               tab_c, tab_d, row):  # pragma: no cover - compiled
    """The step's interpolant (scipy's ``_dense_output_impl``: three extra stages) → ``row``
    (t_old, h, F_0 … F_6, y_old)."""
    for s in range(N_STAGES + 1, tab_a.shape[0]):
        _stage_input(k, tab_a[s], s, h, y_old, tmp)
        _rhs(coef, dcoef, j, t_old + tab_c[s] * h, tmp[0], tmp[1], tmp[2], w, e2, a_axis, k[s])
    row[0], row[1] = t_old, h
    for c in range(3):
        dy = y[c] - y_old[c]
        row[2 + c] = dy
        row[5 + c] = h * k[0, c] - dy
        row[8 + c] = 2.0 * dy - h * (f_new[c] + k[0, c])
        for r in range(tab_d.shape[0]):
            acc = 0.0
            for i in range(tab_d.shape[1]):
                acc += tab_d[r, i] * k[i, c]
            row[11 + 3 * r + c] = h * acc
        row[23 + c] = y_old[c]


@njit(cache=True, nogil=True)
def dop853_leg(coef, dcoef, j, t_bound, y0, rtol, atol, earth, max_lat, tab_a, tab_b, tab_c,
               tab_e3, tab_e5, tab_d, control, rows, n_rows, t_stop):  # pragma: no cover
    """Integrate leg ``j``'s position over leg time [0, ``t_bound``] from ``y0`` → its dense
    rows appended to ``rows`` from row ``n_rows`` (grown by doubling as needed); it stops after
    the first step reaching ``t_stop`` (the run's end inside the leg; ``t_bound`` otherwise):
    the steps, and so the rows, up to there are those of the whole leg's integration.

    Returns (status, rows, the new row count, the end position): status 0 done, 1 hand the
    leg to scipy (module docstring). The steps as scipy's ``DOP853.step``: each attempt of
    h = min(h_abs, to the end) accepted when the error norm < 1, h_abs scaled by the
    controller. Every step advances t (h ≥ scipy's minimum step, 10 ulp of t), so none is
    dropped as solve_ivp drops a step that does not."""
    a_axis, e2 = earth[0], earth[1]
    safety, min_factor, max_factor, expo, order = (control[0], control[1], control[2],
                                                   control[3], control[4])
    w = np.empty(32)
    k = np.empty((tab_a.shape[0], 3))
    y = y0.copy()
    y_new = np.empty(3)
    tmp = np.empty(3)
    scale = np.empty(3)
    f = np.empty(3)
    _rhs(coef, dcoef, j, 0.0, y[0], y[1], y[2], w, e2, a_axis, f)
    h_abs = _first_step(coef, dcoef, j, t_bound, y, f, rtol, atol, w, e2, a_axis, np.empty(3),
                        order)
    g = max_lat - abs(y[0])
    t = 0.0
    while t != t_bound:
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs < min_step:
            return 1, rows, n_rows, y
        accepted = rejected = False
        h = t_new = 0.0
        while not accepted:
            if h_abs < min_step:
                return 1, rows, n_rows, y
            t_new = t + h_abs
            if t_new - t_bound > 0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            k[0] = f
            _rk_step(coef, dcoef, j, t, y, h, k, w, e2, a_axis, y_new, tmp, tab_a, tab_b, tab_c)
            for c in range(3):
                scale[c] = atol[c] + max(abs(y[c]), abs(y_new[c])) * rtol
            err = _error_norm(k, h, scale, tab_e3, tab_e5)
            if err < 1:
                factor = max_factor if err == 0 else min(max_factor, safety * err ** expo)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                accepted = True
            else:
                h_abs *= max(min_factor, safety * err ** expo)
                rejected = True
        g_new = max_lat - abs(y_new[0])
        if (g <= 0 and g_new >= 0) or (g >= 0 and g_new <= 0):
            return 1, rows, n_rows, y
        g = g_new
        if n_rows == rows.shape[0]:
            bigger = np.empty((2 * rows.shape[0] + 16, rows.shape[1]))
            bigger[:n_rows] = rows[:n_rows]
            rows = bigger
        _dense_row(coef, dcoef, j, t, h, y, y_new, k[N_STAGES], k, w, e2, a_axis, tmp, tab_a,
                   tab_c, tab_d, rows[n_rows])
        n_rows += 1
        f[:] = k[N_STAGES]
        y[:] = y_new
        t = t_new
        if t - t_bound >= 0 or t >= t_stop:
            break
    return 0, rows, n_rows, y
