"""Compiled loop of :func:`rlgsim.sim.sensors.sensor_triad.count_pulses` (numba): every channel of a
sensor triad's block in one call.

The NumPy formulation of one channel's block (:func:`rlgsim.sim.sensors.sensor_triad._channel`, then
:func:`rlgsim.sim.sensors.pulses.count_scaled`) makes about ten passes over 60 000 samples, each
reading and writing whole float64/int64 buffers: the row products, the bias, σ·z, the scale
factor, the range check's two reductions, ``rint``, the int64 cast, the prefix sum, the shift
and the difference. This kernel walks the block in chunks of at most :data:`CHUNK` samples of
one thermal step, so everything between the inputs and the int32 pulses stays in two small
buffers in the L1 cache: per channel, the scaled increments in one vectorised loop (SIMD: no
dependency between samples), their largest magnitude and the fixed-point ``rint`` in a second,
then the prefix sum — the only sequential part — in a third. One call for all the channels of a
triad: the per-call setup (argument unboxing, the caller's per-channel slicing and scaling)
is paid once per block, not once per channel.

Bit for bit the NumPy path (tests/test_pulse_kernel.py compares them over random blocks,
both step layouts, steps at rest, K⁺/K⁻ and unpowered samples). The same IEEE-754 float64
operations in the same order per sample (no ``fastmath``, so LLVM neither reassociates nor
contracts a product and a sum into a fused multiply-add; splitting a sample's arithmetic
between loops changes no operation):

    u = ((E_x·x_x + E_y·x_y) + E_z·x_z) + D·Δt       (the own-axis term is x itself: E = 1)
    u = u + float64(z)·σ                              (only when the channel has white noise)
    u = u·(K·2^30)       (K⁺ where u ≥ 0, K⁻ where u < 0 for an accelerometer), 0 while unpowered
    q = rint(u) (round half to even) as int64;  Φ = ρ + q_0 + … + q_j;  c_j = Φ >> 30;
    pulse_j = int32(c_j − c_{j−1})

(:mod:`rlgsim.sim.sensors.pulses` explains the fixed point; D·Δt and K·2^30 are the same products the
NumPy path forms, K·2^30 exact: a power of two). For a step at rest (every sample the same
increment, :func:`rlgsim.sim.sensors.sensor_triad.step_inputs`) the first bracket is evaluated once
with the step's first sample — the same numbers, so the same value for every sample.
The kernel also returns each channel's largest |u| — as the bit pattern of the float64 with the
sign cleared, whose integer maximum is the float maximum and exceeds +inf's for a NaN (an
integer reduction vectorises without ``fastmath``) — so the caller applies
:func:`rlgsim.sim.sensors.pulses.check_range`'s fast test; any channel failing it (out of range or NaN)
is recomputed by the NumPy path, which raises the one-line error.

Indices inside the inner loops are unsigned: numba adds a negative-index wrap-around to every
signed index it cannot prove non-negative, which kept the prefix-sum loop at half speed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Samples per chunk: two float64/int64 buffers of this length stay in the L1 cache.
CHUNK = 512

_ABS_BITS = np.int64(0x7FFFFFFFFFFFFFFF)      # a float64's bits without the sign


@njit(cache=True, nogil=True, inline="always")
def _scaled_per_sample(ub, x_t, rows, bias, sample_dt, zs, sg, k_pos, k_neg, one, step_of,
                       power, s, o, c0, w, has_z, has_neg, has_power):  # pragma: no cover
    """:func:`count_block`'s scaled increments ``ub[:w]`` of channel ``s`` for the samples
    ``c0 … c0 + w − 1`` when each sample names its step (``step_of``)."""
    for t in range(w):
        j = np.uint64(c0 + t)
        st = step_of[j]
        x0, x1, x2 = x_t[0, j], x_t[1, j], x_t[2, j]
        p0 = x0 if o == 0 else rows[st, s, 0] * x0
        p1 = x1 if o == 1 else rows[st, s, 1] * x1
        p2 = x2 if o == 2 else rows[st, s, 2] * x2
        u = ((p0 + p1) + p2) + bias[st, s] * sample_dt
        if has_z:
            u = u + np.float64(zs[np.uint64(t)]) * sg
        if has_neg and not u >= 0.0:
            u = u * (k_neg[st, s] * one)
        else:
            u = u * (k_pos[st, s] * one)
        if has_power and power[st] <= 0.0:
            u = 0.0
        ub[np.uint64(t)] = u


@njit(cache=True, nogil=True, inline="always")
def _count_chunk(ub, bits, q, w, h, ph, pv, outs):  # pragma: no cover
    """:func:`count_block`'s count of one chunk of one channel: the largest |u| bits ``h``
    updated, ``u`` rounded to the nearest integer (half to even), accumulated into the phase
    ``ph`` and counted in whole pulses (``ph >> 30``) into ``outs``; returns
    ``(h, ph, pv)`` with ``pv`` the last count."""
    for t in range(w):
        ut = np.uint64(t)
        v = bits[ut] & _ABS_BITS
        if v > h:
            h = v
        q[ut] = np.int64(np.rint(ub[ut]))
    for t in range(w):
        ut = np.uint64(t)
        ph += q[ut]
        cc = ph >> 30
        outs[ut] = np.int32(cc - pv)
        pv = cc
    return h, ph, pv


@njit(cache=True, nogil=True)
def count_block(x_t, rows, bias, sample_dt, z, sigma, k_pos, k_neg, one, r, step_of,
                uniform, first, own, power, remainder, out, new, peak_bits):  # pragma: no cover
    """Count the pulses of every channel of one block into ``out`` (n, C) int32, the new
    remainders into ``new`` (C,) int64 and each channel's largest |u| (u the scaled
    increments) into ``peak_bits`` (C,) int64 as the bits of a float64 (NaN when one is NaN).

    ``x_t`` (3, n) float64 increments; ``rows`` (m, C, 3) installation rows; ``bias`` (m, C)
    [unit of x per s]; ``sample_dt`` Δt [s]; ``z`` (C, n) float32 standard normals (shape
    (1, 0): no white noise); ``sigma`` (C,) σ [unit of x]; ``k_pos`` (m, C) scale factor;
    ``k_neg`` (m, C) the K⁻ (shape (0, 0): one scale factor); ``one`` = 2^30 (folded into the
    scale factor); ``r`` samples per step (> 0) or 0 when ``step_of`` (n,) int64 gives each
    sample's step; ``uniform`` (m,) bool steps at rest with ``first`` (3, m) their increment
    (size 0: none known); ``own`` (C,) int64 each sensor's body axis (its row entry is exactly
    1) or −1; ``power`` (m,) float64, a step with power ≤ 0 unpowered (size 0: always on);
    ``remainder`` (C,) int64 in [0, 2^30)."""
    n = x_t.shape[1]
    m = rows.shape[0]
    c = rows.shape[1]
    has_z = z.shape[1] > 0
    has_neg = k_neg.shape[0] > 0
    has_power = power.shape[0] > 0
    has_steps = uniform.shape[0] > 0
    ub = np.empty(CHUNK)
    bits = ub.view(np.int64)
    q = np.empty(CHUNK, dtype=np.int64)
    phi = np.empty(c, dtype=np.int64)
    prev = np.zeros(c, dtype=np.int64)
    hb = np.zeros(c, dtype=np.int64)
    for s in range(c):
        phi[s] = remainder[s]
    for i in range(m if r > 0 else 1):              # r = 0: one pass over every sample
        j0 = i * r if r > 0 else 0
        j1 = j0 + r if r > 0 else n
        at_rest = r > 0 and has_steps and uniform[i]
        off = r > 0 and has_power and power[i] <= 0.0
        for c0 in range(j0, j1, CHUNK):
            c1 = min(c0 + CHUNK, j1)
            w = c1 - c0
            for s in range(c):
                o = own[s]
                sg = sigma[s] if has_z else 0.0
                zs = z[s, c0:c1] if has_z else z[0, 0:0]
                if r > 0:
                    kp = k_pos[i, s] * one
                    kn = k_neg[i, s] * one if has_neg else 0.0
                    a = bias[i, s] * sample_dt
                    e0, e1, e2 = rows[i, s, 0], rows[i, s, 1], rows[i, s, 2]
                    if at_rest:
                        x0, x1, x2 = first[0, i], first[1, i], first[2, i]
                        p0 = x0 if o == 0 else e0 * x0
                        p1 = x1 if o == 1 else e1 * x1
                        p2 = x2 if o == 2 else e2 * x2
                        base = ((p0 + p1) + p2) + a
                        for t in range(w):
                            ub[np.uint64(t)] = base
                    else:
                        xa, xb, xc = x_t[0, c0:c1], x_t[1, c0:c1], x_t[2, c0:c1]
                        for t in range(w):
                            ut = np.uint64(t)
                            x0, x1, x2 = xa[ut], xb[ut], xc[ut]
                            p0 = x0 if o == 0 else e0 * x0
                            p1 = x1 if o == 1 else e1 * x1
                            p2 = x2 if o == 2 else e2 * x2
                            ub[ut] = ((p0 + p1) + p2) + a
                    # the noise and the scale factor in one loop per case (a loop-invariant
                    # test inside the loop kept LLVM from vectorising it as well)
                    if has_z and has_neg:
                        for t in range(w):
                            ut = np.uint64(t)
                            u = ub[ut] + np.float64(zs[ut]) * sg
                            ub[ut] = u * kp if u >= 0.0 else u * kn
                    elif has_z:
                        for t in range(w):
                            ut = np.uint64(t)
                            ub[ut] = (ub[ut] + np.float64(zs[ut]) * sg) * kp
                    elif has_neg:
                        for t in range(w):
                            ut = np.uint64(t)
                            u = ub[ut]
                            ub[ut] = u * kp if u >= 0.0 else u * kn
                    else:
                        for t in range(w):
                            ut = np.uint64(t)
                            ub[ut] = ub[ut] * kp
                    if off:
                        for t in range(w):
                            ub[np.uint64(t)] = 0.0
                else:                                   # a step index per sample
                    _scaled_per_sample(ub, x_t, rows, bias, sample_dt, zs, sg, k_pos, k_neg,
                                       one, step_of, power, s, o, c0, w, has_z, has_neg,
                                       has_power)
                hb[s], phi[s], prev[s] = _count_chunk(ub, bits, q, w, hb[s], phi[s], prev[s],
                                                      out[c0:c1, s])
    for s in range(c):
        new[s] = phi[s] - (prev[s] << 30)
        peak_bits[s] = hb[s]


@njit(cache=True, nogil=True)
def steps_at_rest(x_t, r, uniform, first):  # pragma: no cover
    """For increments ``x_t`` (3, m·r) float64, C-contiguous: ``uniform[i]`` whether every
    sample of step ``i`` (``r`` samples) has the bits of the step's first sample on all three
    axes, and ``first[:, i]`` that sample (:func:`rlgsim.sim.sensors.sensor_triad.step_inputs`).
    The bits are compared by an OR of XORs over the step, an integer reduction that
    vectorises (an early exit at the first difference would not)."""
    m = uniform.shape[0]
    bits = x_t.view(np.int64)
    for i in range(m):
        j0 = i * r
        acc = np.int64(0)
        for k in range(3):
            row = bits[k, j0:j0 + r]
            f = row[0]
            for t in range(r):
                acc |= row[np.uint64(t)] ^ f
            first[k, i] = x_t[k, j0]
        uniform[i] = acc == 0
