"""System-level compensation of paper 000 (eqs. 24-29): a copy of a dataset whose IMU pulses are
converted to a desired temperature with the fitted parameter models.

System-level compensation (eqs. 24-29), per axis with the modelled K(T), D(T) in the
calibration's convention (K = K_nom (1 + s·1e-6), D in rad/s or m/s²)::

    N' = K(T_d)/K(T) · N + K(T_d) (D(T_d) − D(T)) Δt        (accelerometers: K± by sign of N)

T is the model's probe, linearly interpolated to each sample from the probe log, and the model
is evaluated on the probe's 1-s grid. The compensated increments are cumulatively rounded back
to integer pulse counts (N'_k = round(ΣN') − round(ΣN' up to k−1)), as a counter fed the
compensated rate would give: the quantisation error stays below half a pulse of integrated
angle and does not accumulate, and the dataset keeps its int32 format, so the unchanged
calibration campaign re-calibrates it. Residuals (Table 3) are the re-calibrated parameter
minus the model's value at T_d; their variance (ddof = 1) is compared with the raw parameter's
variance over the run.
"""

from __future__ import annotations

import pathlib
import time
from typing import Any

import numpy as np

from rlgsim.lab.studies.paper000_config import AXES
from rlgsim.lab.studies.paper000_kernel import convert_block, slopes
from rlgsim.lab.studies.runs import probe_temperatures
from rlgsim.sim.writer.derived import rewrite_pulses


def timed_compensation(*args) -> float:
    """:func:`compensate_dataset` in a worker; returns its wall time [s]."""
    t = time.perf_counter()
    compensate_dataset(*args)
    return time.perf_counter() - t


def compensate_dataset(src: pathlib.Path, dst: pathlib.Path, models: dict[str, Any],
                       probes: dict[str, str], desired_c: float, *,
                       chunk: int = 1 << 20) -> pathlib.Path:
    """Write a copy of dataset ``src`` whose IMU pulses are converted to ``desired_c`` by
    paper 000 eqs. (26) and (29) with the fitted parameter ``models`` (name → regressor of the
    window-mean temperature of ``probes[name]``); see the module docstring."""
    from rlgsim.estimators.calibration import DatasetReader
    from rlgsim.estimators.kalman_calibration import DEG_PER_H, UG

    reader = DatasetReader(src)
    nominal = reader.nominal()
    rate = reader.rate_hz
    reader.close()
    dt = 1.0 / rate
    ptime, temps = probe_temperatures(src, sorted(set(probes.values())))

    def on_grid(param: str) -> np.ndarray:
        col = temps[probes[param]]
        good = np.isfinite(col)
        col = np.interp(ptime, ptime[good], col[good])
        return models[param].predict(col[:, None])

    def at_desired(param: str) -> float:
        return float(models[param].predict(np.array([[desired_c]]))[0])

    def make_transform(sensor: str):
        """Eqs. (26)/(29) on one sensor's pulses, cumulatively rounded (module docstring)."""
        # per axis: parameter on the probe grid (sf ppm, bias °/h or µg) and at T_d
        if sensor == "gyro":
            sf = [[on_grid(f"gyro_sf_{a}")] for a in AXES]
            sf_d = [[at_desired(f"gyro_sf_{a}")] for a in AXES]
            b = [on_grid(f"gyro_bias_{a}") * DEG_PER_H for a in AXES]
            b_d = [at_desired(f"gyro_bias_{a}") * DEG_PER_H for a in AXES]
            k_nom = nominal.k_g
        else:
            sf = [[on_grid(f"accel_sf_pos_{a}"), on_grid(f"accel_sf_neg_{a}")] for a in AXES]
            sf_d = [[at_desired(f"accel_sf_pos_{a}"), at_desired(f"accel_sf_neg_{a}")]
                    for a in AXES]
            b = [on_grid(f"accel_bias_{a}") * UG for a in AXES]
            b_d = [at_desired(f"accel_bias_{a}") * UG for a in AXES]
            k_nom = nominal.k_a_pos
        return _Transform(ptime, dt, sf, sf_d, b, b_d, k_nom)

    return rewrite_pulses(src, dst, make_transform,
                          title_suffix=f" — pulses compensated to {desired_c} °C",
                          attrs={"compensated_to_c": float(desired_c)}, chunk=chunk)


def inputs_outside_range(src: pathlib.Path, xs: dict[str, np.ndarray], probes: dict[str, str],
                         windows: list[tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """Extrapolation of the compensation (issue 27): per parameter, the share of the probe
    samples inside the calibration ``windows`` (t0, t1 [s]) at which the model is evaluated
    outside its training temperatures [min, max] of ``xs`` [%], and the largest distance beyond,
    in % of the training span (:func:`rlgsim.lab.studies.input_range.outside_range`).

    The models are fitted to window-mean temperatures, but :func:`compensate_dataset` evaluates
    them at every probe sample: the first and last windows' own ramps reach past the range of
    the means (by about half a window's temperature change), so the compensation of those
    samples extrapolates even though every fit (Table 2) is in-sample."""
    from rlgsim.lab.studies.input_range import outside_range
    ptime, temps = probe_temperatures(src, sorted(set(probes.values())))
    inside = np.zeros(ptime.shape, dtype=bool)
    for t0, t1 in windows:
        inside |= (ptime > t0) & (ptime <= t1)
    out = {}
    for param, probe in probes.items():
        grid = temps[probe][inside]
        grid = grid[np.isfinite(grid)]
        share, excess, _ = outside_range({"T": xs[param]}, {"T": grid}, ["T"])
        out[param] = (share, excess)
    return out


class _Transform:
    """Eqs. (26)/(29) on one sensor's pulse blocks, in sample order, cumulatively rounded.

    ``sf[i]``/``sf_d[i]``: axis i's scale-factor error [ppm] on the probe grid ``ptime`` and
    at T_d — one entry (gyro), or two (accelerometer: K+ for N ≥ 0, K− for N < 0); ``b[i]``,
    ``b_d[i]``: its bias (pulse units per second / K) likewise. Per sample and axis:
    K(T_d)/K(T) = (1 + 1e-6 s(T_d)) / (1 + 1e-6 s(T)) with s(T) interpolated linearly to the
    sample's middle, times N, plus K(T_d) (b(T_d) − b(T)) Δt; the running sum over the samples
    is rounded to whole pulses and differenced. One compiled pass per block
    (:func:`rlgsim.lab.studies.paper000_kernel.convert_block`: the numpy formulation's numbers,
    bit for bit, without its full-length temporaries)."""

    def __init__(self, ptime, dt, sf, sf_d, b, b_d, k_nom) -> None:
        self.ptime = np.ascontiguousarray(ptime, dtype=float)
        self.dt = dt
        two = len(sf[0]) == 2
        self.two_sided = two
        self.sf_pos = np.ascontiguousarray([s[0] for s in sf], dtype=float)
        self.sf_neg = np.ascontiguousarray([s[1] for s in sf] if two else self.sf_pos,
                                           dtype=float)
        num_p = [1 + 1e-6 * s[0] for s in sf_d]
        num_n = [1 + 1e-6 * s[1] for s in sf_d] if two else num_p
        self.num_pos, self.num_neg = np.array(num_p), np.array(num_n)
        self.kd_pos = np.array([k_nom[i] * num_p[i] for i in range(3)])
        self.kd_neg = np.array([k_nom[i] * num_n[i] for i in range(3)])
        self.bias = np.ascontiguousarray(b, dtype=float)
        self.bias_d = np.array(b_d, dtype=float)
        self.slopes = [slopes(self.ptime, a) for a in (self.sf_pos, self.sf_neg, self.bias)]
        self.compiled = all(np.all(np.isfinite(a)) for a in (
            self.sf_pos, self.sf_neg, self.bias, *self.slopes, self.num_pos, self.num_neg,
            self.kd_pos, self.kd_neg, self.bias_d))
        self.cum = np.zeros(3)
        self.last = np.zeros(3)

    def __call__(self, k0: int, pulses: np.ndarray) -> np.ndarray:
        if not self.compiled:           # non-finite model values: numpy's interp handles them
            return self.numpy_block(k0, pulses)
        out = np.empty(pulses.shape, dtype=np.int32)
        convert_block(np.ascontiguousarray(pulses, dtype=np.int32), int(k0), float(self.dt),
                      self.ptime, self.sf_pos, self.sf_neg, self.bias, *self.slopes,
                      self.two_sided, self.num_pos, self.num_neg, self.kd_pos, self.kd_neg,
                      self.bias_d, self.cum, self.last, out)
        return out

    def numpy_block(self, k0: int, pulses: np.ndarray) -> np.ndarray:
        """:meth:`__call__` in numpy, column by column (the compiled pass's reference, and the
        path for non-finite model values)."""
        n = pulses.shape[0]
        N = pulses.T.astype(float, order="C")              # (axes, samples)
        t = (np.arange(k0, k0 + n) + 0.5) * self.dt
        comp = np.empty_like(N)
        for i in range(3):
            den = np.interp(t, self.ptime, self.sf_pos[i])
            if self.two_sided:
                neg = N[i] < 0
                np.copyto(den, np.interp(t, self.ptime, self.sf_neg[i]), where=neg)
                num = np.where(neg, self.num_neg[i], self.num_pos[i])
                kd = np.where(neg, self.kd_neg[i], self.kd_pos[i])
            else:
                num, kd = self.num_pos[i], self.kd_pos[i]
            np.multiply(den, 1e-6, out=den)
            np.add(den, 1, out=den)
            np.divide(num, den, out=den)
            np.multiply(den, N[i], out=comp[i])
            drift = np.interp(t, self.ptime, self.bias[i])
            np.subtract(self.bias_d[i], drift, out=drift)
            np.multiply(kd, drift, out=drift)
            np.multiply(drift, self.dt, out=drift)
            np.add(comp[i], drift, out=comp[i])
        c = np.cumsum(comp, axis=1, out=comp)
        np.add(c, self.cum[:, None], out=c)
        r = np.rint(c, out=N)
        out = np.empty((n, 3), dtype=np.int32)
        out[0] = r[:, 0] - self.last
        out[1:] = (r[:, 1:] - r[:, :-1]).T
        self.cum, self.last = c[:, -1].copy(), r[:, -1].copy()
        return out
