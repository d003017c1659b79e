"""Compiled per-channel loop of :func:`rlgsim.sim.sensor_triad.count_pulses` (numba).

The NumPy formulation of one channel's block (:func:`rlgsim.sim.sensor_triad._channel`, then
:func:`rlgsim.sim.pulses.count_scaled`) makes about ten passes over 60 000 samples, each
reading and writing whole float64/int64 buffers: the row products, the bias, σ·z, the scale
factor, the range check's two reductions, ``rint``, the int64 cast, the prefix sum, the shift
and the difference. This kernel makes one pass per channel, holding the sample's value in a
register, and writes only the int32 pulse.

Bit for bit the NumPy path (tests/test_pulse_kernel.py compares them over random blocks,
both step layouts, steps at rest, K⁺/K⁻ and unpowered samples). The same IEEE-754 float64
operations in the same order per sample (no ``fastmath``, so LLVM neither reassociates nor
contracts a product and a sum into a fused multiply-add):

    u = ((E_x·x_x + E_y·x_y) + E_z·x_z) + D·Δt       (the own-axis term is x itself: E = 1)
    u = u + float64(z)·σ                              (only when the channel has white noise)
    u = u·(K·2^30)       (K⁺ where u ≥ 0, K⁻ where u < 0 for an accelerometer), 0 while unpowered
    q = rint(u) (round half to even) as int64;  Φ = ρ + q_0 + … + q_j;  c_j = Φ >> 30;
    pulse_j = int32(c_j − c_{j−1})

(:mod:`rlgsim.sim.pulses` explains the fixed point). For a step at rest (every sample the
same increment, :func:`rlgsim.sim.sensor_triad.step_inputs`) the first bracket is evaluated
once with the step's first sample — the same numbers, so the same value for every sample.
The kernel also returns the largest and smallest scaled increment so the caller applies
:func:`rlgsim.sim.pulses.check_range`'s fast test; any channel failing it (out of range or
NaN) is recomputed by the NumPy path, which raises the one-line error.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def count_channel(x_t, row, a, z, sigma, k_pos, k_neg, r, step_of, uniform, first, own,
                  off, remainder, out, col):  # pragma: no cover
    """Count one channel's pulses of one block into column ``col`` of ``out`` (n, C) int32;
    returns (new remainder, max |u|, −max |u|) with u the scaled increments (NaN, NaN when
    one is NaN).

    ``x_t`` (3, n) float64 increments; ``row`` (m, 3) installation rows; ``a`` (m,) bias·Δt;
    ``z`` (n,) float32 standard normals (size 0: no white noise); ``sigma`` σ [unit of x];
    ``k_pos`` (m,) scale factor × 2^30; ``k_neg`` (m,) the K⁻ × 2^30 (size 0: one scale
    factor); ``r`` samples per step (> 0) or 0 when ``step_of`` (n,) int64 gives each sample's
    step; ``uniform`` (m,) bool steps at rest with ``first`` (3, m) their increment (size 0:
    none known); ``own`` the sensor's body axis (its row entry is exactly 1) or −1; ``off``
    (n,) bool unpowered samples (size 0: always on); ``remainder`` ∈ [0, 2^30)."""
    n = x_t.shape[1]
    m = row.shape[0]
    has_z = z.shape[0] > 0
    has_neg = k_neg.shape[0] > 0
    has_off = off.shape[0] > 0
    has_steps = uniform.shape[0] > 0
    phi = np.int64(remainder)
    prev = np.int64(0)
    hi = 0.0
    nan = False
    for i in range(m if r > 0 else 1):
        j0 = i * r if r > 0 else 0
        j1 = j0 + r if r > 0 else n
        kp = k_pos[i]
        kn = k_neg[i] if has_neg else 0.0
        # the per-sample body is written out in both loops: as an inlined njit function
        # returning (phi, prev, hi, nan) the kernel ran 15 x slower (A/B on one block)
        if r > 0 and has_steps and uniform[i]:
            x0, x1, x2 = first[0, i], first[1, i], first[2, i]
            p0 = x0 if own == 0 else row[i, 0] * x0
            p1 = x1 if own == 1 else row[i, 1] * x1
            p2 = x2 if own == 2 else row[i, 2] * x2
            base = ((p0 + p1) + p2) + a[i]
            for j in range(j0, j1):
                u = base
                if has_z:
                    u = u + np.float64(z[j]) * sigma
                if has_neg and not u >= 0.0:
                    u = u * kn
                else:
                    u = u * kp
                if has_off and off[j]:
                    u = 0.0
                if u > hi:
                    hi = u
                if -u > hi:
                    hi = -u
                if u != u:
                    nan = True
                phi += np.int64(np.rint(u))
                c = phi >> 30
                out[j, col] = np.int32(c - prev)
                prev = c
        else:
            for j in range(j0, j1):
                s = i if r > 0 else step_of[j]
                if r == 0:
                    kp = k_pos[s]
                    kn = k_neg[s] if has_neg else 0.0
                x0, x1, x2 = x_t[0, j], x_t[1, j], x_t[2, j]
                p0 = x0 if own == 0 else row[s, 0] * x0
                p1 = x1 if own == 1 else row[s, 1] * x1
                p2 = x2 if own == 2 else row[s, 2] * x2
                u = ((p0 + p1) + p2) + a[s]
                if has_z:
                    u = u + np.float64(z[j]) * sigma
                if has_neg and not u >= 0.0:
                    u = u * kn
                else:
                    u = u * kp
                if has_off and off[j]:
                    u = 0.0
                if u > hi:
                    hi = u
                if -u > hi:
                    hi = -u
                if u != u:
                    nan = True
                phi += np.int64(np.rint(u))
                c = phi >> 30
                out[j, col] = np.int32(c - prev)
                prev = c
    if nan:
        hi = np.nan
    return phi - (prev << 30), hi, -hi
