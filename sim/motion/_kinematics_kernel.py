"""Compiled turntable increments over a window of samples (numba, ``nogil``): what
:meth:`rlgsim.sim.motion.kinematics.Motion._exact` computes with NumPy, in one call.

A block of paper000's turntable programme holds about four windows (the turning motions and
the samples straddling a motion boundary, ~2 000 of its 60 000 samples); NumPy spent ~70 µs
of interpreter time on each (edges, boundary search, runs, ~12 small array operations), with
the GIL held — ~0.3 ms a block in the simulator's main thread. Here a window is one loop over
its samples, each split at the motion boundaries strictly inside it, with the pieces
integrated and summed in order.

The same IEEE-754 float64 operations in the same order as the NumPy path, so the same numbers
bit for bit (tests/test_motion_fill.py compares both with the whole-block computation):

    edges e_j = (k0 + j)/f;  a piece [a, b) of a sample, δ = 1/f for a whole sample, b − a
    for the pieces of a split one; its motion: the last start t0 ≤ a (clipped at the first)
    at rest:  Δθ = a_w·δ,  Δv = a_f·δ
    turning:  h = 0.5·δ;  τm = (a − t_s) + h;  s_w = sin(w·h)/w;  wm = w·τm
              s1 = (−2·sin(wm))·s_w;  s2 = δ − (2·cos(wm))·s_w
              x_i = ((0 + δ·T_0i) + s1·T_1i) + s2·T_2i      (numpy.einsum's order)
    a sample of k pieces: p_0 + (((p_1 + p_2) + …) + p_k−1) — numpy.add.reduceat over a
    column: the first piece, plus numpy's sum of the others, which is one after another
    below 8 of them (pairwise above: such a sample — more than :data:`MAX_PIECES` pieces, a
    motion boundary every few ms of a slow sample — leaves the window to the NumPy path)

No ``fastmath`` (no fused multiply-add, no reassociation). ``sin``/``cos`` are the C library's,
as NumPy's float64 ``sin``/``cos`` are on x86-64 with NumPy 2 — but a NumPy build may use its
own vectorised ones, so :func:`rlgsim.sim.motion.kinematics._compiled_window` compares the kernel with the NumPy path on a fixed
programme once per process, and the caller keeps the NumPy path unless they agree.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


#: Most pieces of one sample summed here (numpy sums more than 8 of them pairwise)
MAX_PIECES = 8


@njit(cache=True, nogil=True)
def exact_window(k0, n, rate_hz, t0, rate, a_w, a_f, turn_w, turn_f, dth, dv, off
                 ):  # pragma: no cover (compiled)
    """Δθ, Δv of samples ``k0 … k0 + n − 1`` of the ``rate_hz`` grid into columns
    ``off … off + n − 1`` of ``dth``, ``dv`` (3, N). ``t0`` (m,) sorted motion starts [s],
    ``rate`` (m,) [rad/s], ``a_w``/``a_f`` (m, 3) C_0ᵀ·x for the Earth rate and the specific
    force, ``turn_w``/``turn_f`` (m, 3, 3) a turn's factors (rows δ, s1, s2). Returns False
    (the columns then unfinished) when a sample holds more than :data:`MAX_PIECES` pieces."""
    m = t0.shape[0]
    kf = float(k0)
    e_lo = kf / rate_hz
    # the motion starts strictly inside the window, in order
    q, hi = 0, m                            # searchsorted(t0, e_lo, "right") by hand
    while q < hi:                           # (numba's own adds ~1 s of compile time)
        mid = (q + hi) // 2
        if t0[mid] <= e_lo:
            q = mid + 1
        else:
            hi = mid
    s = max(q - 1, 0)                       # the motion of the first piece
    whole = 1.0 / rate_hz
    for j in range(n):
        ea = (kf + float(j)) / rate_hz
        eb = (kf + float(j + 1)) / rate_hz
        while q < m and t0[q] <= ea:        # on an edge (or before): no split
            q += 1
        split = q < m and t0[q] < eb
        p_w0 = p_w1 = p_w2 = p_f0 = p_f1 = p_f2 = 0.0
        r_w0 = r_w1 = r_w2 = r_f0 = r_f1 = r_f2 = 0.0
        a = ea
        pieces = 0
        while True:
            end = not (q < m and t0[q] < eb)
            if end:
                b = eb
            else:                               # a boundary inside the sample ends the piece
                b = t0[q]
                q += 1
            delta = b - a if split else whole
            while s + 1 < m and t0[s + 1] <= a:
                s += 1
            w = rate[s]
            if w == 0.0:
                x0, x1, x2 = a_w[s, 0] * delta, a_w[s, 1] * delta, a_w[s, 2] * delta
                y0, y1, y2 = a_f[s, 0] * delta, a_f[s, 1] * delta, a_f[s, 2] * delta
            else:
                h = 0.5 * delta
                tm = (a - t0[s]) + h
                sw = math.sin(w * h) / w
                wm = w * tm
                s1 = (-2.0 * math.sin(wm)) * sw
                s2 = delta - (2.0 * math.cos(wm)) * sw
                tw, tf = turn_w[s], turn_f[s]
                x0 = ((0.0 + delta * tw[0, 0]) + s1 * tw[1, 0]) + s2 * tw[2, 0]
                x1 = ((0.0 + delta * tw[0, 1]) + s1 * tw[1, 1]) + s2 * tw[2, 1]
                x2 = ((0.0 + delta * tw[0, 2]) + s1 * tw[1, 2]) + s2 * tw[2, 2]
                y0 = ((0.0 + delta * tf[0, 0]) + s1 * tf[1, 0]) + s2 * tf[2, 0]
                y1 = ((0.0 + delta * tf[0, 1]) + s1 * tf[1, 1]) + s2 * tf[2, 1]
                y2 = ((0.0 + delta * tf[0, 2]) + s1 * tf[1, 2]) + s2 * tf[2, 2]
            if pieces == 0:                     # the first piece
                p_w0, p_w1, p_w2, p_f0, p_f1, p_f2 = x0, x1, x2, y0, y1, y2
            elif pieces == 1:                   # the rest summed in order, then added to it
                r_w0, r_w1, r_w2, r_f0, r_f1, r_f2 = x0, x1, x2, y0, y1, y2
            else:
                r_w0, r_w1, r_w2 = r_w0 + x0, r_w1 + x1, r_w2 + x2
                r_f0, r_f1, r_f2 = r_f0 + y0, r_f1 + y1, r_f2 + y2
            pieces += 1
            if end:
                break
            a = b
        if pieces > MAX_PIECES:                 # numpy sums a longer rest pairwise
            return False
        c = off + j
        if pieces > 1:
            p_w0, p_w1, p_w2 = p_w0 + r_w0, p_w1 + r_w1, p_w2 + r_w2
            p_f0, p_f1, p_f2 = p_f0 + r_f0, p_f1 + r_f1, p_f2 + r_f2
        dth[0, c], dth[1, c], dth[2, c] = p_w0, p_w1, p_w2
        dv[0, c], dv[1, c], dv[2, c] = p_f0, p_f1, p_f2
    return True
