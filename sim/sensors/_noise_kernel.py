"""Compiled slow noise (numba, ``nogil``): one block of :class:`rlgsim.sim.sensors.noise.SlowNoise` —
the flicker bank's first-order filters and the rate random walk — in one call.

Why compiled code: the NumPy path makes one scipy ``lfilter`` call per Gauss–Markov process
(ten for the default bank) plus element-wise passes on (channels × steps) arrays of a few
thousand values per block; its cost is per-call overhead under the GIL, in the IMU prefetch
thread (paper000_ramp: 724 blocks, ~0.2 s per run).

Bit for bit the NumPy path (tests/test_noise_kernel.py compares them). Per process ``i``,
channel ``c`` and step ``k`` the same IEEE-754 float64 operations in the same order, without
``fastmath`` (no reassociation, no fused multiply-add)::

    d = q[i, c]·√(1 − φᵢ²)                          (the drive scale, as FlickerBank.block_from)
    x = w[i, c, k]·d
    y = z + 1·x;  z = x·0 − y·(−φᵢ)                  (scipy's lfilter, transposed direct form
                                                      II, order 1, a₀ = 1; z starts at φᵢ·state)
    out[c, k] = out[c, k] + y                        (processes summed in order from 0)

and the walk ``v = w·s``, ``v₀ = v₀ + state``, ``x_k = x_{k−1} + v_k`` (numpy's cumsum);
the block's slow noise is ``(0 + flicker) + walk`` as :meth:`SlowNoise.block` adds them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def slow_block(wf, phi, q, fs, wr, scale, ws, has_flicker, has_walk, out, new_fs, new_ws
               ):                                             # pragma: no cover (compiled)
    """The slow noise of one block into ``out`` (m, C) and the new states into ``new_fs``
    (J, C) and ``new_ws`` (C,).

    ``wf`` (J, C, m) the flicker drives (standard normals), ``phi`` (J,) and ``q`` (J, C) the
    bank's coefficients, ``fs`` (J, C) its state; ``wr`` (m, C) the walk's drives, ``scale``
    (C,) its ``K·√Δt``, ``ws`` (C,) its state. A term that is off (``has_*`` False) leaves its
    state as it is and adds nothing."""
    m, C = out.shape
    for k in range(m):
        for c in range(C):
            out[k, c] = 0.0
    if has_flicker:
        J = phi.size
        fl = np.zeros((C, m))
        for i in range(J):
            ph = phi[i]
            root = math.sqrt(1.0 - ph * ph)
            a1 = -ph
            for c in range(C):
                d = q[i, c] * root
                z = ph * fs[i, c]
                y = 0.0
                for k in range(m):
                    x = wf[i, c, k] * d
                    y = z + 1.0 * x
                    z = x * 0.0 - y * a1
                    fl[c, k] = fl[c, k] + y
                new_fs[i, c] = y
        for k in range(m):
            for c in range(C):
                out[k, c] = out[k, c] + fl[c, k]
    else:
        new_fs[:, :] = fs
    if has_walk:
        for c in range(C):
            s = scale[c]
            acc = wr[0, c] * s + ws[c]
            out[0, c] = out[0, c] + acc
            for k in range(1, m):
                acc = acc + wr[k, c] * s
                out[k, c] = out[k, c] + acc
            new_ws[c] = acc
    else:
        new_ws[:] = ws
