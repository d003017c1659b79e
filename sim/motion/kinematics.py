"""Exact sensor inputs on the turntable: angle and velocity increments per sample interval.

For sample ``k`` at rate ``f`` (interval [k/f, (k+1)/f), time coordinate (k+1)/f):

    Δθ_k = ∫ ω_ib^b dt,   ω_ib^b(t) = ω_nb^b(t) + C_n^b(t) ω_ie^n           [rad]
    Δv_k = ∫ f^b dt,      f^b(t)    = C_n^b(t) f^n,   f^n = (0, 0, γ)          [m/s]

with ω_nb^b the table rate in body axes, ω_ie^n the Earth rate in ENU and γ the normal gravity
at the site (:mod:`rlgsim.sim.motion.site`, :mod:`rlgsim.ground.earth`); C_b^n is the table's gimbal
convention R_x(outer) R_z(inner) (:func:`rlgsim.ground.frames.body_to_enu`). The navigation
frame is ENU at the site and the table does not translate, so the transport rate is zero; the
IMU's measurement origin is taken to be **at the intersection of the table axes (no lever
arm)**, so rotations add no centripetal or tangential acceleration and the specific force is
exactly −gravity in body axes.

Closed form. During a turntable motion the body turns at the constant rate w about an axis u that
is fixed in the body (:mod:`rlgsim.sim.motion.turntable`), so with C_0 = C_b^n at the motion's start and τ the
time since it (Rodrigues; Titterton & Weston 2004, eq. 11.2):

    C_n^b(τ) = R(u, −wτ) C_0^T,   R(u, α) = I + sin α [u×] + (1 − cos α)[u×]²

and for any constant navigation-frame vector x^n with a = C_0^T x^n:

    ∫_{τa}^{τb} C_n^b x^n dτ = Δ a + s_1 (u × a) + s_2 u × (u × a)
    s_1 = (cos wτ_b − cos wτ_a)/w = −2 sin(w τ_m) sin(w h)/w
    s_2 = Δ − (sin wτ_b − sin wτ_a)/w = Δ − 2 cos(w τ_m) sin(w h)/w

(Δ = τ_b − τ_a, h = Δ/2, τ_m = (τ_a + τ_b)/2; the product forms avoid cancellation; w = 0
gives s_1 = s_2 = 0 exactly). The table part is simply w u Δ. A sample interval that straddles
a motion boundary is split at the boundary and the pieces are summed, so the increments are the
exact integrals (to rounding), not rate × Δt.

Vectorised over samples; the only Python loop runs over the motions that touch a block. In a
long run (numba loaded) the windows of turning and straddling samples are computed by one
compiled call each (:mod:`rlgsim.sim.motion._kinematics_kernel`: the same numbers, checked
against this module's NumPy path once per process).

Why this file is over 400 lines: it is one model, the exact kinematics of the table on the
rotating Earth (segments, their angles and the closed-form increments over any sample grid,
with the runs at rest found on the way); the programme reader is apart (turntable.py) and a
vehicle's kinematics too (trajectory.py).
"""

from __future__ import annotations

import bisect
import sys
from dataclasses import dataclass
from functools import cached_property
from collections.abc import Mapping
from typing import Any, Iterable

import numpy as np

from rlgsim.ground.frames import body_axis, body_to_enu
from rlgsim.ground.units import DEG
from rlgsim.sim.motion.site import Site
from rlgsim.sim.motion.turntable import TurntableProgram

_TIME_TOL_S = 1e-6
_ANGLE_TOL_DEG = 1e-6


@dataclass(frozen=True)
class TurntableSegment:
    """A turntable motion placed on the run's time axis (what the timeline's "turntable" track
    holds): ``t0_s``/``t1_s`` [s], ``track`` = "turntable", ``label``, ``attrs`` = the
    :class:`~rlgsim.sim.motion.turntable.TableMotion` fields (``kind``, ``axis``, ``rate_deg_s``,
    ``outer_deg``, ``inner_deg`` at ``t0_s``, ``position``, ``window``, ...)."""

    t0_s: float
    t1_s: float
    track: str
    label: str
    attrs: Mapping[str, Any]


def segments_from_program(program: TurntableProgram, duration_s: float
                          ) -> list[TurntableSegment]:
    """Lay a programme's motions back to back on [0, duration_s] (for standalone use and tests;
    the run's timeline comes from :mod:`rlgsim.sim.run.schedule`)."""
    out: list[TurntableSegment] = []
    t = 0.0
    for m in program.motions(until_s=duration_s):
        out.append(TurntableSegment(t, t + m.duration_s, "turntable", m.label, m.attrs()))
        t += m.duration_s
    return out


@dataclass
class MotionBlock:
    """Exact inputs for ``n`` samples: ``dtheta_rad`` (n, 3) = ∫ω_ib^b dt [rad],
    ``dv_m_per_s`` (n, 3) = ∫f^b dt [m/s], table angles at each sample's end ``outer_deg``,
    ``inner_deg`` (n,) [°, in [0, 360)], ``segment`` (n,) index of the motion in which each
    sample interval ends; ``first_sample`` k0 and ``rate_hz`` f place sample j on the run's
    grid, [(k0 + j)/f, (k0 + j + 1)/f); ``constant`` the runs ``(lo, hi)`` of whole samples at
    rest inside one static motion: samples lo..hi−1 hold one increment, bit for bit, except
    in the :attr:`unwritten` runs (other samples may share theirs too); ``states`` a vehicle's
    truth at the sample ends when it was computed with the block (:meth:`rlgsim.sim.motion.trajectory.Trajectory.truth`), else None."""

    dtheta_rad: np.ndarray
    dv_m_per_s: np.ndarray
    outer_deg: np.ndarray | None
    inner_deg: np.ndarray | None
    segment: np.ndarray | None
    first_sample: int = 0
    rate_hz: float = 1.0
    constant: tuple[tuple[int, int], ...] = ()
    states: dict[str, np.ndarray] | None = None
    #: runs ``(lo, hi)`` of samples inside :attr:`constant` runs whose increments were NOT
    #: written (:meth:`Motion.increments` with ``held_steps``): their rows of ``dtheta_rad``
    #: and ``dv_m_per_s`` hold whatever the memory held; each lies in a ``constant`` run whose
    #: first samples were written, and holds their increment
    unwritten: tuple[tuple[int, int], ...] = ()
    #: (6, n): rows 0-2 ``dtheta_rad.T``, rows 3-5 ``dv_m_per_s.T`` when both are views of one
    #: array (:meth:`Motion.increments`), so a per-row reduction of both is one call; else None
    both: np.ndarray | None = None

    @cached_property
    def t_s(self) -> np.ndarray:
        """(n,) sample end times [s], (k0 + j + 1)/f."""
        return self.end_times(np.arange(self.dtheta_rad.shape[0]))

    def end_times(self, j: np.ndarray) -> np.ndarray:
        """End times [s] of samples ``j``: element by element :attr:`t_s` ``[j]``."""
        return _edges(self.first_sample, np.asarray(j) + 1, self.rate_hz)

    def attitude(self) -> np.ndarray:
        """True attitude C_b^n (body → ENU) at each sample's end, (n, 3, 3)."""
        return body_to_enu(self.outer_deg, self.inner_deg)


def _edges(k0: int, j: np.ndarray | int, rate_hz: float) -> np.ndarray:
    """Sample edges (k0 + j)/f [s] of the grid (the start of sample j; ``k0 + j`` exact in
    float64 below 2^53), element by element the values of ``(k0 + arange(n + 1))/f``."""
    return (k0 + np.asarray(j, dtype=float)) / rate_hz


def _written(lo: int, hi: int, r: int, unwritten: list[tuple[int, int]]
             ) -> list[tuple[int, int]]:
    """The parts of the fill run of samples [lo, hi) that :meth:`Motion.increments` writes
    when a reader of whole steps of ``r`` samples (``r`` > 0) at rest reads only the first
    step of each run of them: everything but the whole steps after the first whole step
    (those are appended to ``unwritten``); ``r`` = 0: all of it."""
    s0, s1 = -(-lo // r) if r > 0 else 0, hi // r if r > 0 else 0
    if s1 - s0 < 2:
        return [(lo, hi)]
    unwritten.append(((s0 + 1) * r, s1 * r))
    return [(lo, (s0 + 1) * r), (s1 * r, hi)]


#: Values assumed when a static segment omits a field (e.g. a bare {"kind": "static"} mount).
_STATIC_DEFAULTS = {"axis": None, "rate_deg_s": 0.0, "outer_deg": 0.0, "inner_deg": 0.0}


def _field(seg: Any, name: str) -> Any:
    attrs = getattr(seg, "attrs", None)
    if type(attrs) is dict:                       # a timeline segment's: no ABC checks
        if name in attrs:
            return attrs[name]
        if hasattr(seg, name):                    # its t0_s, t1_s
            return getattr(seg, name)
    elif isinstance(attrs, Mapping) and name in attrs:
        return attrs[name]
    if isinstance(seg, Mapping) and name in seg:
        return seg[name]
    if hasattr(seg, name):
        return getattr(seg, name)
    if name in _STATIC_DEFAULTS and _field(seg, "kind") == "static":
        return _STATIC_DEFAULTS[name]
    raise ValueError(f"turntable segment {seg!r} has no {name!r}")


_window_kernel: list = []


def _compiled_window() -> Any:
    """:func:`rlgsim.sim.motion._kinematics_kernel.exact_window` when it gives
    :meth:`Motion._exact`'s numbers in this process (compared once on a fixed programme with
    turns, boundaries between sample edges and a zero-length motion), else None."""
    if not _window_kernel:
        try:
            from rlgsim.sim.motion._kinematics_kernel import exact_window
            _window_kernel.append(exact_window if _agrees(exact_window) else None)
        except ImportError:                     # pragma: no cover - numba is a dependency
            _window_kernel.append(None)
    return _window_kernel[0]


def _agrees(kernel: Any) -> bool:
    """Whether ``kernel`` gives :meth:`Motion._exact`'s bits on a fixed programme."""
    static = {"kind": "static", "axis": None, "rate_deg_s": 0.0, "inner_deg": 0.0}
    turn = {"kind": "rotate", "axis": "outer", "rate_deg_s": 7.3, "inner_deg": 0.0}
    segs = [TurntableSegment(0.0, 1.013, "turntable", "a", {**static, "outer_deg": 10.0}),
            TurntableSegment(1.013, 13.5, "turntable", "b", {**turn, "outer_deg": 10.0}),
            TurntableSegment(13.5, 13.5, "turntable", "c",
                             {**static, "outer_deg": 10.0 + 7.3 * 12.487}),
            TurntableSegment(13.5, 20.0, "turntable", "d",
                             {**turn, "outer_deg": 10.0 + 7.3 * 12.487, "axis": "inner"})]
    mo = Motion(segs)
    for rate_hz, k0, n in ((100.0, 0, 2100), (7.3, 3, 150), (1000.0, 13_400, 200)):
        dth, dv = np.empty((3, n)), np.empty((3, n))
        done = kernel(k0, n, rate_hz, mo._t0, mo._rate, mo._coef["w"][0], mo._coef["f"][0],
                      mo._turn["w"], mo._turn["f"], dth, dv, 0)
        ref = mo._exact(k0, n, rate_hz)
        if not done:
            return False
        if not all(np.array_equal(x.view(np.int64), np.ascontiguousarray(r.T).view(np.int64))
                   for x, r in zip((dth, dv), ref)):
            return False
    return True


class Motion:
    """Exact kinematics of the IMU on the turntable at ``site``.

    ``segments``: the timeline's turntable segments in time order (objects with ``t0_s``,
    ``t1_s`` and the :class:`~rlgsim.sim.motion.turntable.TableMotion` fields either as attributes or in an
    ``attrs`` mapping; segments whose ``track`` is not "turntable" are skipped, so the whole
    timeline may be passed). They must be contiguous, and each must start at the angles where the
    previous one ended. After the last segment the table is held static at its final angles.
    A static segment may omit ``axis``, ``rate_deg_s`` and the angles (then 0°, 0°).
    """

    #: compute the windows of :meth:`increments` with the compiled kernel
    #: (:mod:`rlgsim.sim.motion._kinematics_kernel`: the same numbers) — None: when numba is
    #: already loaded in this process (a short run does not import it for this)
    compiled: bool | None = None

    def __init__(self, segments: Iterable[Any], site: Site | None = None) -> None:
        self.site = site if site is not None else Site()
        segs = [s for s in segments if getattr(s, "track", "turntable") == "turntable"]
        if not segs:
            raise ValueError("no turntable segments")
        t0 = np.array([float(_field(s, "t0_s")) for s in segs])
        t1 = np.array([float(_field(s, "t1_s")) for s in segs])
        kind = [_field(s, "kind") for s in segs]
        axis = [_field(s, "axis") for s in segs]
        rate = np.array([float(_field(s, "rate_deg_s")) if k == "rotate" else 0.0
                         for s, k in zip(segs, kind)])
        outer = np.array([float(_field(s, "outer_deg")) for s in segs])
        inner = np.array([float(_field(s, "inner_deg")) for s in segs])
        for j, (k, a) in enumerate(zip(kind, axis)):
            if k not in ("static", "rotate") or (k == "rotate" and a not in ("outer", "inner")):
                raise ValueError(f"turntable segment {j}: bad kind/axis {k!r}/{a!r}")
        if np.any(t1 < t0):
            raise ValueError("turntable segment ends before it starts")
        gaps = np.abs(t0[1:] - t1[:-1])
        if gaps.size and gaps.max() > _TIME_TOL_S:
            j = int(np.argmax(gaps))
            raise ValueError(f"turntable segments {j} and {j + 1} are not contiguous "
                             f"({t1[j]!r} s vs {t0[j + 1]!r} s)")
        # angles at the end of each segment must be where the next one starts
        dur = t1 - t0
        end_o = outer + np.where([a == "outer" for a in axis], rate * dur, 0.0)
        end_i = inner + np.where([a == "inner" for a in axis], rate * dur, 0.0)
        for name, end, start in (("outer", end_o[:-1], outer[1:]), ("inner", end_i[:-1], inner[1:])):
            d = np.abs((end - start + 180.0) % 360.0 - 180.0)
            if d.size and d.max() > _ANGLE_TOL_DEG:
                j = int(np.argmax(d))
                raise ValueError(f"turntable segment {j + 1} starts at {name} = {start[j]:g}° "
                                 f"but segment {j} ends at {end[j] % 360:g}°")
        # a final static segment holding the last angles to +∞
        self.n_segments = len(segs)
        self._t0 = np.append(t0, t1[-1])
        self._rate = np.append(rate * DEG, 0.0)                     # rad/s
        self._rate_deg = np.append(rate, 0.0)
        self._axis = list(axis) + [None]
        self._is_outer = np.array([a == "outer" for a in self._axis])
        self._outer0 = np.append(outer, end_o[-1] % 360.0)
        self._inner0 = np.append(inner, end_i[-1] % 360.0)
        m = len(self._t0)
        c0 = body_to_enu(self._outer0, self._inner0)                  # (m, 3, 3) C_b^n
        self._u = np.stack([body_axis(a, i) for a, i in zip(self._axis, self._inner0)])
        # per segment: a, u×a, u×(u×a) for Earth rate and specific force
        self._coef = {}
        for key, vec in (("w", self.site.earth_rate_enu), ("f", self.site.specific_force_enu)):
            a = np.einsum("mji,j->mi", c0, vec)                       # C_0^T x^n
            ua = np.cross(self._u, a)
            self._coef[key] = (a, ua, np.cross(self._u, ua))
        # the (3, 3) factors of a turn's closed form per segment (what _integrate multiplies)
        self._turn = {key: np.stack([c[0] + self._rate[:, None] * self._u if key == "w" else c[0],
                                     c[1], c[2]], axis=1)
                      for key, c in self._coef.items()}
        self._sorted = bool(np.all(self._t0[1:] >= self._t0[:-1]))
        #: the starts as floats, for the searches of one or two times (bisect holds the GIL;
        #: numpy's searchsorted releases and retakes it, a hand-off to the other threads)
        self._t0_list = self._t0.tolist()
        self._m = m

    @property
    def end_s(self) -> float:
        """End of the last turntable segment [s]."""
        return float(self._t0[-1])

    def angles(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Table angles (outer, inner) [°, in [0, 360)] at times ``t_s`` and the segment index
        (the segment in which a time ends: a boundary time belongs to the segment ending there).
        """
        t = np.asarray(t_s, dtype=float)
        j = np.clip(self._locate(t, "left") - 1, 0, self._m - 1)
        if t.size and np.min(t) < self._t0[0] - _TIME_TOL_S:
            raise ValueError(f"time {t.min()!r} s is before the first turntable segment "
                             f"({self._t0[0]!r} s)")
        turned = self._rate_deg[j] * (t - self._t0[j])
        is_outer = self._is_outer[j]
        outer = (self._outer0[j] + np.where(is_outer, turned, 0.0)) % 360.0
        inner = (self._inner0[j] + np.where(is_outer, 0.0, turned)) % 360.0
        return outer, inner, np.minimum(j, self.n_segments - 1)

    def _locate(self, t: np.ndarray, side: str) -> np.ndarray:
        """``np.searchsorted(self._t0, t, side)``, in O(n + m log n) for sorted 1-D ``t``."""
        if t.ndim != 1 or t.size < 64 or not self._sorted or np.any(t[1:] < t[:-1]):
            return np.searchsorted(self._t0, t, side=side)
        find = bisect.bisect_left if side == "left" else bisect.bisect_right
        lo, hi = find(self._t0_list, t[0]), find(self._t0_list, t[-1])
        if lo == hi:
            return np.full(t.size, lo, dtype=np.intp)
        # each start t0_k (lo <= k < hi) adds one from the first t it precedes onwards
        first = np.searchsorted(t, self._t0[lo:hi], side="right" if side == "left" else "left")
        step = np.zeros(t.size + 1, dtype=np.intp)
        np.add.at(step, first, 1)
        return lo + np.cumsum(step[:-1])

    def _runs(self, a: np.ndarray) -> list[tuple[int, int, int]]:
        """The maximal runs ``(lo, hi, j)`` of the sorted sub-interval starts ``a`` lying in one
        segment ``j`` — the runs of ``clip(_locate(a, "right") − 1, 0, m − 1)``, found from
        the segment starts inside ``a`` (O(k log n)) instead of a per-sample index array."""
        n = a.size
        lo = bisect.bisect_right(self._t0_list, a[0])     # np.searchsorted(side="right")'s,
        hi = bisect.bisect_right(self._t0_list, a[-1])    # without releasing the GIL
        # sample i lies in segment (lo + number of starts t0_k, lo <= k < hi, with t0_k <= a_i) − 1
        first = np.searchsorted(a, self._t0[lo:hi], side="left").tolist()
        out: list[tuple[int, int, int]] = []
        start, j = 0, max(lo - 1, 0)
        for k, f in enumerate(first):
            nj = max(lo + k, 0)                 # segment from sample f on (clipped at 0)
            if nj == j:
                continue
            if f > start:
                out.append((start, f, j))
            start, j = f, nj
        out.append((start, n, j))
        # clip(·, 0, m − 1): the upper bound never binds (at most m starts are <= a_i)
        return out

    def attitude(self, t_s: np.ndarray) -> np.ndarray:
        """True attitude C_b^n (body → ENU) at times ``t_s``, (…, 3, 3)."""
        o, i, _ = self.angles(t_s)
        return body_to_enu(o, i)

    def increments(self, t0_s: float, n: int, rate_hz: float, *, angles: bool = True,
                   held_steps: int = 0) -> MotionBlock:
        """Exact Δθ and Δv for ``n`` samples at ``rate_hz`` starting at ``t0_s`` (on the grid).

        Sample j covers [(k0 + j)/f, (k0 + j + 1)/f) with k0 = round(t0_s·f).
        ``angles=False`` leaves ``outer_deg``, ``inner_deg`` and ``segment`` None (a caller
        that needs the table at a few sample ends asks :meth:`angles` for those
        :meth:`MotionBlock.end_times`: the same values, element by element).

        The whole samples at rest inside one static motion all hold the product a·(1/f) of
        :meth:`_integrate` and are filled with it; the samples of turning motions and those
        straddling a motion boundary are computed by :meth:`_exact` over windows that hold each
        turning motion's samples whole, so every number is the one the whole-block
        computation gives (tests/test_motion_fill.py compares the two).

        ``held_steps`` = r > 0: a caller that reads a run of whole steps of r samples at rest
        only through its first step (the IMU stage: :func:`rlgsim.sim.sensors.imu._held_steps`)
        has each fill run's samples from its second whole step to its last whole step's end
        left unwritten — ~97 % of paper000's samples, whose 2 × 24 bytes a sample were the
        block's largest memory traffic; they are listed in :attr:`MotionBlock.unwritten`.
        """
        if n < 0 or rate_hz <= 0:
            raise ValueError(f"need n >= 0 and rate_hz > 0, got n={n}, rate_hz={rate_hz}")
        k0 = round(t0_s * rate_hz)
        if abs(k0 - t0_s * rate_hz) > 1e-6:
            raise ValueError(f"t0_s = {t0_s!r} s is not on the {rate_hz:g} Hz sample grid")
        if n == 0:
            both = np.zeros((6, 0))
            return MotionBlock(both[:3].T, both[3:].T, np.zeros(0), np.zeros(0),
                               np.zeros(0, dtype=np.int64), k0, rate_hz, both=both)
        e0, e1 = _edges(k0, np.array([0, n]), rate_hz)
        if e0 < self._t0[0] - _TIME_TOL_S:
            raise ValueError(f"t0_s = {t0_s!r} s is before the first turntable segment")
        # stored axis by axis, (3, n), and handed out as (n, 3) views: each component is one
        # long run and the IMU stage takes the rows it needs without a copy
        both = np.empty((6, n))                 # Δθ and Δv rows in one array (MotionBlock.both)
        dth, dv = both[:3], both[3:]
        fills, windows = self._layout(k0, n, rate_hz, e0, e1)
        unwritten = []
        for lo, hi, j in fills:
            for a, b in _written(lo, hi, held_steps, unwritten):
                dth[:, a:b] = (self._coef["w"][0][j] * (1.0 / rate_hz))[:, None]
                dv[:, a:b] = (self._coef["f"][0][j] * (1.0 / rate_hz))[:, None]
        kernel = _compiled_window() if windows and self._sorted and self.compiled is not False \
            and (self.compiled or "numba" in sys.modules) else None
        for lo, hi in windows:
            if kernel is None or not kernel(    # the same numbers, compiled (nogil)
                    k0 + lo, hi - lo, rate_hz, self._t0, self._rate, self._coef["w"][0],
                    self._coef["f"][0], self._turn["w"], self._turn["f"], dth, dv, lo):
                dth[:, lo:hi], dv[:, lo:hi] = (x.T for x in
                                               self._exact(k0 + lo, hi - lo, rate_hz))
        block = MotionBlock(dth.T, dv.T, None, None, None, k0, rate_hz,
                            tuple((lo, hi) for lo, hi, _ in fills), unwritten=tuple(unwritten),
                            both=both)
        if angles:
            block.outer_deg, block.inner_deg, block.segment = self.angles(block.t_s)
        return block

    def _layout(self, k0: int, n: int, rate_hz: float, e0: float, e1: float
                ) -> tuple[list[tuple[int, int, int]], list[tuple[int, int]]]:
        """How :meth:`increments` computes samples 0..n−1 (edges ``e0``, ``e1``): ``fills``
        ``(lo, hi, j)`` whole samples at rest in static motion ``j``, and ``windows``
        ``(lo, hi)`` for :meth:`_exact` (turning motions with the samples around their ends,
        samples straddling a motion boundary)."""
        inside = self._starts_inside(e0, e1)
        pos = self._first_edge_at(inside, k0, n, rate_hz)          # 1..n, sorted
        straddling = set((pos[_edges(k0, pos, rate_hz) != inside] - 1).tolist())
        # stretches of samples whose starts lie in one motion: from 0 and each boundary's edge
        starts = np.unique(np.concatenate([[0], pos[pos < n]]))
        seg = np.maximum(np.searchsorted(self._t0, _edges(k0, starts, rate_hz), side="right")
                         - 1, 0)
        fills: list[tuple[int, int, int]] = []
        exact: list[tuple[int, int]] = []
        for lo, hi, j in zip(starts.tolist(), [*starts[1:].tolist(), n], seg.tolist()):
            if self._rate[j] != 0.0:
                exact.append((lo, hi))
                continue
            end = hi - 1 if hi - 1 in straddling else hi       # only a stretch's last sample
            if end > lo:
                fills.append((lo, end, j))
            if end < hi:
                exact.append((end, hi))
        windows: list[tuple[int, int]] = []
        for lo, hi in exact:                    # adjacent pieces in one window
            if windows and windows[-1][1] == lo:
                windows[-1] = (windows[-1][0], hi)
            else:
                windows.append((lo, hi))
        return fills, windows

    def _starts_inside(self, lo: float, hi: float) -> np.ndarray:
        """The segment starts t with lo < t < hi, in order (two binary searches when the
        starts are sorted, as a timeline's are)."""
        if not self._sorted:
            return self._t0[(self._t0 > lo) & (self._t0 < hi)]
        i = bisect.bisect_right(self._t0_list, lo)      # np.searchsorted's, without
        k = bisect.bisect_left(self._t0_list, hi)       # releasing the GIL
        return self._t0[i:k]

    @staticmethod
    def _first_edge_at(t: np.ndarray, k0: int, n: int, rate_hz: float) -> np.ndarray:
        """For times ``t`` strictly inside (edge 0, edge n): the index of the first edge ≥ t,
        ``np.searchsorted(edges, t)`` without the n + 1 edges."""
        p = np.clip(np.ceil(t * rate_hz) - k0, 1, n).astype(np.int64)
        for _ in range(4):                      # t·f is within an ulp or two of the answer
            high = _edges(k0, p - 1, rate_hz) >= t
            low = _edges(k0, p, rate_hz) < t
            if not (high.any() or low.any()):
                return p
            p = np.clip(p - high + low, 1, n)
        return np.searchsorted(_edges(k0, np.arange(n + 1), rate_hz), t)

    def _exact(self, k0: int, n: int, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """Δθ, Δv (n, 3) of samples k0..k0+n−1 of the ``rate_hz`` grid (n ≥ 1), each
        sample interval split at the motion boundaries inside it and its pieces summed."""
        edges = _edges(k0, np.arange(n + 1), rate_hz)
        # split sample intervals at the segment boundaries inside the block
        inside = self._starts_inside(edges[0], edges[-1])
        if inside.size:
            pos = np.searchsorted(edges, inside)
            inside = inside[edges[pos] != inside]
            where = np.searchsorted(edges, inside)
            pts = np.insert(edges, where, inside)
            is_edge = np.insert(np.ones(n + 1, dtype=bool), where, False)
        else:
            pts = edges
            is_edge = None
        a, b = pts[:-1], pts[1:]
        # a whole sample lasts exactly 1/f (b − a would carry the rounding of t, ~eps·t)
        delta = np.full(a.size, 1.0 / rate_hz)
        if is_edge is not None:
            split = ~(is_edge[:-1] & is_edge[1:])
            delta[split] = b[split] - a[split]
        dth = np.empty((3, a.size)).T
        dv = np.empty((3, a.size)).T
        for lo, hi, j in self._runs(a):
            self._integrate(j, a[lo:hi], delta[lo:hi], dth[lo:hi], dv[lo:hi])
        if inside.size:
            first = np.searchsorted(pts[:-1], edges[:-1])
            dth = np.add.reduceat(dth, first, axis=0)
            dv = np.add.reduceat(dv, first, axis=0)
        return dth, dv

    def _integrate(self, j: int, a: np.ndarray, delta: np.ndarray, dth: np.ndarray,
                   dv: np.ndarray) -> None:
        """Fill ∫ω_ib^b and ∫f^b over the sub-intervals [a, a + delta) lying in segment ``j``."""
        w = self._rate[j]
        if w == 0.0:
            aw = self._coef["w"][0][j]
            af = self._coef["f"][0][j]
            np.multiply(aw[:, None], delta, out=dth.T)
            np.multiply(af[:, None], delta, out=dv.T)
            return
        ts = self._t0[j]
        h = 0.5 * delta
        tm = (a - ts) + h
        sw = np.sin(w * h) / w
        wm = w * tm
        s1 = -2.0 * np.sin(wm) * sw
        s2 = delta - 2.0 * np.cos(wm) * sw
        coef = np.stack([delta, s1, s2], axis=1)                       # (k, 3)
        # einsum: a tall (k, 3) × (3, 3) product through BLAS is 10× slower; the factors are
        # (a_w + w·u, u×a_w, u×(u×a_w)) and (a_f, u×a_f, u×(u×a_f)) stacked as rows
        dth[:] = np.einsum("kj,ji->ki", coef, self._turn["w"][j])
        dv[:] = np.einsum("kj,ji->ki", coef, self._turn["f"][j])
