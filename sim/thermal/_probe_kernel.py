"""Compiled probe readings (numba, ``nogil``): the lag, noise and resolution of
:meth:`rlgsim.sim.thermal.thermometers.ProbeSet.read` for one block in one call.

Why compiled code: the NumPy path makes ~20 calls per block on (probes × steps) arrays of a few
thousand values — gathers, a scipy ``lfilter`` per lag group, five element-wise passes — and
its cost is the per-call overhead under the GIL (paper000_ramp: 724 blocks, ~0.06 s of the
main thread per run besides the normal draws, which stay NumPy's).

Bit for bit the NumPy path (tests/test_probe_kernel.py compares them). Per probe ``p`` and
step ``k`` the same IEEE-754 float64 operations in the same order, without ``fastmath`` (no
reassociation, no fused multiply-add)::

    f = (1 − a − c)·T[k−1];  f = f + c·T[k]               (the NumPy path's forcing)
    θ = z + 1·f;  z = f·0 − θ·(−a)                         (scipy's lfilter, transposed
                                                            direct form II, order 1, a₀ = 1)
    r = n·σ;  r = r + θ;  r = rint(r / q)·q  (q > 0)        (noise, resolution)

``z`` starts at ``a·θ[−1]`` as the NumPy path's ``zi``; a probe without lag (τ = 0) reads
``θ = T[k]``. ``rint`` is round-half-to-even, as ``np.round`` with no decimals.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(nogil=True, cache=True)
def read_block(T, node_index, state, a, c, lagged, sigma, q, reading, new_state
               ):                                             # pragma: no cover (compiled)
    """Readings of one block into ``reading`` (m, P), which holds the standard normal draws
    on entry; the new probe state into ``new_state`` (2, P).

    ``T`` (m, n_nodes) node temperatures [°C] at the block's grid points; ``node_index`` (P,)
    int64 probed nodes; ``state`` (2, P) the carried state (row 0 θ, row 1 the probed node
    temperatures at the block start); ``a``, ``c`` (P,) the lag coefficients; ``lagged`` (P,)
    bool τ > 0; ``sigma`` (P,) noise [K]; ``q`` (P,) resolution [K] (0: none)."""
    m = T.shape[0]
    P = node_index.size
    for p in range(P):
        node = node_index[p]
        ap = a[p]
        cp = c[p]
        k1 = 1.0 - ap - cp
        a1 = -ap
        s = sigma[p]
        qp = q[p]
        prev = state[1, p]
        z = ap * state[0, p]
        theta = state[0, p]
        for k in range(m):
            x = T[k, node]
            if lagged[p]:
                f = k1 * prev
                f = f + cp * x
                theta = z + 1.0 * f
                z = f * 0.0 - theta * a1
            else:
                theta = x
            r = reading[k, p] * s
            r = r + theta
            if qp > 0.0:
                r = r / qp
                r = np.rint(r)
                r = r * qp
            reading[k, p] = r
            prev = x
        new_state[0, p] = theta
        new_state[1, p] = prev
