"""Free-inertial navigation scores: what a compensator buys in position and heading.

On a dataset or a recording (:mod:`rlgsim.lab.navigation_source`), the IMU is aligned on its
first static segment (:func:`rlgsim.estimators.ins.align`: coarse levelling + gyrocompassing,
then the zero-velocity Kalman filter) and navigates free-inertially for the rest of the run (or
a stated span) with the height held at the site's (:mod:`rlgsim.estimators.ins`). Variants:

* ``raw``: the pulses through the nominal pulse weights;
* one per compensator: the raw increments minus the compensator's gyro-bias prediction
  (the studies' compensators model the gyro bias; the accelerometers stay raw);
* ``oracle (gyros)``: minus the true temperature law of the gyro biases (the truth group's
  ``gyro_bias − gyro_bias_random``) — the best a gyro compensator can do;
* ``oracle``: the laws of the gyro *and* accelerometer biases removed;
* ``truth``: the exact increments of the motion (the mechanization's numerical floor).

Every variant aligns on its own data, as an INS does (an East gyro bias left in the data turns
the heading by ε_E/(Ω cos L) at alignment: the ``heading bound`` column is that figure for the
variant's residual East bias over the alignment, when the truth is known).

Scores (per variant): horizontal position error at 1 h and at the end of the span, radial error
rate (least-squares slope through the origin of the horizontal error against time, nmi/h),
horizontal velocity error RMS, heading error after alignment and at the end. The site does not
move (turntable or bench), so the true position is the site and the true velocity zero.
"""

from __future__ import annotations

import math
import os
from typing import Any, Callable, Mapping

import numpy as np

from rlgsim.estimators.ins import align, attitude_error, heading_error_bound, integrate
from rlgsim.ground.earth import radii_of_curvature
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.frames import quat_to_dcm
from rlgsim.ground.units import ARCMIN, DEG, HOUR, MICRO_G, NAUTICAL_MILE
from rlgsim.lab.navigation_source import NavSource, open_source

#: the fine alignment's measurement interval [s] (zero-velocity updates over ≤ 600 s)
ALIGN_STEP_S = 5.0

ModelPrediction = np.ndarray | Callable[[np.ndarray], np.ndarray]


def _corrections(src: NavSource, models: Mapping[str, ModelPrediction] | None
                 ) -> dict[str, Callable[[int, int], tuple[np.ndarray | None, np.ndarray | None]]]:
    """variant → f(k0, k1) giving (gyro, accel) bias rates [rad/s, m/s²] (m, 3) to subtract."""
    out: dict[str, Callable] = {"raw": lambda k0, k1: (None, None)}
    for name, pred in (models or {}).items():
        if callable(pred):
            out[name] = (lambda p: lambda k0, k1: (np.asarray(
                p((np.arange(k0, k1) + 0.5) / src.rate_hz), float), None))(pred)
        else:
            arr = np.asarray(pred, dtype=float)
            if src.law_gyro is None or arr.shape != src.law_gyro.shape:
                raise UserInputError(f"model {name!r}: a prediction array must have the "
                                     f"dataset's thermal-step shape (steps, 3)")
            out[name] = (lambda a: lambda k0, k1: (a[src.step_index(k0, k1)], None))(arr)
    if src.law_gyro is not None:
        out["oracle (gyros)"] = lambda k0, k1: (src.law_gyro[src.step_index(k0, k1)], None)
    if src.law_gyro is not None and src.law_accel is not None:
        out["oracle"] = lambda k0, k1: (src.law_gyro[src.step_index(k0, k1)],
                                        src.law_accel[src.step_index(k0, k1)])
    return out


def _other(src: NavSource, name: str, spec: Mapping[str, Any], a0: int, end: int) -> Callable:
    """A variant whose pulses come from another dataset on the same sample grid (e.g. a
    compensated copy), minus constant biases ``gyro_bias`` [rad/s] / ``accel_bias`` [m/s²];
    refused if it lost a sample of the navigated span a0..end−1."""
    other = open_source(spec["path"])
    src.closers.append(other.close)
    if other.n != src.n or other.rate_hz != src.rate_hz:
        raise UserInputError(f"variant {name!r}: {other.name} has {other.n} samples at "
                             f"{other.rate_hz:g} Hz; {src.name} has {src.n} at {src.rate_hz:g} Hz")
    other.refuse_lost(a0, end)
    bg = np.asarray(spec.get("gyro_bias", np.zeros(3)), float)
    ba = np.asarray(spec.get("accel_bias", np.zeros(3)), float)

    def corr(k0: int, k1: int, pulses=None):
        return ("pulses", other.read(k0, k1), bg, ba)
    return corr


def _increments(src: NavSource, k0: int, k1: int, corr, pulses, truth
                ) -> tuple[np.ndarray, np.ndarray]:
    if corr is None:
        return truth
    ng, na = pulses
    c = corr(k0, k1)
    if len(c) == 4:                                     # pulses of another dataset
        (ng, na), bg, ba = c[1], c[2], c[3]
        return ng * src.gyro_weight - bg * src.dt, na * src.accel_weight - ba * src.dt
    dth, dv = ng * src.gyro_weight, na * src.accel_weight
    bg, ba = c
    if bg is not None:
        dth = dth - bg * src.dt
    if ba is not None:
        dv = dv - ba * src.dt
    return dth, dv


def _rms_smooth(r: np.ndarray, every: int, rate: float, window_s: float = 100.0) -> float:
    """RMS of |r| (m, 3) after averaging over ``window_s`` (the bias the navigation feels,
    the white noise averaged out)."""
    w = max(1, int(round(window_s * rate / every)))
    m = r.shape[0] // w * w
    if m == 0:
        return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))
    rw = r[:m].reshape(-1, w, 3).mean(axis=1)
    return float(np.sqrt(np.mean(np.sum(rw ** 2, axis=1))))


def _span(src: NavSource, span_s: float | None, align_s: float, every: int
          ) -> tuple[int, int, int]:
    """Sample indices: alignment start and end, navigation end (module docstring)."""
    rate, dt = src.rate_hz, src.dt
    a0 = src.start
    a1 = min(src.static_end, a0 + int(round(align_s * rate)))
    if (a1 - a0) * dt < 60.0:
        raise UserInputError(f"{src.name}: the first static segment after power-on holds "
                             f"{(a1 - a0) * dt:g} s; the alignment needs at least 60 s")
    if span_s is not None and not (math.isfinite(float(span_s)) and float(span_s) > 0):
        raise UserInputError(f"span_s = {span_s!r}; need a finite span > 0 s")
    end = src.n if span_s is None else a1 + int(round(float(span_s) * rate))
    if end > src.n:
        raise UserInputError(f"{src.name}: span {span_s} s after the alignment ends at "
                             f"{end * dt:g} s, past the end of the data ({src.n * dt:g} s)")
    end = a1 + (end - a1) // every * every
    if end <= a1:
        raise UserInputError(f"{src.name}: nothing left to navigate after the alignment "
                             f"({a1 * dt:g} s of {src.n * dt:g} s; it takes the first static "
                             f"segment after power-on, at most align_s = {align_s:g} s)")
    src.refuse_lost(a0, end)                           # a dropout after the span is no matter
    return a0, a1, end


def _align_all(src: NavSource, variants: dict, a0: int, a1: int) -> tuple[dict, dict, dict]:
    """Align every variant on samples a0..a1−1: start states, heading error after alignment
    and the heading bound of its residual East gyro error [rad]."""
    dt = src.dt
    pulses = src.read(a0, a1)
    truth = src.truth(a0, a1) if src.truth is not None else None
    c_true_a1 = src.attitude(np.array([a1 * dt]))[0]
    c_mid = src.attitude(np.array([0.5 * (a0 + a1) * dt]))[0]
    states, psi_align, bound = {}, {}, {}
    for v, corr in variants.items():
        dth, dv = _increments(src, a0, a1, corr, pulses, truth)
        al = align(dth, dv, dt, src.latitude_deg, 0.0, src.height_m, step_s=ALIGN_STEP_S)
        states[v] = al.state
        psi_align[v] = attitude_error(al.c_bn, c_true_a1)[2]
        bound[v] = math.nan
        if truth is not None:
            resid_b = (dth - truth[0]).mean(axis=0) / dt               # residual gyro rate, body
            bound[v] = -heading_error_bound(float((c_mid @ resid_b)[0]), src.latitude_deg)
    return states, psi_align, bound


def _run_all(src: NavSource, variants: dict, states: dict, a1: int, end: int, every: int,
             chunk_s: float) -> tuple[dict, dict, str]:
    """Navigate every variant chunk by chunk from a1 to end: outputs and residual rates."""
    rate, dt = src.rate_hz, src.dt
    step = max(every, int(round(chunk_s * rate)) // every * every)
    out = {v: {"lat": [], "lon": [], "v": [], "q": []} for v in variants}
    resid = {v: [[], []] for v in variants}            # residual gyro / accel rate per output
    vertical = ""
    for k0 in range(a1, end, step):
        k1 = min(end, k0 + step)
        pulses = src.read(k0, k1)
        truth = src.truth(k0, k1) if src.truth is not None else None
        for v, corr in variants.items():
            dth, dv = _increments(src, k0, k1, corr, pulses, truth)
            if truth is not None:
                m = (k1 - k0) // every * every
                for j, (x, y) in enumerate(((dth, truth[0]), (dv, truth[1]))):
                    resid[v][j].append((x[:m] - y[:m]).reshape(-1, every, 3).mean(axis=1) / dt)
            sol = integrate(states[v], dth, dv, dt, output_every=every)
            states[v] = sol.final
            vertical = sol.vertical
            for key, val in (("lat", sol.lat), ("lon", sol.lon), ("v", sol.v), ("q", sol.q)):
                out[v][key].append(val)
    return out, resid, vertical


def _errors(src: NavSource, out: dict, t: np.ndarray) -> dict[str, np.ndarray]:
    """(variant, time) error series: north, east [m], velocity E, N [m/s], heading [′]."""
    c_true = src.attitude(t)
    r_m, r_e = radii_of_curvature(src.latitude_deg)
    lat0 = src.latitude_deg * DEG
    cols: dict[str, list] = {k: [] for k in ("north", "east", "ve", "vn", "head")}
    for o in out.values():
        lat, lon = np.concatenate(o["lat"]), np.concatenate(o["lon"])
        vel, q = np.concatenate(o["v"]), np.concatenate(o["q"])
        cols["north"].append((lat - lat0) * (r_m + src.height_m))
        cols["east"].append(lon * (r_e + src.height_m) * math.cos(lat0))
        cols["ve"].append(vel[:, 0])
        cols["vn"].append(vel[:, 1])
        cols["head"].append(attitude_error(quat_to_dcm(q), c_true)[:, 2] / ARCMIN)
    return {k: np.array(v) for k, v in cols.items()}


def navigate_source(src: NavSource, *, models: Mapping[str, ModelPrediction] | None = None,
                    others: Mapping[str, Mapping[str, Any]] | None = None,
                    span_s: float | None = None, align_s: float = 600.0,
                    output_s: float = 1.0, chunk_s: float = 3600.0):
    """Navigate every variant (module docstring); returns an :class:`xarray.Dataset`."""
    import xarray as xr
    rate, dt = src.rate_hz, src.dt
    every = max(1, int(round(output_s * rate)))
    a0, a1, end = _span(src, span_s, align_s, every)
    variants = _corrections(src, models)
    for name, spec in (others or {}).items():
        variants[name] = _other(src, name, spec, a0, end)
    if others:                                          # keep raw, the others, then the rest
        order = ["raw", *others, *[v for v in variants if v != "raw" and v not in others]]
        variants = {v: variants[v] for v in order}
    if src.truth is not None:
        variants["truth"] = None
    names = list(variants)
    states, psi_align, bound = _align_all(src, variants, a0, a1)
    out, resid, vertical = _run_all(src, variants, states, a1, end, every, chunk_s)
    t = (a1 + np.arange(1, (end - a1) // every + 1) * every) / rate
    e = _errors(src, out, t)
    dims = ("variant", "time")
    horiz = np.hypot(e["north"], e["east"])
    data: dict[str, Any] = {
        "north_error_m": (dims, e["north"], {"units": "m"}),
        "east_error_m": (dims, e["east"], {"units": "m"}),
        "horizontal_error_m": (dims, horiz, {"units": "m"}),
        "velocity_error_east_m_s": (dims, e["ve"], {"units": "m s-1"}),
        "velocity_error_north_m_s": (dims, e["vn"], {"units": "m s-1"}),
        "heading_error_arcmin": (dims, e["head"], {"units": "arcmin"})}
    tn = t - a1 * dt
    i1h = np.searchsorted(tn, HOUR - 1e-9)
    summary = {"error_1h_m": horiz[:, i1h] if i1h < tn.size else np.full(len(names), np.nan),
               "error_end_m": horiz[:, -1],
               "radial_error_rate_nmi_per_h": (horiz @ tn) / (tn @ tn) * HOUR / NAUTICAL_MILE,
               "velocity_error_rms_m_s": np.sqrt(np.mean(e["ve"] ** 2 + e["vn"] ** 2, axis=1)),
               "heading_error_align_arcmin": np.array([psi_align[v] / ARCMIN for v in names]),
               "heading_bound_arcmin": np.array([bound[v] / ARCMIN for v in names]),
               "heading_error_end_arcmin": e["head"][:, -1]}
    if src.truth is not None:
        for j, (key, unit) in enumerate((("residual_gyro_error_deg_h", DEG / HOUR),
                                         ("residual_accel_error_ug", MICRO_G))):
            summary[key] = np.array([_rms_smooth(np.concatenate(resid[v][j]), every, rate)
                                     / unit for v in names])
    for key, val in summary.items():
        data[key] = (("variant",), np.asarray(val, float))
    return xr.Dataset(data, coords={"variant": names, "time": ("time", t, {"units": "s"})},
                      attrs={"source": src.name, "latitude_deg": src.latitude_deg,
                             "height_m": src.height_m, "vertical_channel": vertical,
                             "align_start_s": a0 * dt, "align_end_s": a1 * dt,
                             "navigation_end_s": end * dt,
                             "compensation": "compensators correct the gyros; the "
                                             "accelerometers stay raw (oracle: both laws)"})


def navigate(source: str | os.PathLike, *, models: Mapping[str, ModelPrediction] | None = None,
             others: Mapping[str, Mapping[str, Any]] | None = None,
             span_s: float | None = None, align_s: float = 600.0, output_s: float = 1.0):
    """Align and navigate a dataset or recording (module docstring) → :class:`xarray.Dataset`
    with the error time series (dims variant, time) and the scores per variant.

    ``models``: name → the gyro-bias prediction [rad/s], either an array (steps, 3) on the
    dataset's thermal grid or a function of the sample mid-times [s] returning (m, 3);
    ``others``: name → {"path": a dataset on the same sample grid (e.g. compensated pulses),
    "gyro_bias": (3,) rad/s, "accel_bias": (3,) m/s² subtracted as constants};
    ``span_s`` [s] navigation span after the alignment (default: the rest of the run);
    ``align_s`` [s] longest alignment; ``output_s`` [s] output interval."""
    src = open_source(source)
    try:
        return navigate_source(src, models=models, others=others, span_s=span_s,
                               align_s=align_s, output_s=output_s)
    finally:
        src.close()


#: the navigation scores a Monte Carlo campaign collects per unit (metric name → dataset key)
NAV_METRICS = {"nav_error_end_m": "error_end_m",
               "nav_radial_rate_nmi_per_h": "radial_error_rate_nmi_per_h",
               "nav_heading_end_arcmin": "heading_error_end_arcmin"}


def nav_rows(ds) -> list[tuple[str, str, float]]:
    """(variant, metric, value) rows of a navigation run for the Monte Carlo summaries (the
    variants are named like the study's compensators, plus ``oracle (gyros)`` and ``truth``);
    ``ds`` a navigation dataset, or a mapping environment → dataset (metric names then
    ``metric@environment``, as the environments recipe names its rows)."""
    if isinstance(ds, dict):
        return [(v, f"{m}@{env}", x) for env, d in ds.items() for v, m, x in nav_rows(d)]
    return [(str(v), metric, float(ds[key].sel(variant=v)))
            for v in ds["variant"].values for metric, key in NAV_METRICS.items()]
