"""The calibration campaign: every turntable calibration window of a dataset → one row of the
parameter-versus-temperature table (paper 000 §4.1: 175 windows over a −5 → 65 °C ramp).

Input (what real turntable hardware would log too; never the truth): the gyro and
accelerometer pulses, the probe temperatures and the turntable's commanded programme
(docs/dataset.md: groups ``imu``, ``probes``, ``timeline``). Windows are the segments of the
``calibration`` track; their motions are the ``turntable`` segments carrying the same
``window`` label. Each window is calibrated independently (:func:`rlgsim.estimators.kalman_calibration.
calibrate_window`): a fresh prior, so every row is a separate measurement of the parameters at
the window's temperature. Only the linearisation point is chained from one window to the next
(the previous window's result is the next one's starting model; windows are cut into contiguous
chunks, one chain per chunk, and the chunks run in parallel processes).

Output per window: the 15 temperature-related parameters of paper 000 (gyro bias and scale
factor, accelerometer bias and positive/negative scale factors, per axis) plus the nine
misalignments, in engineering units — bias °/h and µg, scale factor in pulses per unit and in
ppm of the nominal, misalignment arcsec — with their 1σ from the filter covariance, the mean of
every probe temperature over the window, and, when the dataset is simulated (group ``truth``),
the truth averaged over the window and the error of every parameter.

Frames: the calibration's body frame is the accelerometer frame (x along accelerometer x, y in
the plane of accelerometers x and y), because the zero-velocity filter cannot tell a common
rotation of both triads from an attitude error. The simulator's truth is given in the table's
body frame with six accelerometer misalignments; :func:`to_accelerometer_frame` re-expresses it
exactly (an LQ decomposition of E_a) before it is compared.

Robustness: a window cut short, a missing or too-short dwell, NaN pulses, NaN probe readings or
a filter failure give a message in that row (``status = "failed"``) and the campaign goes on;
a dataset without calibration windows raises :class:`CampaignError`.

Not a scikit-learn estimator: a calibration maps a window of pulses and a commanded programme to
one parameter set (there is no X → y to fit and predict), so the sklearn estimator contract of
the compensators does not apply here.

Why this file is long: it holds one job, the calibration campaign over a dataset — its windows
(:func:`find_windows`), their reader (:class:`DatasetReader`, on the one dataset reader), the
filter called per window, the result table and the worker pool — and these parts share the
window specification and the parameter list; the filter itself is
:mod:`rlgsim.estimators.kalman_calibration`, the figures
:mod:`rlgsim.estimators.calibration_plot`.
"""

from __future__ import annotations

import csv
import math
import os
import pathlib
import tomllib
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from rlgsim.estimators.kalman_calibration import (ACCEL_MIS, BA, BG, GYRO_MIS, MA, MG, SAN, SAP, SG,
                                           UG, DEG_PER_H, CommandedMotion, FilterSettings,
                                           WindowResult, calibrate_window)
from rlgsim.estimators.strapdown import SensorModel
from rlgsim.ground import dataset_format as fmt
from rlgsim.ground.atomic import atomic_file
from rlgsim.ground.dataset_format import open_dataset
from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG
from rlgsim.ground.errors import UserInputError
from rlgsim.ground.lifeline import process_pool
from rlgsim.ground.units import ARCSEC, G0

__all__ = ["PARAMETERS", "PAPER_PARAMETERS", "AXES", "CampaignError", "Parameter",
           "engineering_values", "to_accelerometer_frame", "WindowSpec", "find_windows", "DatasetReader", "CampaignSettings", "filter_settings",
           "calibrate_one", "CampaignResult", "unit_of", "open_reader", "run_campaign", "UNIT_NAMES"]

#: Defaults when a dataset names no nominal values (paper 000 §4.1; sim presets' defaults).
DEFAULT_GYRO_SF_PULSE_PER_ARCSEC = 2.14
DEFAULT_ACCEL_SF_PULSE_PER_S_PER_G = 5000.0
DEFAULT_ARW_DEG_PER_SQRT_H = 0.002
DEFAULT_VRW_UG_PER_SQRT_HZ = 10.0
#: Shortest usable static dwell [s].
MIN_DWELL_S = 10.0
AXES = "xyz"


class CampaignError(ValueError):
    """The dataset cannot be calibrated at all (no windows, not a dataset, no pulses)."""


# ---------------------------------------------------------------------------- parameters

@dataclass(frozen=True)
class Parameter:
    """One reported parameter: column ``name``, ``unit``, state index in the filter (its σ is
    in the same unit) and ``group`` for plots."""

    name: str
    unit: str
    state: int
    group: str


def _parameters() -> list[Parameter]:
    out = []
    for i, a in enumerate(AXES):
        out.append(Parameter(f"gyro_bias_{a}", "deg/h", BG.start + i, "gyro bias"))
    for i, a in enumerate(AXES):
        out.append(Parameter(f"gyro_sf_{a}", "ppm", SG.start + i, "gyro scale factor"))
    for k, (i, j) in enumerate(GYRO_MIS):
        out.append(Parameter(f"gyro_mis_{AXES[i]}{AXES[j]}", "arcsec", MG.start + k,
                             "gyro misalignment"))
    for i, a in enumerate(AXES):
        out.append(Parameter(f"accel_bias_{a}", "ug", BA.start + i, "accelerometer bias"))
    for i, a in enumerate(AXES):
        out.append(Parameter(f"accel_sf_pos_{a}", "ppm", SAP.start + i,
                             "accelerometer positive scale factor"))
    for i, a in enumerate(AXES):
        out.append(Parameter(f"accel_sf_neg_{a}", "ppm", SAN.start + i,
                             "accelerometer negative scale factor"))
    for k, (i, j) in enumerate(ACCEL_MIS):
        out.append(Parameter(f"accel_mis_{AXES[i]}{AXES[j]}", "arcsec", MA.start + k,
                             "accelerometer misalignment"))
    return out


PARAMETERS = _parameters()
#: A parameter's unit as a column-name suffix.
UNIT_NAMES = {"deg/h": "deg_per_h", "ppm": "ppm", "arcsec": "arcsec", "ug": "ug"}
#: Row key -> (parameter, part) for the parameter columns (part: "", "_sigma", "_true",
#: "_error").
_PARAMETER_OF = {f"{p.name}{part}": (p, part) for p in PARAMETERS
                 for part in ("", "_sigma", "_true", "_error")}
#: The 15 temperature-related parameters of paper 000 (eqs. 19, 22).
PAPER_PARAMETERS = [p.name for p in PARAMETERS if "_mis_" not in p.name]


def engineering_values(model: SensorModel, nominal: SensorModel) -> dict[str, float]:
    """Parameters in reporting units: biases °/h and µg, scale factors as ppm of the nominal,
    misalignments arcsec (E off-diagonals); plus the scale factors in pulses per unit
    (``*_pulse_per_arcsec``, ``*_pulse_per_s_per_g``)."""
    v: dict[str, float] = {}
    for i, a in enumerate(AXES):
        v[f"gyro_bias_{a}"] = model.d_g[i] / DEG_PER_H
        v[f"gyro_sf_{a}"] = (model.k_g[i] / nominal.k_g[i] - 1) * 1e6
        v[f"gyro_sf_{a}_pulse_per_arcsec"] = model.k_g[i] * ARCSEC
        v[f"accel_bias_{a}"] = model.d_a[i] / UG
        v[f"accel_sf_pos_{a}"] = (model.k_a_pos[i] / nominal.k_a_pos[i] - 1) * 1e6
        v[f"accel_sf_neg_{a}"] = (model.k_a_neg[i] / nominal.k_a_neg[i] - 1) * 1e6
        v[f"accel_sf_pos_{a}_pulse_per_s_per_g"] = model.k_a_pos[i] * G0
        v[f"accel_sf_neg_{a}_pulse_per_s_per_g"] = model.k_a_neg[i] * G0
    for i, j in GYRO_MIS:
        v[f"gyro_mis_{AXES[i]}{AXES[j]}"] = model.e_g[i, j] / ARCSEC
    for i, j in ACCEL_MIS:
        v[f"accel_mis_{AXES[i]}{AXES[j]}"] = model.e_a[i, j] / ARCSEC
    return v


def to_accelerometer_frame(model: SensorModel) -> SensorModel:
    """Re-express a pulse model given in some body frame b in the accelerometer frame b'
    (x along accelerometer x, y in the accelerometers' x–y plane), exactly.

    E_a = L Q (LQ decomposition, L lower triangular with positive diagonal, Q a rotation) so
    E_a Δv^b = L Δv^{b'} with Δv^{b'} = Q Δv^b; the gyros see E_g Qᵀ. Each row's diagonal is
    moved into the scale factor and bias: K(DΔt + PΔx) = (K∘p)((D/p)Δt + diag(1/p) P Δx).
    """
    qt, r = np.linalg.qr(model.e_a.T)           # E_aᵀ = Qᵀ R  →  E_a = Rᵀ Q
    s = np.sign(np.diag(r))
    L = (r.T * s)                               # columns scaled: L = Rᵀ S
    Q = (qt * s).T                              # rows scaled:    Q = S Qᵀ... (S Q_tᵀ)
    la = np.diag(L).copy()
    Pg = model.e_g @ Q.T
    pg = np.diag(Pg).copy()
    return SensorModel(k_g=model.k_g * pg, d_g=model.d_g / pg, e_g=Pg / pg[:, None],
                       k_a_pos=model.k_a_pos * la, k_a_neg=model.k_a_neg * la,
                       d_a=model.d_a / la, e_a=L / la[:, None])


# ------------------------------------------------------------------------------- windows

@dataclass
class WindowSpec:
    """One calibration window: ``index`` (the dataset's window number), absolute ``t0_s`` /
    ``t1_s``, ``label``, its commanded ``motions`` (times relative to ``t0_s``) and
    ``problem`` (why it cannot be calibrated, or None)."""

    index: int
    t0_s: float
    t1_s: float
    label: str
    motions: list[CommandedMotion]
    problem: str | None = None


def _static_positions(motions: Sequence[CommandedMotion]) -> dict[int, float]:
    out: dict[int, float] = {}
    for m in motions:
        if m.kind == "static" and m.position is not None and m.position >= 0:
            out[m.position] = out.get(m.position, 0.0) + (m.t1_s - m.t0_s)
    return out


def find_windows(segments: Sequence[dict]) -> list[WindowSpec]:
    """Calibration windows from timeline segments (dicts with ``t0``, ``t1``, ``track``,
    ``label``, ``attrs``), with the problems that stop a window from being calibrated.

    A window is *cut short* when it is shorter than the longest window; a dwell is *missing*
    when a static position found in complete windows is absent, or shorter than
    :data:`MIN_DWELL_S`.
    """
    cal = [s for s in segments if s["track"] == "calibration"]
    turn = [s for s in segments if s["track"] == "turntable"]
    out: list[WindowSpec] = []
    for s in sorted(cal, key=lambda s: s["t0"]):
        w = s["attrs"].get("window")
        t0, t1 = float(s["t0"]), float(s["t1"])
        mine = [m for m in turn if m["attrs"].get("window") == w and m["t1"] > t0 and m["t0"] < t1]
        motions = [CommandedMotion(float(m["t0"]) - t0, float(m["t1"]) - t0,
                                   m["attrs"].get("kind", "static"), m["attrs"].get("axis"),
                                   float(m["attrs"].get("rate_deg_s") or 0.0),
                                   float(m["attrs"].get("outer_deg") or 0.0),
                                   float(m["attrs"].get("inner_deg") or 0.0),
                                   m["attrs"].get("position"), m["label"])
                   for m in sorted(mine, key=lambda m: m["t0"])]
        out.append(WindowSpec(int(w) if w is not None else len(out), t0, t1, s["label"], motions))
    if not out:
        return out
    full = max(w.t1_s - w.t0_s for w in out)
    complete = [w for w in out if w.t1_s - w.t0_s >= full - 1e-6]
    ref = Counter(frozenset(_static_positions(w.motions)) for w in complete).most_common(1)[0][0]
    for w in out:
        dur = w.t1_s - w.t0_s
        dwells = _static_positions(w.motions)
        if not w.motions:
            w.problem = "no turntable motions in the window"
        elif dur < full - 1e-6:
            last = w.motions[-1].label
            w.problem = (f"window cut short: {dur:.1f} s of {full:.1f} s (the run ends in "
                         f"{last}); not calibrated")
        elif w.motions[0].kind != "static":
            w.problem = "window does not start with a static dwell (needed for the alignment)"
        else:
            missing = sorted(ref - set(dwells))
            short = sorted(p for p, d in dwells.items() if d < MIN_DWELL_S)
            if missing:
                w.problem = ("missing dwell(s) " + ", ".join(f"P{p:02d}" for p in missing)
                             + "; not calibrated")
            elif short:
                w.problem = ("dwell(s) shorter than "
                             f"{MIN_DWELL_S:g} s: " + ", ".join(f"P{p:02d} ({dwells[p]:.1f} s)"
                                                               for p in short)
                             + "; not calibrated")
    return out


# ------------------------------------------------------------------------------ the data

class DatasetReader:
    """What the calibration needs from an rlgsim dataset (docs/dataset.md), read through the
    one dataset reader (:func:`rlgsim.ground.dataset_format.open_dataset`): site, sample rate,
    timeline segments, pulses, probes, nominal values, and — for simulated data only, for
    scoring — the truth. A file that cannot be calibrated raises :class:`CampaignError`."""

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = str(path)
        try:
            self.ds = open_dataset(self.path)
        except UserInputError as exc:
            raise CampaignError(str(exc)) from None
        if not self.ds.has(fmt.IMU, "gyro_pulses"):
            self.ds.close()
            raise CampaignError(f"{self.path}: the dataset has no IMU pulses (group imu); "
                                f"simulate a device with gyros and accelerometers")
        if not self.ds.has(fmt.IMU, "accel_pulses"):
            self.ds.close()
            raise CampaignError(f"{self.path}: the dataset has no accelerometer pulses; the "
                                f"systematic calibration needs them")
        a = self.ds.attrs
        self.latitude_deg = float(a.get("latitude_deg", DEFAULT_LATITUDE_DEG))
        self.height_m = float(a.get("height_m", 0.0))
        self.rate_hz = float(self.ds.group_attrs(fmt.IMU).get("sample_rate_hz",
                                                              a.get("sample_rate_hz", 100.0)))
        self.n_samples = self.ds.length(fmt.IMU, "gyro_pulses")
        self._device = self._device_tables()

    def close(self) -> None:
        self.ds.close()

    # ---- metadata -------------------------------------------------------------------------
    def _device_tables(self) -> dict:
        text = self.ds.attrs.get("device_text", "")
        try:
            return tomllib.loads(text) if text else {}
        except tomllib.TOMLDecodeError:
            return {}

    def nominal(self) -> SensorModel:
        """Nominal scale factors from the device preset embedded in the dataset (the
        ``[gyro]`` / ``[accelerometer]`` tables), else the defaults."""
        kg = float(self._device.get("gyro", {}).get("scale_factor_pulses_per_arcsec",
                                                    DEFAULT_GYRO_SF_PULSE_PER_ARCSEC))
        ka = float(self._device.get("accelerometer", {}).get(
            "scale_factor_pulses_per_s_per_g", DEFAULT_ACCEL_SF_PULSE_PER_S_PER_G))
        return SensorModel.nominal(kg / ARCSEC, ka / G0)

    def noise(self) -> dict[str, float]:
        """Nominal noise levels from the device preset's ``[noise]`` table (sim/sensors/noise.py keys:
        ``gyro_arw_deg_per_sqrt_h``, ``accel_vrw_ug_per_sqrt_hz``,
        ``gyro_bias_instability_deg_per_h``, ``gyro_rrw_deg_per_h_per_sqrt_h``,
        ``accel_bias_instability_ug``, ``accel_rrw_ug_per_sqrt_s``); absent keys are left out."""
        t = self._device.get("noise", {})
        return {k: float(v) for k, v in t.items()
                if isinstance(v, (int, float)) and not isinstance(v, bool)}

    def unit_noise(self) -> dict[str, np.ndarray]:
        """The drawn unit's own noise levels per axis, SI (3,) each, keyed ``gyro_arw``,
        ``gyro_bi``, ``gyro_rrw``, ``accel_vrw``, ``accel_bi``, ``accel_rrw`` (the dataset's
        truth coefficients ``noise.<key>[<axis>]``, rad/s^0.5 … m/s^2.5); empty for data
        without them. The preset's ``[noise]`` table holds the nominal levels; each unit's are
        drawn around them (``[tolerance.noise]``), and the filter is consistent only with the
        unit's own (docs/calibration.md, "Consistency per group")."""
        try:
            if not self.ds.has(fmt.TRUTH, "coefficient"):
                return {}
            coeff = self.ds.coefficients()
        except (KeyError, ValueError, OSError):
            return {}
        out = {}
        for key in ("gyro_arw", "gyro_bi", "gyro_rrw", "accel_vrw", "accel_bi", "accel_rrw"):
            vals = [coeff.get(f"noise.{key}[{a}]") for a in AXES]
            if all(v is not None and math.isfinite(v) and v >= 0 for v in vals):
                out[key] = np.array(vals, dtype=float)
        return out

    def segments(self) -> list[dict]:
        """Timeline segments (dicts ``t0``, ``t1``, ``track``, ``label``, ``attrs``)."""
        if not self.ds.has(fmt.TIMELINE):
            raise CampaignError(f"{self.path}: the dataset has no timeline group, so no "
                                f"calibration windows")
        return self.ds.segments()

    # ---- data over a window ---------------------------------------------------------------
    def sample_range(self, t0_s: float, t1_s: float) -> tuple[int, int]:
        return int(round(t0_s * self.rate_hz)), int(round(t1_s * self.rate_hz))

    def pulses(self, t0_s: float, t1_s: float) -> tuple[np.ndarray, np.ndarray]:
        k0, k1 = self.sample_range(t0_s, t1_s)
        if k1 > self.n_samples:
            raise ValueError(f"pulses end at {self.n_samples / self.rate_hz:.1f} s, the window "
                             f"needs {t1_s:.1f} s")
        rows = slice(k0, k1)
        return (self.ds.read(fmt.IMU, "gyro_pulses", rows).astype(float),
                self.ds.read(fmt.IMU, "accel_pulses", rows).astype(float))

    def probe_names(self) -> list[str]:
        if not self.ds.has(fmt.PROBES):
            return []
        return self.ds.strings(fmt.PROBES, "probe")

    def probes(self, t0_s: float, t1_s: float) -> np.ndarray:
        """Probe readings (m, p) [°C] over the window (rows whose step ends in (t0, t1])."""
        if not self.ds.has(fmt.PROBES):
            return np.zeros((0, 0))
        return self.ds.read(fmt.PROBES, "temperature",
                            self.ds.time_rows(fmt.PROBES, t0_s, t1_s))

    def truth(self, t0_s: float, t1_s: float) -> SensorModel | None:
        """The true pulse model averaged over the window (simulated data only)."""
        if not self.ds.has(fmt.TRUTH, "gyro_scale_factor"):
            return None
        rows = self.ds.time_rows(fmt.TRUTH, t0_s, t1_s)

        def mean(name):
            return np.asarray(self.ds.read(fmt.TRUTH, name, rows), dtype=float).mean(axis=0)
        try:
            return SensorModel(k_g=mean("gyro_scale_factor"), d_g=mean("gyro_bias"),
                               e_g=mean("gyro_installation"),
                               k_a_pos=mean("accel_scale_factor_pos"),
                               k_a_neg=mean("accel_scale_factor_neg"),
                               d_a=mean("accel_bias"), e_a=mean("accel_installation"))
        except (KeyError, ValueError):
            return None


# -------------------------------------------------------------------------------- one row

#: Chunks a campaign's windows are cut into (a chunk runs in one process, each window starting
#: from the previous one's result): 175 windows → 16 chunks of 11, enough to keep 2-8
#: processes busy; a short campaign gets chunks of one window.
CHUNKS = 16


@dataclass
class CampaignSettings:
    """Campaign options: the filter ``settings`` (noise levels filled from the dataset when
    left at zero), a ``nominal`` model (default: from the dataset), ``workers`` processes,
    ``chunk_windows`` windows per chunk (default: the windows cut into :data:`CHUNKS` chunks;
    the table depends on it — each chunk chains its windows' starting models — but not on
    ``workers``); ``unit_noise``: the filter takes the unit's own noise levels per axis when
    the data records them (:meth:`DatasetReader.unit_noise`), else the preset's nominal
    ones."""

    filter: FilterSettings | None = None
    nominal: SensorModel | None = None
    arw_deg_per_sqrt_h: float | None = None
    vrw_ug_per_sqrt_hz: float | None = None
    workers: int | None = None
    chunk_windows: int | None = None
    unit_noise: bool = True


def _filter_settings(reader: DatasetReader, cs: CampaignSettings) -> FilterSettings:
    if cs.filter is not None:
        return cs.filter
    unit = getattr(reader, "unit_noise", None)
    return filter_settings(reader.noise(), arw_deg_per_sqrt_h=cs.arw_deg_per_sqrt_h,
                           vrw_ug_per_sqrt_hz=cs.vrw_ug_per_sqrt_hz,
                           unit_levels=unit() if (cs.unit_noise and unit is not None) else None)


def filter_settings(noise: dict | None = None, *, arw_deg_per_sqrt_h: float | None = None,
                    vrw_ug_per_sqrt_hz: float | None = None,
                    unit_levels: dict[str, np.ndarray] | None = None) -> FilterSettings:
    """The calibration filter's settings from a device's ``[noise]`` table (the preset keys
    ``gyro_arw_deg_per_sqrt_h``, ``accel_vrw_ug_per_sqrt_hz``, ``gyro_bias_instability_deg_per_h``,
    ``gyro_rrw_deg_per_h_per_sqrt_h``, ``accel_bias_instability_ug``, ``accel_rrw_ug_per_sqrt_s``;
    absent ones: the defaults) — the one derivation used by ``rlgsim calibrate``, the campaign
    and the Python API, for datasets and recordings alike.

    ``unit_levels`` (:meth:`DatasetReader.unit_noise`: the unit's own levels per axis, SI)
    replace the table's nominal ones where given — what the unit's noise characterisation
    (an Allan-variance test, IEEE Std 952) gives before it is calibrated; explicit
    ``arw_deg_per_sqrt_h`` / ``vrw_ug_per_sqrt_hz`` still win. The accelerometer parameters'
    linear drift within a window is estimated (``FilterSettings.accel_drift``), so that the
    reported values are window means during a temperature ramp."""
    nz = dict(noise or {})
    lv = dict(unit_levels or {})
    arw = arw_deg_per_sqrt_h if arw_deg_per_sqrt_h is not None else nz.get(
        "gyro_arw_deg_per_sqrt_h", DEFAULT_ARW_DEG_PER_SQRT_H)
    vrw = vrw_ug_per_sqrt_hz if vrw_ug_per_sqrt_hz is not None else nz.get(
        "accel_vrw_ug_per_sqrt_hz", DEFAULT_VRW_UG_PER_SQRT_HZ)
    levels = dict(
        gyro_arw=arw * math.pi / 180 / 60, accel_vrw=vrw * UG,
        gyro_bi=nz.get("gyro_bias_instability_deg_per_h", 0.0) * DEG_PER_H,
        gyro_rrw=nz.get("gyro_rrw_deg_per_h_per_sqrt_h", 0.0) * DEG_PER_H / 60.0,
        accel_bi=nz.get("accel_bias_instability_ug", 0.0) * UG,
        accel_rrw=nz.get("accel_rrw_ug_per_sqrt_s", 0.0) * UG)
    explicit = {"gyro_arw": arw_deg_per_sqrt_h is not None,
                "accel_vrw": vrw_ug_per_sqrt_hz is not None}
    for key, value in lv.items():
        if key in levels and not explicit.get(key, False):
            levels[key] = np.asarray(value, dtype=float)
    return FilterSettings(
        arw_rad_per_sqrt_s=levels["gyro_arw"], vrw_m_per_s_per_sqrt_s=levels["accel_vrw"],
        gyro_bias_instability_rad_per_s=levels["gyro_bi"],
        gyro_rrw_rad_per_s_per_sqrt_s=levels["gyro_rrw"],
        accel_bias_instability_m_per_s2=levels["accel_bi"],
        accel_rrw_m_per_s2_per_sqrt_s=levels["accel_rrw"], accel_drift=True)


def calibrate_one(reader: DatasetReader, spec: WindowSpec, settings: FilterSettings,
                  nominal: SensorModel, start: SensorModel | None = None
                  ) -> tuple[dict, SensorModel | None]:
    """Calibrate one window; returns its table row and the calibrated model (None if failed)."""
    row: dict[str, Any] = dict(window=spec.index, label=spec.label, t0_s=spec.t0_s,
                               t1_s=spec.t1_s, status="ok", message="")
    names = reader.probe_names()
    temps = reader.probes(spec.t0_s, spec.t1_s)
    problems = []
    for p, name in enumerate(names):
        col = temps[:, p] if temps.size else np.zeros(0)
        row[f"temp_{name}_c"] = float(np.mean(col)) if col.size and np.all(np.isfinite(col)) \
            else float("nan")
        bad = int(np.sum(~np.isfinite(col)))
        if bad:
            problems.append(f"probe {name} has {bad} NaN reading(s) of {col.size} in the window")
        elif not col.size:
            problems.append(f"probe {name} has no reading in the window")
    truth = reader.truth(spec.t0_s, spec.t1_s)
    truth_eng = (engineering_values(to_accelerometer_frame(truth), nominal)
                 if truth is not None else None)
    if spec.problem:
        row.update(status="failed", message="; ".join([spec.problem] + problems))
        _fill(row, None, None, truth_eng)
        return row, None
    try:
        ng, na = reader.pulses(spec.t0_s, spec.t1_s)
        if not (np.all(np.isfinite(ng)) and np.all(np.isfinite(na))):
            raise ValueError("NaN pulses in the window")
        result = calibrate_window(ng, na, reader.rate_hz, spec.motions, nominal,
                                  reader.latitude_deg, reader.height_m, settings=settings,
                                  start=start)
    except (ValueError, np.linalg.LinAlgError, IndexError) as exc:
        row.update(status="failed", message="; ".join([f"calibration failed: {exc}"] + problems))
        _fill(row, None, None, truth_eng)
        return row, None
    row.update(iterations=result.iterations, converged=bool(result.converged),
               n_measurements=result.n_measurements,
               residual_rms_mm_s=result.residual_rms_m_per_s * 1e3, nis=result.nis)
    if not result.converged:
        problems.append(f"not converged after {result.iterations} iterations")
    if problems:
        row.update(status="failed", message="; ".join(problems))
    _fill(row, result, engineering_values(result.model, nominal), truth_eng)
    return row, result.model


def _fill(row: dict, result: WindowResult | None, est: dict | None, truth: dict | None) -> None:
    for p in PARAMETERS:
        row[p.name] = est[p.name] if est else float("nan")
        row[f"{p.name}_sigma"] = float(result.sigma[p.state]) if result is not None else float("nan")
        row[f"{p.name}_true"] = truth[p.name] if truth else float("nan")
        row[f"{p.name}_error"] = (est[p.name] - truth[p.name]) if est and truth else float("nan")
    for key in [k for k in (est or {}) if k.endswith(("_pulse_per_arcsec", "_pulse_per_s_per_g"))]:
        row[key] = est[key]
    if est is None:
        for a in AXES:
            row[f"gyro_sf_{a}_pulse_per_arcsec"] = float("nan")
            row[f"accel_sf_pos_{a}_pulse_per_s_per_g"] = float("nan")
            row[f"accel_sf_neg_{a}_pulse_per_s_per_g"] = float("nan")


# ----------------------------------------------------------------------------- campaign

@dataclass
class CampaignResult:
    """The table: ``rows`` (one dict per window, columns :attr:`columns`), ``probes`` names,
    ``nominal`` model, and run ``meta`` (dataset, seconds, workers)."""

    rows: list[dict]
    probes: list[str]
    nominal: SensorModel
    meta: dict = field(default_factory=dict)

    @property
    def columns(self) -> list[str]:
        base = ["window", "label", "t0_s", "t1_s", "status", "message", "iterations",
                "converged", "n_measurements", "residual_rms_mm_s", "nis"]
        base += [f"temp_{p}_c" for p in self.probes]
        for p in PARAMETERS:
            base += [p.name, f"{p.name}_sigma", f"{p.name}_true", f"{p.name}_error"]
        for a in AXES:
            base += [f"gyro_sf_{a}_pulse_per_arcsec"]
        for a in AXES:
            base += [f"accel_sf_pos_{a}_pulse_per_s_per_g", f"accel_sf_neg_{a}_pulse_per_s_per_g"]
        return base

    def column(self, name: str) -> np.ndarray:
        return np.array([r.get(name, float("nan")) for r in self.rows])

    @property
    def has_truth(self) -> bool:
        """Whether any window has a true value (a simulated dataset; a recording has none)."""
        return any(math.isfinite(r.get(f"{PARAMETERS[0].name}_true", float("nan")))
                   for r in self.rows)

    def table_columns(self) -> list[tuple[str, str]]:
        """The user-facing table's columns as (header, row key): each parameter column's
        header carries its unit (``gyro_bias_x_deg_per_h``, ``gyro_bias_x_sigma_deg_per_h``,
        ``gyro_sf_x_ppm``, ``accel_bias_x_ug``, ``gyro_mis_xy_arcsec``); the ``_true`` and
        ``_error`` columns only when some window has a truth."""
        truth = self.has_truth
        out = []
        for key in self.columns:
            p = _PARAMETER_OF.get(key)
            if p is None:
                out.append((key, key))
                continue
            param, part = p
            if part in ("_true", "_error") and not truth:
                continue
            out.append((f"{param.name}{part}_{UNIT_NAMES[param.unit]}", key))
        return out

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r["status"] != "ok"]

    def write_csv(self, path: str | os.PathLike, *, units_in_names: bool = False
                  ) -> pathlib.Path:
        """Write the table as CSV (to a temporary name, renamed on success);
        ``units_in_names``: the headers of :meth:`table_columns` (``rlgsim calibrate``'s
        table), else the row keys :attr:`columns` (a study's working files)."""
        path = pathlib.Path(path)
        pairs = self.table_columns() if units_in_names else [(c, c) for c in self.columns]
        with atomic_file(path) as tmp, open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([h for h, _ in pairs])
            for r in self.rows:
                w.writerow([_csv_value(r.get(c, "")) for _, c in pairs])
        return path


def _csv_value(v: Any) -> Any:
    if isinstance(v, (bool, np.bool_)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return "" if math.isnan(v) else repr(float(v))
    if isinstance(v, np.integer):
        return int(v)
    return v


def unit_of(column: str) -> str:
    """Unit of a table column (for the dataset group and plots)."""
    for p in PARAMETERS:
        if column in (p.name, f"{p.name}_sigma", f"{p.name}_true", f"{p.name}_error"):
            return p.unit
    if column.endswith("_pulse_per_arcsec"):
        return "arcsec-1"
    if column.endswith("_pulse_per_s_per_g"):
        return "s-1"
    if column.endswith("_c"):
        return "degC"
    if column.endswith("_s"):
        return "s"
    if column == "residual_rms_mm_s":
        return "mm s-1"
    return "1"


_WORKER_READER: dict[str, DatasetReader] = {}


def _chunk_job(path: str, specs: list[WindowSpec], settings: FilterSettings,
               nominal: SensorModel) -> list[dict]:
    reader = _WORKER_READER.get(str(path))
    if reader is None:
        reader = _WORKER_READER[str(path)] = open_reader(path)
    rows = []
    start = None
    for spec in specs:
        row, model = calibrate_one(reader, spec, settings, nominal, start)
        rows.append(row)
        if model is not None and row["status"] == "ok":
            start = model
    return rows


def open_reader(source):
    """The campaign's reader of ``source``: a dataset path (:class:`DatasetReader`) or an
    object with ``open()`` returning a reader of the same interface (a recording and its
    programme: :class:`rlgsim.estimators.recording_calibration.RecordingSource`)."""
    if hasattr(source, "open") and not isinstance(source, (str, os.PathLike)):
        return source.open()
    return DatasetReader(source)


def _source(path):
    return path if hasattr(path, "open") and not isinstance(path, (str, os.PathLike)) \
        else str(path)


def run_campaign(path, options: CampaignSettings | None = None,
                 progress: Callable[[int], None] | None = None) -> CampaignResult:
    """Calibrate every window of the dataset at ``path`` (or of a recording given as a
    :class:`~rlgsim.estimators.recording_calibration.RecordingSource`); ``progress(n)`` is
    called with the number of windows finished by each chunk."""
    import time
    options = options or CampaignSettings()
    reader = open_reader(path)
    try:
        windows = find_windows(reader.segments())
        if not windows:
            raise CampaignError(f"{path}: the dataset has no calibration windows (its turntable "
                                f"programme is not a calibration; use program = "
                                f"\"calibration19\" in the scenario's [turntable])")
        nominal = options.nominal or reader.nominal()
        settings = _filter_settings(reader, options)
        probes = reader.probe_names()
    finally:
        reader.close()
    workers = options.workers or min(2, os.cpu_count() or 1)
    # the chunk size follows from the number of windows, never from the worker count: a
    # chunk's windows chain their starting models, so the table is the same bytes for any
    # number of workers
    per = options.chunk_windows or max(1, math.ceil(len(windows) / CHUNKS))
    chunks = [windows[i:i + per] for i in range(0, len(windows), per)]
    t0 = time.perf_counter()
    rows: list[dict] = []
    if workers <= 1 or len(chunks) == 1:
        for c in chunks:
            rows += _chunk_job(_source(path), c, settings, nominal)
            if progress:
                progress(len(c))
        _WORKER_READER.pop(str(path), None)
    else:
        with process_pool(max_workers=workers) as ex:   # workers die with us
            futures = [ex.submit(_chunk_job, _source(path), c, settings, nominal)
                       for c in chunks]
            for fut, c in zip(futures, chunks):
                rows += fut.result()
                if progress:
                    progress(len(c))
    rows.sort(key=lambda r: r["t0_s"])
    wall = time.perf_counter() - t0
    return CampaignResult(rows, probes, nominal,
                          meta=dict(dataset=str(path), seconds=wall, workers=workers,
                                    windows=len(windows),
                                    failed=sum(r["status"] != "ok" for r in rows)))
