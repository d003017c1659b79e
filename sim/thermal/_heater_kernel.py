"""Compiled step loop of the heater controllers (numba, ``nogil``): the modal recurrence of
:meth:`rlgsim.sim.thermal.integrator.ThermalIntegrator._stepwise_loop` for a network with
heaters and no nonlinear links, one call per block instead of ~10 NumPy calls per step.

Why compiled code: a heater's PI controller reads its sensor at every grid point and its power
feeds back into the next step, so the recurrence cannot be vectorised over the steps; in Python
each step costs ~3 µs of interpreter and ufunc-dispatch overhead, all of it holding the GIL
(paper000_ramp: 86 880 steps, ~0.25 s of the main thread per run). Here the loop runs without
the GIL.

Bit for bit the Python loop (tests/test_thermal_kernel.py compares them; the dataset checks
compare whole runs). Per step ``k`` and mode ``i`` the same IEEE-754 float64 operations in the
same order, without ``fastmath`` (LLVM neither reassociates nor contracts a product and a sum
into a fused multiply-add)::

    g_ik = c_0i·x_0k;  g_ik = g_ik + c_ti·x_tk  (t = 1, 2, …: setpoint, its step, power, air,
    boundaries — numpy's outer products summed in the same order)
    w_i = μ_i·ws_i;  w_i = w_i + g_ik;  then per heater j in order (powered steps only):
    e = sp_j − ts_j;  v = kp_j·e + I_j;  P = clip(v, 0, Pmax_j);  I_j = (I_j + ki_j·e) + aw_j·(P − v)
    if P ≠ 0:  w_i = w_i + (c_ij·P)

The sensor readings ``ts = r_s · w`` are where the Python loop calls BLAS: numpy's ``matmul``
of the (H, n) read-out rows with the state vector — for one heater ``0.0 + cblas_ddot`` (numpy's
``DOUBLE_dot``), for several ``cblas_dgemv`` (numpy's ``DOUBLE_gemv``), with the vector's
stride as it is (contiguous for the block's first step, every second element of a scratch
buffer after). OpenBLAS sums differently for a unit and a non-unit stride, so this kernel calls
*the same BLAS functions of numpy's own library with the same arguments* (registered with
LLVM's symbol table under private names, which lets numba cache the compiled kernel).
:func:`kernel` returns ``None`` — the caller then keeps the Python loop — when numba is not
importable, numpy's BLAS is not the ILP64 scipy-openblas it ships with (no such symbols), or a
self-check of the registered functions against ``numpy.matmul`` fails.
"""

from __future__ import annotations

import ctypes
import glob
import os
from typing import Any, Callable

import numpy as np

#: numpy's CBLAS symbols (scipy-openblas, 64-bit integers) → the names the kernel links to
_SYMBOLS = {"scipy_cblas_ddot64_": "rlgsim_numpy_cblas_ddot",
            "scipy_cblas_dgemv64_": "rlgsim_numpy_cblas_dgemv"}
_CBLAS_COL_MAJOR = 102
_CBLAS_TRANS = 112

_state: dict[str, Any] = {}


def _numpy_blas_library() -> ctypes.CDLL | None:
    """numpy's bundled OpenBLAS (wheels: ``numpy.libs/libscipy_openblas64_*``), or None."""
    base = os.path.dirname(os.path.dirname(np.__file__))
    for pattern in ("numpy.libs/libscipy_openblas64_*", "numpy/.dylibs/libscipy_openblas64_*",
                    "numpy.libs/libscipy_openblas64_*.dll"):
        for path in sorted(glob.glob(os.path.join(base, pattern))):
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            if all(hasattr(lib, s) for s in _SYMBOLS):
                return lib
    return None


import llvmlite.binding as _llvm                # numba absent: ImportError for the caller
from numba import njit, types

_LIB = _numpy_blas_library()
if _LIB is not None:
    for _sym, _name in _SYMBOLS.items():
        _llvm.add_symbol(_name, ctypes.cast(getattr(_LIB, _sym), ctypes.c_void_p).value)

# pointers are passed as integers (the same register in the C calling convention)
_ddot = types.ExternalFunction(_SYMBOLS["scipy_cblas_ddot64_"],
                               types.float64(types.int64, types.uintp, types.int64,
                                             types.uintp, types.int64))
_dgemv = types.ExternalFunction(_SYMBOLS["scipy_cblas_dgemv64_"],
                                types.void(types.int32, types.int32, types.int64, types.int64,
                                           types.float64, types.uintp, types.int64,
                                           types.uintp, types.int64, types.float64,
                                           types.uintp, types.int64))


@njit(nogil=True, cache=True)
def read_rows(rows, x_ptr, inc, out):                           # pragma: no cover (compiled)
    """``out = rows @ x`` as numpy's matmul computes it; ``rows`` (H, n) C-contiguous, ``x``
    ``n`` float64 at address ``x_ptr``, ``inc`` elements apart; ``out`` (H,)."""
    h, n = rows.shape
    if h == 1:
        out[0] = 0.0 + _ddot(n, rows.ctypes.data, 1, x_ptr, inc)
    else:
        _dgemv(_CBLAS_COL_MAJOR, _CBLAS_TRANS, n, h, 1.0, rows.ctypes.data, n, x_ptr, inc,
               0.0, out.ctypes.data, 1)


@njit(nogil=True, cache=True)
def heater_loop(mu, w0, inc0, coef, inputs, on, WT, scratch, rs, rt, track, cols, kp, ki, aw,
                pmax, sp0, tg, integ, power_out, ts, tt):        # pragma: no cover (compiled)
    """The step loop (module docstring) over ``m = g.shape[1]`` steps.

    ``mu`` (n,) modal factors; ``w0`` (n,) modal state at the block start, read by the sensors
    with stride ``inc0``; the modal forcing ``g_ik = Σ_t coef[t, i]·inputs[t, k]`` summed in
    the order of ``t`` (``coef`` (nt, n), ``inputs`` (nt, m)); ``on`` (m,) bool powered; ``WT`` (m, n)
    output, row k the state after step k; ``scratch`` (n, 2) the sensors' copy of the state
    (column 0, stride 2); ``rs``/``rt`` (H, n) sensor/tracked-node read-out rows; ``track``
    bool; ``cols`` (H, n) heater input columns (× P [W]); ``kp, ki, aw, pmax, sp0, tg`` (H,)
    controller constants; ``integ`` (H,) integrator states (updated); ``power_out`` (m, H)
    heater powers [W]; ``ts, tt`` (H,) work buffers."""
    n = mu.size
    m = inputs.shape[1]
    nt = coef.shape[0]
    H = kp.size
    for k in range(m):
        powered = on[k]
        if powered:
            if k == 0:
                read_rows(rs, w0.ctypes.data, inc0, ts)
                if track:
                    read_rows(rt, w0.ctypes.data, inc0, tt)
            else:
                read_rows(rs, scratch.ctypes.data, 2, ts)
                if track:
                    read_rows(rt, scratch.ctypes.data, 2, tt)
        w = WT[k]
        if k == 0:
            for i in range(n):
                w[i] = mu[i] * w0[i]
        else:
            ws = WT[k - 1]
            for i in range(n):
                w[i] = mu[i] * ws[i]
        for i in range(n):
            gi = coef[0, i] * inputs[0, k]
            for t in range(1, nt):
                gi = gi + coef[t, i] * inputs[t, k]
            w[i] = w[i] + gi
        if powered:
            for j in range(H):
                sp = sp0[j] + tg[j] * tt[j] if track else sp0[j]
                e = sp - ts[j]
                v = kp[j] * e + integ[j]
                P = pmax[j] if v > pmax[j] else (0.0 if v < 0.0 else v)
                integ[j] = integ[j] + ki[j] * e + aw[j] * (P - v)
                power_out[k, j] = P
                if P != 0.0:
                    for i in range(n):
                        w[i] = w[i] + cols[j, i] * P
        else:
            for j in range(H):
                integ[j] = 0.0
                power_out[k, j] = 0.0
        for i in range(n):
            scratch[i, 0] = w[i]


def _self_check(read_rows: Callable) -> bool:
    """The registered functions give numpy's products (one row and several; unit and non-unit
    vector strides): a guard against a library that is not the one numpy calls."""
    rng = np.random.default_rng(12345)
    for h in (1, 2, 3):
        for n in (1, 5, 17, 42, 64):
            rows = rng.standard_normal((h, n))
            buf = rng.standard_normal((n, 2))
            x = buf[:, 0]
            xc = np.ascontiguousarray(x)
            for vec, ptr, inc in ((xc, xc.ctypes.data, 1), (x, buf.ctypes.data, 2)):
                out = np.empty(h)
                read_rows(rows, ptr, inc, out)
                if out.tobytes() != (rows @ vec).tobytes():
                    return False
    return True


def kernel() -> Callable | None:
    """The compiled heater loop, or None when numpy's BLAS is not the expected library
    (checked once per process)."""
    if "kernel" not in _state:
        ok = False
        if _LIB is not None:
            try:
                ok = _self_check(read_rows)
            except Exception:                   # pragma: no cover - optional speed-up only
                ok = False
        _state["kernel"] = heater_loop if ok else None
    return _state["kernel"]
