"""Pulse counting with a carried fractional remainder: no pulse is ever lost or invented.

A laser gyro's fringe counter (or a quartz accelerometer's current-to-frequency converter) emits
one pulse each time the accumulated phase crosses an integer (paper 000 §3.3, eqs. 17 and 20:
the computer counts the pulses in each sampling interval). With ``inc_j`` the phase increment of
sample ``j`` in pulses (float64, from the measurement equation):

    q_j = rint(inc_j · 2^30)                       int64 fixed point, 2^-30 pulse resolution
    Φ_j = ρ + q_0 + q_1 + … + q_j                  ρ ∈ [0, 2^30): remainder carried in
    c_j = Φ_j >> 30  (= floor(Φ_j / 2^30)),        pulses_j = c_j − c_{j−1},  c_{−1} = 0
    ρ'  = Φ_last − (c_last << 30)                  remainder carried out

so the pulses of a block sum to floor((ρ + Σq)/2^30) and, chained over blocks, **the sum of all
pulses is exactly the floor of the total phase** (integer arithmetic is associative, so this
holds whatever the grouping). The integer part is removed at every block end, keeping Φ small.

Why fixed point rather than a float64 running phase: float64 sums round differently when the
same increments are grouped differently, so "sum of pulses == floor(total phase)" would hold
only up to rounding at integer crossings; the int64 running sum is exact and associative, and
numpy's int64 prefix sum is ~10× faster than its float64 one. The resolution, 2^-30 pulse
(≈ 4·10⁻¹⁰ arcsec for a 2.14 pulse/arcsec gyro), is far below any physical effect: even a
constant increment that always rounds the same way drifts by at most 2^-31 pulse per sample
(≈ 2·10⁻⁸ °/h at 100 Hz). A block may hold up to 2^33 pulses (≈ 1800 °/s for 600 s at 2.14
pulses/arcsec).
"""

from __future__ import annotations

import numpy as np

#: Fractional bits of the fixed-point phase.
FRACTION_BITS = 30
#: Fixed-point units per pulse.
ONE = 1 << FRACTION_BITS


#: Largest |increment| of one sample [pulses]: a sample's pulses are stored as int32.
MAX_SAMPLE_PULSES = float(2**31 - 2)
#: Largest sum of |increments| of one call [pulses]: the running fixed-point phase is int64
#: (2^33 · 2^30 = 2^63), so one block may hold up to 2^33 pulses in total.
MAX_BLOCK_PULSES = float(2**33 - 2)


def check_range(inc: np.ndarray, scale: float = 1.0) -> None:
    """Refuse increments the counter cannot represent exactly — NaN or infinite, more than
    :data:`MAX_SAMPLE_PULSES` in one sample or :data:`MAX_BLOCK_PULSES` in one block — with a
    one-line :class:`~rlgsim.ground.errors.UserInputError` (a device preset whose scale factor,
    bias or temperature law gives an absurd rate), instead of wrapping around silently.
    ``scale`` (a power of two) when ``inc`` holds the increments already multiplied by it.

    Fast path: the largest |increment| (two reductions, no temporary); the sum of |increments|
    is computed only when the peak times the count could exceed the block limit."""
    n = inc.size
    if n == 0:
        return
    peak = max(float(inc.max()), -float(inc.min()))          # NaN: both tests below fail
    if peak <= MAX_SAMPLE_PULSES * scale and peak * n <= MAX_BLOCK_PULSES * scale:
        return
    total = float(np.abs(inc).sum()) / scale                # exact: scale is a power of two
    peak = float(np.abs(inc).max()) / scale
    if total <= MAX_BLOCK_PULSES and peak <= MAX_SAMPLE_PULSES:
        return
    from rlgsim.ground.errors import UserInputError

    if not np.isfinite(total):
        raise UserInputError("pulse counter: a sample's phase increment is not finite (NaN or "
                             "infinite); check the device preset's scale factors, biases and "
                             "temperature-law coefficients")
    raise UserInputError(
        f"pulse counter: {peak:.3g} pulses in one sample ({total:.3g} in one block) cannot be "
        f"counted: at most {MAX_SAMPLE_PULSES:.3g} per sample and {MAX_BLOCK_PULSES:.3g} per "
        f"block are allowed; check the device preset's scale factors, biases and "
        f"temperature-law coefficients and the turntable rates")


def quantise(inc: np.ndarray) -> np.ndarray:
    """Fixed-point phase increments rint(inc·2^30) as int64 (``inc`` float64 [pulses],
    overwritten); increments out of the counter's range are refused (:func:`check_range`)."""
    check_range(inc)
    np.multiply(inc, float(ONE), out=inc)
    np.rint(inc, out=inc)
    return inc.astype(np.int64)


def count_fixed(q: np.ndarray, remainder: int, out: np.ndarray | None = None
                ) -> tuple[np.ndarray, int]:
    """Pulses (n,) int32 and the new remainder for fixed-point increments ``q`` (n,) int64
    (overwritten) and the carried ``remainder`` ∈ [0, 2^30); ``out`` (n,) int32 (may be a
    strided column of a larger array) receives the pulses when given."""
    n = q.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int32), int(remainder)
    q[0] += remainder
    np.cumsum(q, out=q)                                # Φ_j
    last = int(q[-1])
    np.right_shift(q, FRACTION_BITS, out=q)            # c_j
    pulses = np.empty(n, dtype=np.int32) if out is None else out
    np.subtract(q[1:], q[:-1], out=pulses[1:], casting="unsafe")
    pulses[0] = q[0]
    return pulses, last - (int(q[-1]) << FRACTION_BITS)


def count_scaled(scaled: np.ndarray, remainder: int, out: np.ndarray | None = None
                 ) -> tuple[np.ndarray, int]:
    """:func:`count_fixed` of increments given already multiplied by :data:`ONE` (float64,
    overwritten): the same pulses as ``count_fixed(quantise(inc), remainder)`` when
    ``scaled = inc·2^30`` — a product with a power of two is exact, so a caller can fold
    2^30 into its last multiplication (the scale factor) and save a pass over the samples."""
    check_range(scaled, float(ONE))
    np.rint(scaled, out=scaled)
    return count_fixed(scaled.astype(np.int64), remainder, out)


def count(inc: np.ndarray, remainder: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pulses (n, C) int32 and new remainders (C,) int64 for float64 increments ``inc`` (n, C)
    [pulses] and carried remainders (C,) int64 in [0, 2^30) (see the module docstring)."""
    n, c = inc.shape
    out = np.empty((n, c), dtype=np.int32)
    new = np.zeros(c, dtype=np.int64)
    for s in range(c):
        q = quantise(np.array(inc[:, s], dtype=float))
        out[:, s], new[s] = count_fixed(q, int(remainder[s]))
    return out, new


def total_phase(remainder: np.ndarray, pulses_so_far: np.ndarray) -> np.ndarray:
    """The accumulated phase [pulses] from the pulse total and the carried remainder."""
    return np.asarray(pulses_so_far, dtype=float) + np.asarray(remainder, dtype=float) / ONE
