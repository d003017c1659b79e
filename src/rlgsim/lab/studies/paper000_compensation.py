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
    ``b_d[i]``: its bias (pulse units per second / K) likewise. Each axis is one contiguous
    row and every intermediate is written in place, so a block costs a few passes over its
    samples; the arithmetic is the equations' in their order (the same numbers as a
    column-by-column evaluation: products and sums are taken term by term, and the running
    sum is a sequential ``cumsum`` in either layout)."""

    def __init__(self, ptime, dt, sf, sf_d, b, b_d, k_nom) -> None:
        self.ptime, self.dt, self.sf, self.sf_d, self.b, self.b_d = ptime, dt, sf, sf_d, b, b_d
        self.k_nom = k_nom
        self.cum = np.zeros(3)
        self.last = np.zeros(3)

    def _ratio_and_weight(self, i: int, t: np.ndarray, n_i: np.ndarray):
        """K(T_d)/K(T) per sample and K(T_d) (a scalar, or per sample by the pulse's sign)."""
        sf, sf_d, k = self.sf[i], self.sf_d[i], self.k_nom[i]
        den = np.interp(t, self.ptime, sf[0])
        if len(sf) == 1:
            num = 1 + 1e-6 * sf_d[0]
            kd = k * num
        else:
            pos = n_i >= 0
            np.copyto(den, np.interp(t, self.ptime, sf[1]), where=~pos)
            num_p, num_n = 1 + 1e-6 * sf_d[0], 1 + 1e-6 * sf_d[1]
            num = np.where(pos, num_p, num_n)
            kd = np.where(pos, k * num_p, k * num_n)
        np.multiply(den, 1e-6, out=den)
        np.add(den, 1, out=den)
        np.divide(num, den, out=den)
        return den, kd

    def __call__(self, k0: int, pulses: np.ndarray) -> np.ndarray:
        n = pulses.shape[0]
        N = pulses.T.astype(float, order="C")              # (axes, samples)
        t = (np.arange(k0, k0 + n) + 0.5) * self.dt
        comp = np.empty_like(N)
        for i in range(3):
            ratio, kd = self._ratio_and_weight(i, t, N[i])
            np.multiply(ratio, N[i], out=comp[i])
            drift = np.interp(t, self.ptime, self.b[i])
            np.subtract(self.b_d[i], drift, out=drift)
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
