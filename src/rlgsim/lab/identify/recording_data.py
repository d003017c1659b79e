"""What identification reads from a recording or an rlgsim dataset, checked once: the probe
temperatures and the chamber air on the temperature grid, the power state, the UHFO, the gyro
rate at its sample rate, and the 100 s bias windows (:func:`rlgsim.lab.windows.window_table`, which
removes the Earth rate). Every other module of :mod:`rlgsim.lab.identify` works on
:class:`RecordingData` only.

Turntable motion (:mod:`.table_motion`): the table's true input rate on the gyro axis per
sample. The bias windows then keep only the **stationary** windows (no sample in which the
table turns), their bias the window rate minus the Earth rate through the table attitude: a
turning window carries the scale-factor error times the table rate (5 ppm of 10 °/s is
0.18 °/h, ten times a navigation gyro's bias law), which the bias law must not see.

Short gaps of the chamber air and the UHFO (dropout rows) are bridged linearly (up to 10 min);
missing probe readings stay NaN and are left out of the thermal fit. A recording that cannot
support an identification is refused here with one
:class:`~rlgsim.ground.errors.UserInputError` line saying what is needed (:data:`NEEDS`).
"""

from __future__ import annotations

import os
import pathlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.sensors.gyro import pulses_per_arcsec
from rlgsim.lab.identify.table_motion import motion_from_dataset, motion_from_recording

__all__ = ["RecordingData", "read_recording", "read_recordings", "NEEDS", "MIN_DURATION_S",
           "MIN_SPAN_K", "scale_factor_line", "screen_probe_glitches"]

#: what an identification needs, quoted in every refusal
NEEDS = ("identification needs at least 2 h of powered data with probe temperatures, the "
         "chamber air (chamber_air_c) and the gyro output, through a chamber programme that "
         "moves the air by at least 5 K")
MIN_DURATION_S = 2 * 3600.0
MIN_SPAN_K = 5.0


@dataclass(frozen=True)
class RecordingData:
    """One run as identification sees it (times in s from the start, temperatures in °C).

    ``t_s`` (m,) the temperature grid (ends of steps of ``step_s``), ``probes_c`` (m, p) with
    NaN where a reading is missing, ``air_c`` (m,), ``power`` (m,) 0/1, ``uhfo_v`` (m,) or None,
    ``rate_deg_per_h`` (N,) the gyro rate per sample at ``sample_rate_hz`` (Earth rate not
    removed; only its fluctuations are used), ``windows`` the 100 s window table."""

    source: str
    step_s: float
    t_s: np.ndarray
    probe_names: tuple[str, ...]
    probes_c: np.ndarray
    air_c: np.ndarray
    power: np.ndarray
    uhfo_v: np.ndarray | None
    gyro_axis: str
    sample_rate_hz: float
    rate_deg_per_h: np.ndarray
    windows: object
    window_s: float
    has_motion: bool
    #: probe readings set missing as glitches (:func:`screen_probe_glitches`)
    probe_glitches: int = 0
    #: the turntable's input rate on the gyro axis (None: a static table, or not readable)
    motion: object = None
    #: why the recording's motion cannot be used (empty when it can, or there is none)
    motion_note: str = ""
    #: bias windows left out because the table turns in them
    moving_windows: int = 0

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1]) if self.t_s.size else 0.0


#: longest gap of the chamber air or the UHFO bridged by linear interpolation [s]
MAX_GAP_S = 600.0


def _bridge(x: np.ndarray, step: float, source: str, what: str) -> np.ndarray:
    """``x`` with short gaps (dropout rows, NaN) filled linearly; a longer gap is refused."""
    bad = ~np.isfinite(x)
    if not bad.any():
        return x
    if bad.all():
        raise _refuse(source, f"{what} has no values")
    edges = np.diff(np.concatenate(([0], bad.astype(np.int8), [0])))
    longest = int((np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)).max())
    if longest * step > MAX_GAP_S:
        raise _refuse(source, f"{what} is missing for {longest * step:g} s in one stretch "
                              f"(gaps up to {MAX_GAP_S:g} s are bridged)")
    idx = np.arange(x.size)
    out = x.copy()
    out[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
    return out


#: a probe reading this far [K] from the median of its ±5 neighbours is a glitch: no probe
#: of a gyro in a chamber moves 5 K in five samples, while a thermometer's power-on-reset
#: value (85 °C for the DS18B20 class) or a bus error lands tens of kelvin away
GLITCH_K = 5.0


def screen_probe_glitches(temps: np.ndarray) -> tuple[np.ndarray, int]:
    """``temps`` (m, p) with isolated glitches set missing (NaN), and how many: a reading
    more than :data:`GLITCH_K` from the median of the 11 readings centred on it (missing
    ones left out). A real recording has no truth record of its anomalies, so they are found
    in the data; one wrong reading of 85 °C would otherwise dominate the least squares."""
    import pandas as pd
    med = pd.DataFrame(temps).rolling(11, center=True, min_periods=1).median().to_numpy()
    bad = np.isfinite(temps) & (np.abs(temps - med) > GLITCH_K)
    if not bad.any():
        return temps, 0
    out = temps.copy()
    out[bad] = np.nan
    return out, int(bad.sum())


def _refuse(source: str, what: str) -> UserInputError:
    return UserInputError(f"{source}: {what}; {NEEDS}")


def _gyro_of(source: str, axes: list[str], gyro: str | None) -> str:
    """The gyro to identify: ``gyro`` if it is one of ``axes``, the only axis without it."""
    if gyro is None:
        if len(axes) != 1:
            raise UserInputError(f"{source}: several gyros ({', '.join(axes)}); say which "
                                 f"one to identify (--gyro AXIS, or in the sidecar [identify] gyro)")
        return axes[0]
    if gyro not in axes:
        raise UserInputError(f"{source}: gyro {gyro!r} not allowed; the gyro axes are "
                             f"{', '.join(axes)}")
    return gyro


def _uhfo_of(imu: Any, gyro: str) -> np.ndarray | None:
    """The gyro's UHFO series [V], or None without one (or one logged for other gyros only)."""
    if "uhfo" not in imu:
        return None
    u = imu["uhfo"]
    uhfo = np.asarray(u.sel(gyro=gyro).values if "gyro" in u.dims else u.values, dtype=float)
    return uhfo if np.isfinite(uhfo).any() else None


def _table_turns(tree: Any) -> bool:
    """Whether the dataset's turntable angles move at all."""
    motion = False
    if "turntable" in tree.children:
        tt = tree["turntable"]
        for key in ("outer_angle", "inner_angle"):
            if key in tt:
                a = np.asarray(tt[key].values, dtype=float)
                motion |= bool(np.nanmax(a) - np.nanmin(a) > 1e-9) if a.size else False
    return motion


def _from_tree(source: str, tree: Any, gyro: str | None) -> dict:
    """The recording's arrays from its opened tree: probes, chamber air, power, the gyro's
    rate [°/h] (from a recording's rate, or a dataset's pulses through its device's scale
    factor), UHFO, and the turntable's motion as a recording gives it."""
    from rlgsim.ground.recording import is_recording, load_recording
    if "probes" not in tree.children or tree["probes"].sizes.get("probe", 0) == 0:
        raise _refuse(source, "no probe temperatures (probe_<name>_c columns)")
    if "thermal" not in tree.children or "chamber_air" not in tree["thermal"]:
        raise _refuse(source, "no chamber air temperature (chamber_air_c)")
    pr = tree["probes"]
    th = tree["thermal"]
    air = np.asarray(th["chamber_air"].values, dtype=float)
    out = dict(names=tuple(str(n) for n in pr["probe"].values),
               temps=np.asarray(pr["temperature"].transpose("time", "probe").values,
                                dtype=float),
               t=np.asarray(pr["time"].values, dtype=float), air=air,
               power=(np.asarray(th["power_on"].values, dtype=float) if "power_on" in th
                      else np.ones_like(air)))
    imu = tree["imu"] if "imu" in tree.children else None
    if imu is None or "gyro" not in imu.coords or imu.sizes.get("gyro", 0) == 0:
        raise _refuse(source, "no gyro output (gyro_<axis>_pulses or a rate column)")
    axes = [str(a) for a in imu["gyro"].values]
    gyro = _gyro_of(source, axes, gyro)
    f = float(imu.attrs.get("sample_rate_hz", tree.attrs.get("sample_rate_hz")))
    out.update(gyro=gyro, f=f, uhfo=_uhfo_of(imu, gyro), motion=_table_turns(tree),
               table=None, motion_note="")
    if is_recording(source):
        rec = load_recording(source)
        out["rate"] = np.asarray(rec.gyro_rate_deg_per_h()[:, rec.gyro_axes.index(gyro)],
                                 dtype=float)
        out["table"], out["motion_note"] = motion_from_recording(rec, gyro)
    else:
        pulses = np.asarray(imu["gyro_pulses"][:, axes.index(gyro)].values, dtype=np.float64)
        import tomllib
        dev = tomllib.loads(str(tree.attrs.get("device_text", "")) or "")
        k = pulses_per_arcsec(dev)
        out["rate"] = pulses * f / k                   # arcsec/s, which is °/h
    return out


def _regular_step(source: str, t: np.ndarray) -> float:
    """The temperature step [s], after checking that the samples are regular from the start."""
    if t.size < 2:
        raise _refuse(source, f"only {t.size} temperature sample(s)")
    step = float(np.median(np.diff(t)))
    if not np.allclose(np.diff(t), step, rtol=1e-6, atol=1e-9) or abs(t[0] - step) > 1e-6 * step:
        raise UserInputError(f"{source}: the temperature samples must be regular from the "
                             f"start (one every {step:g} s, the first at {step:g} s); {NEEDS}")
    return step


def _check_excitation(source: str, t: np.ndarray, air: np.ndarray, power: np.ndarray,
                      step: float) -> None:
    """Refuse a recording powered too briefly or whose (bridged) chamber air does not move."""
    powered = power > 0.5
    if t[-1] < MIN_DURATION_S or powered.sum() * step < MIN_DURATION_S:
        on_h, all_h = powered.sum() * step / 3600, t[-1] / 3600   # 3 digits: 1.997 is no 2
        raise _refuse(source, f"too short: {on_h:.4g} h powered of {all_h:.4g} h")
    span = float(np.ptp(air))
    if span < MIN_SPAN_K:
        raise _refuse(source, f"no temperature excitation: the chamber air spans only "
                              f"{span:.2f} K")


def _bias_windows(source: str, window_s: float, gyro: str, table: Any, at_rest: Any,
                  rate: np.ndarray, f: float) -> tuple[Any, int]:
    """The bias window table (the turntable's turning windows left out, the Earth rate through
    its attitude taken off) and how many windows were left out; at least 20 are needed."""
    from rlgsim.lab.windows import window_table
    try:
        windows = window_table(source, window_s, gyro=gyro)
    except ValueError as exc:            # e.g. missing probe readings inside a window
        raise UserInputError(f"{source}: the {window_s:g} s bias windows cannot be formed "
                             f"({exc}); identification needs windows with complete gyro and "
                             f"probe data") from None
    moving_windows = 0
    if table is not None or at_rest is not None:
        windows, moving_windows = _stationary_windows(windows, table or at_rest, rate, f,
                                                      window_s)
    if len(windows) < 20:
        raise _refuse(source, f"only {len(windows)} complete powered {window_s:g} s windows "
                              f"of the gyro" + (f" with the turntable at rest ({moving_windows} "
                                                f"left out because the table turns in them)"
                                                if moving_windows else ""))
    return windows, moving_windows


def read_recording(path: str | os.PathLike, *, gyro: str | None = None,
                   window_s: float = 100.0) -> RecordingData:
    """Read and check a recording (table + sidecar) or an rlgsim dataset."""
    return read_recordings(path, [gyro], window_s=window_s)[0]


def read_recordings(path: str | os.PathLike, gyros: list[str | None], *,
                    window_s: float = 100.0) -> list[RecordingData]:
    """:func:`read_recording` of each of ``gyros``, the recording opened once (a several-gyro
    identification, :mod:`.twin_gyros`); with several gyros a refusal names the gyro (and the
    gyros read before it, which ``--gyro`` identifies alone)."""
    from rlgsim.ground.datatree import open_tree
    source = os.fspath(path)
    p = pathlib.Path(source)
    if not p.exists():
        raise UserInputError(f"{source}: no such file")
    # opened lazily: only the arrays read below come off the disk (one gyro's column, not the
    # datetime twins of the 7.2 M sample times that loading the tree would compute)
    tree = open_tree(source)
    out: list[RecordingData] = []
    try:
        raw = []
        for g in gyros:
            with _naming(gyros, g, len(raw)):
                raw.append(_from_tree(source, tree, g))
    finally:
        tree.close()
    for g, r in zip(gyros, raw):
        with _naming(gyros, g, len(out)):
            out.append(_checked(source, r, window_s))
    return out


class _naming:
    """Re-raise a refusal for gyro ``g`` of several ``gyros`` with the gyro named, and the
    ``done`` gyros before it as identifiable alone."""

    def __init__(self, gyros: list, g, done: int) -> None:
        self.gyros, self.g, self.done = gyros, g, gyros[:done]

    def __enter__(self) -> None:
        return None

    def __exit__(self, kind, exc, tb) -> bool:
        if kind is UserInputError and len(self.gyros) > 1:
            raise UserInputError(f"{exc} (gyro {self.g}" + (
                f"; gyro {', '.join(self.done)} can be identified alone: --gyro "
                f"{self.done[0]})" if self.done else ")")) from None
        return False


def _checked(source: str, r: dict, window_s: float) -> RecordingData:
    """One gyro's arrays (:func:`_from_tree`) checked and completed: the turntable's motion,
    the regular temperature grid, bridged gaps, the excitation, probe glitches, the windows."""
    from rlgsim.ground.recording import is_recording
    gyro, f, rate, table, motion = r["gyro"], r["f"], r["rate"], r["table"], r["motion"]
    if motion and table is None and not is_recording(source):
        from rlgsim.ground.dataset_format import open_dataset
        with open_dataset(source) as ds:        # the dataset's motion arrays, once it is closed
            table = motion_from_dataset(ds, gyro, rate.size, f)
    # a table at rest away from zero: no motion, but its attitude still sets the Earth rate
    at_rest = table if table is not None and not table.moving.any() else None
    if at_rest is not None:
        table = None
    motion = motion or table is not None
    t, power = r["t"], r["power"]
    step = _regular_step(source, t)
    air = _bridge(r["air"], step, source, "the chamber air")
    uhfo = r["uhfo"]
    if uhfo is not None:
        uhfo = _bridge(uhfo, step, source, "the UHFO")
    _check_excitation(source, t, air, power, step)
    temps, glitches = screen_probe_glitches(r["temps"])
    good = np.isfinite(temps).mean(axis=0)
    if np.all(good < 0.5):
        raise _refuse(source, "the probes hold no usable readings")
    windows, moving_windows = _bias_windows(source, window_s, gyro, table, at_rest, rate, f)
    return RecordingData(source=source, step_s=step, t_s=t, probe_names=r["names"],
                         probes_c=temps, air_c=air, power=(power > 0.5).astype(float),
                         uhfo_v=uhfo, gyro_axis=gyro, sample_rate_hz=f, rate_deg_per_h=rate,
                         windows=windows, window_s=window_s, has_motion=motion,
                         probe_glitches=glitches, motion=table, motion_note=r["motion_note"],
                         moving_windows=moving_windows)


def _stationary_windows(windows, table, rate: np.ndarray, f: float, window_s: float):
    """The window table without the windows in which the turntable turns, and how many were
    left out; the bias of the others is the window's mean rate minus the mean Earth rate on
    the gyro axis through the table attitude (module docstring)."""
    m = int(round(f * window_s))
    rows = np.rint(np.asarray(windows["time_s"], dtype=float) / window_s).astype(int) - 1
    n_win = table.moving.size // m
    rows_ok = rows < n_win
    moving = np.ones(rows.size, dtype=bool)
    mw = table.moving[:n_win * m].reshape(n_win, m).any(axis=1)
    moving[rows_ok] = mw[rows[rows_ok]]
    keep = ~moving
    out = windows[keep].reset_index(drop=True)
    r = rows[keep]
    rate_w = rate[:n_win * m].reshape(n_win, m).mean(axis=1)[r]
    earth_w = table.input_deg_per_h[:n_win * m].reshape(n_win, m).mean(axis=1)[r]
    out["bias_deg_per_h"] = rate_w - earth_w
    return out, int(moving.sum())


def scale_factor_line(data: "RecordingData") -> str:
    """The one line saying why the scale factor (and its temperature law) keeps the
    template's values when the recording's motion cannot be used (a static table, or a
    recording without angle columns); :mod:`.scale_factor_fit` words the rest."""
    if data.motion is None and data.motion_note:
        return f"scale factor: kept from the template — {data.motion_note}"
    if data.motion is None:
        return ("scale factor: kept from the template — the recording has no turntable motion; "
                "a static gyro sees only the Earth rate's component on its axis (≈ 10 °/h), on "
                "which a scale-factor change of 10 ppm is 10⁻⁴ °/h, indistinguishable from a "
                "bias change; identifying it needs rate steps on a turntable at several "
                "temperatures")
    return ("scale factor: identified from the turntable's rate segments (see the scale-factor "
            "section of the report)")
