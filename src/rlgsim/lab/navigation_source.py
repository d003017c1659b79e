"""What the navigation scores read from a dataset or a recording (:mod:`rlgsim.lab.navigation`).

A :class:`NavSource` hands out, chunk by chunk, the IMU's pulse counts and (for a simulated
dataset) the true per-sample increments and the true temperature laws of the biases, plus the
site, the nominal pulse weights, the alignment segment and the true attitude. The datasets'
layout is docs/dataset.md; recordings docs/recordings.md (a recording must name its site;
its mount's body frame: :mod:`rlgsim.lab.navigation_mount`).

Alignment segment: the first static turntable motion after power-on (a recording: from the row
after its last power_on reading of 0 before the first reading of 1, or its first row without
that column; the sidecar's orientation), at most ``align_s`` long; navigation starts where it
ends.
"""

from __future__ import annotations

import math
import os
import pathlib
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from rlgsim.ground.errors import UserInputError


@dataclass
class NavSource:
    """Inputs of a navigation run. ``gyro_weight`` [rad/pulse] and ``accel_weight``
    [(m/s)/pulse] (3,) nominal pulse weights; ``start`` the first powered sample; ``law_gyro``
    / ``law_accel`` (steps, 3) the true temperature laws of the biases [rad/s, m/s²] on the
    thermal grid of ``step_s`` (None for a recording)."""

    name: str
    rate_hz: float
    latitude_deg: float
    height_m: float
    n: int
    gyro_weight: np.ndarray
    accel_weight: np.ndarray
    start: int
    static_end: int
    read: Callable[[int, int], tuple[np.ndarray, np.ndarray]]
    attitude: Callable[[np.ndarray], np.ndarray]
    truth: Callable[[int, int], tuple[np.ndarray, np.ndarray]] | None = None
    step_s: float = 0.0
    law_gyro: np.ndarray | None = None
    law_accel: np.ndarray | None = None
    closers: list = field(default_factory=list)
    #: sample indices whose increments were lost (a dropout: counted 0), sorted; the
    #: navigation refuses a span that holds one (:meth:`refuse_lost`)
    lost: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    #: the one line for the first lost sample ``k`` of a span and the span's count of them
    lost_line: Callable[[int, int], str] | None = None

    @property
    def dt(self) -> float:
        return 1.0 / self.rate_hz

    def step_index(self, k0: int, k1: int) -> np.ndarray:
        """Thermal-step row of samples k0..k1−1 (the row whose step holds the sample middle)."""
        mid = (np.arange(k0, k1) + 0.5) / self.rate_hz
        return np.minimum((mid // self.step_s).astype(np.intp), len(self.law_gyro) - 1)

    def close(self) -> None:
        for c in self.closers:
            c()

    def refuse_lost(self, k0: int, k1: int) -> None:
        """Refuse (one line) if a sample of k0..k1−1 was lost: free-inertial navigation
        integrates every increment, and a lost one is a wrong attitude and velocity from there
        on. A loss outside the span (after it, or before power-on) does not matter."""
        inside = self.lost[(self.lost >= k0) & (self.lost < k1)]
        if inside.size:
            k = int(inside[0])
            line = (self.lost_line(k, int(inside.size)) if self.lost_line is not None
                    else f"{self.name}: sample {k} ({k / self.rate_hz:g} s) was lost")
            raise UserInputError(f"{line}; free-inertial navigation needs every sample's "
                                 f"increments of the span ({k0 / self.rate_hz:g} s to "
                                 f"{k1 / self.rate_hz:g} s) — end the span before "
                                 f"{k / self.rate_hz:g} s (--span-h) or navigate a run "
                                 f"without gaps")


#: What navigate says of a run on a vehicle (a dataset with a trajectory, an exported drive).
VEHICLE_ADVICE = ("a vehicle's mission is scored by the aided navigator of the vehicle study "
                  "(recipe vehicle, docs/trajectories.md)")


def _text(v: Any) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _weight(coef: dict, key: str, unit: str, path: pathlib.Path) -> float:
    """A nominal scale factor of the truth's coefficient table, in ``unit`` (finite, > 0)."""
    if key not in coef or coef[key][1] != unit:
        raise UserInputError(f"{path}: truth coefficient {key} missing or not in {unit} "
                             f"(got {coef.get(key)!r})")
    value = coef[key][0]
    if not (math.isfinite(value) and value > 0):
        raise UserInputError(f"{path}: truth coefficient {key} = {value!r} {unit}; a nominal "
                             f"scale factor is a finite number > 0 (a damaged dataset?)")
    return value


def _from_dataset_static(path: pathlib.Path) -> NavSource:
    """:func:`_from_dataset` for a dataset of any number of gyros and no accelerometers: the
    site, the power-on, the alignment segment, the truth and the attitude (read and weights
    are the caller's)."""
    return _from_dataset(path, need_imu=False)


def _numbers(ds: Any, group: str, name: str, shape: tuple[int | None, ...]) -> None:
    """Refuse (one line) a variable that is missing or not numeric of ``shape`` (None: any
    length)."""
    if not ds.has(group, name):
        what = f"group {group!r}" if not ds.has(group) else f"variable {group}/{name}"
        raise UserInputError(f"{ds.path}: the dataset has no {what}")
    info = next(v for v in ds.variables(group) if v.name == name)
    ok = (info.dtype.kind in "iuf" and len(info.shape) == len(shape)
          and all(want is None or got == want for got, want in zip(info.shape, shape)))
    if not ok:
        want = " × ".join("n" if w is None else str(w) for w in shape)
        raise UserInputError(f"{ds.path}: {group}/{name} is {info.dtype} of shape "
                             f"{info.shape}; navigation needs numbers of shape ({want}) "
                             f"(a damaged dataset?)")


def _root(ds: Any, key: str) -> float:
    """A numeric root attribute, one line if missing or not a number."""
    value = ds.attrs.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserInputError(f"{ds.path}: root attribute {key} = {value!r}; a number is needed "
                             f"(a damaged dataset?)")
    return float(value)


def _from_dataset(path: pathlib.Path, need_imu: bool = True) -> NavSource:
    """The dataset's inputs of a navigation run, read through the one reader
    (:func:`rlgsim.ground.dataset_format.open_dataset`): every group, variable, shape and
    root attribute used here is checked first (one line naming it), and a run on a vehicle
    (group ``trajectory``) is refused — its motion is not the fixed site's."""
    from rlgsim.ground import dataset_format as fmt
    from rlgsim.sim.motion.recorded import dataset_motion
    ds = fmt.open_dataset(path)                       # the format checks, one line on failure
    try:
        if ds.has(fmt.TRAJECTORY):
            raise UserInputError(
                f"{path}: a run on a vehicle (group trajectory); navigate aligns on a static "
                f"segment at a fixed site and scores the drift from it — {VEHICLE_ADVICE}")
        gyros = ds.strings(fmt.IMU, "gyro")
        if need_imu and len(gyros) < 3:
            raise UserInputError(f"{path}: imu/gyro has {len(gyros)} gyro(s) ({', '.join(gyros)});"
                                 " navigation needs three (x, y, z)")
        if need_imu and not ds.has(fmt.IMU, "accel_pulses"):
            raise UserInputError(f"{path}: imu/accel_pulses missing; navigation needs three "
                                 "accelerometers")
        n = ds.length(fmt.IMU, "gyro_pulses")
        _numbers(ds, fmt.IMU, "gyro_pulses", (n, len(gyros)))
        rate = _root(ds, "sample_rate_hz")
        latitude, height = _root(ds, "latitude_deg"), _root(ds, "height_m")
        coef = {n_: (float(v), str(u)) for n_, v, u in zip(
            ds.strings(fmt.TRUTH, "coefficient"), ds.read(fmt.TRUTH, "coefficient_value"),
            ds.strings(fmt.TRUTH, "coefficient_units"))}
        law_g = law_a = None
        if need_imu:
            _numbers(ds, fmt.IMU, "accel_pulses", (n, 3))
            k_g = np.array([_weight(coef, f"gyro.k0[{a}]", "pulses/rad", path) for a in "xyz"])
            k_a = np.array([_weight(coef, f"accel.k0[{a}]", "pulses/(m/s)", path) for a in "xyz"])
            laws = []
            for sensor, width in (("gyro", len(gyros)), ("accel", 3)):
                for name in (f"{sensor}_bias", f"{sensor}_bias_random"):
                    _numbers(ds, fmt.TRUTH, name, (ds.length(fmt.TRUTH, f"{sensor}_bias"), width))
                laws.append(np.asarray(ds.read(fmt.TRUTH, f"{sensor}_bias"))
                            - np.asarray(ds.read(fmt.TRUTH, f"{sensor}_bias_random")))
            law_g, law_a = laws
        else:
            k_g = k_a = np.ones(3)
        segments = ds.segments("turntable")
        if not segments:
            raise UserInputError(f"{path}: no turntable track in the timeline; the navigation "
                                 "scores cover runs at a fixed site")
        try:
            motion = dataset_motion(ds)
        except ValueError as exc:                     # the site or a turntable segment
            raise UserInputError(f"{path}: the run's site and turntable motion cannot be "
                                 f"rebuilt from its root attributes and timeline ({exc}); a "
                                 f"damaged dataset?") from None
        step = _root(ds, "thermal_step_s")
        power = np.asarray(ds.read(fmt.THERMAL, "power_on"))
        on = np.nonzero(power >= 1)[0]
        if on.size == 0:
            raise UserInputError(f"{path}: the IMU is never powered (thermal/power_on)")
        start = int(math.ceil(on[0] * step * rate))
        lost = np.zeros(0, dtype=np.intp)
        if need_imu and ds.has(fmt.IMU, "sample_valid"):
            lost = start + np.flatnonzero(np.asarray(ds.read(fmt.IMU, "sample_valid"))[start:]
                                          == 0)

        def lost_line(k: int, count: int) -> str:
            return (f"{path}: imu/sample_valid: frame {k} ({k / rate:g} s) was lost ({count} "
                    f"lost frame(s) in the navigated span, counted 0 in the pulses; a device "
                    f"with [anomalies.imu_dropouts])")
        t_start = start / rate
        static_end = start
        for seg in segments:
            if seg["t1"] <= t_start:
                continue
            if seg["attrs"].get("kind") == "static" and seg["t0"] <= t_start + 1e-9:
                static_end = int(math.floor(seg["t1"] * rate + 1e-6))
            break

        def read(k0: int, k1: int) -> tuple[np.ndarray, np.ndarray]:
            return (np.asarray(ds.read(fmt.IMU, "gyro_pulses", slice(k0, k1)), dtype=float),
                    np.asarray(ds.read(fmt.IMU, "accel_pulses", slice(k0, k1)), dtype=float))
        if not need_imu:
            read = None                                 # type: ignore[assignment]

        def truth(k0: int, k1: int) -> tuple[np.ndarray, np.ndarray]:
            mb = motion.increments(k0 / rate, k1 - k0, rate, angles=False)
            return mb.dtheta_rad, mb.dv_m_per_s

        return NavSource(path.name, rate, latitude, height, n,
                         1.0 / k_g, 1.0 / k_a, start, max(static_end, start), read,
                         motion.attitude, truth, step, law_g, law_a, [ds.close],
                         lost, lost_line)
    except BaseException:
        ds.close()
        raise


def _from_recording(path: pathlib.Path) -> NavSource:
    """A recording (table + sidecar) as a :class:`NavSource`: the site, the pulses of the
    three body axes picked by name, the fixed mount's attitude, the dropout rows."""
    from rlgsim.ground.recording import load_recording
    from rlgsim.ground.recording_sidecar import need_fixed_site
    from rlgsim.lab.navigation_mount import body_axes, body_frame
    rec = load_recording(path)
    sc = rec.sidecar
    need_fixed_site(sc, "rlgsim navigate", VEHICLE_ADVICE)
    if not sc.site_given:
        raise UserInputError(f"{sc.path}: [site] latitude_deg missing; navigation needs the "
                             "site's latitude and height in the sidecar")
    if len(rec.gyro_axes) < 3:
        raise UserInputError(f"{sc.path}: {len(rec.gyro_axes)} gyro column(s); navigation needs "
                             "three gyros (x, y, z)")
    if len(rec.accel_axes) < 3:
        raise UserInputError(f"{sc.path}: {len(rec.accel_axes)} accelerometer column(s); "
                             "navigation needs three accelerometers (x, y, z)")
    axes = body_axes(rec.gyro_axes, rec.accel_axes, sc.path)
    k_g = rec._need_sf("gyro")
    k_a = rec._need_sf("accel")
    g = rec.gyro_pulses()[:, [rec.gyro_axes.index(ax) for ax in axes]]
    a = rec.accel_pulses()[:, [rec.accel_axes.index(ax) for ax in axes]]
    c_nb = body_frame(sc.orientation, axes, sc.path)

    def attitude(t: np.ndarray) -> np.ndarray:
        return np.broadcast_to(c_nb.T, (len(t), 3, 3))

    def lost_line(k: int, count: int) -> str:
        return (f"{path}: row {k + 1} is a dropout (dropout = 1; {count} row(s) in the "
                f"navigated span)")

    # as a dataset's, the alignment starts at power-on: the row after the last reading that
    # says unpowered (power_on is a slow column, NaN between readings, each reading the state
    # over the interval it closes — an export starts where its dataset does)
    start = 0
    if "power_on" in rec.columns:
        power = np.asarray(rec.columns["power_on"], dtype=float)
        on = np.flatnonzero(power >= 1)
        if on.size == 0:
            raise UserInputError(f"{path}: column power_on: the IMU is never powered")
        off = np.flatnonzero(~np.isnan(power[:on[0]]))
        start = int(off[-1]) + 1 if off.size else 0
    return NavSource(path.name, rec.sample_rate_hz, sc.latitude_deg, sc.height_m,
                     rec.n_samples, np.full(3, 1.0 / k_g), np.full(3, 1.0 / k_a), start,
                     rec.n_samples, lambda k0, k1: (g[k0:k1], a[k0:k1]), attitude,
                     lost=np.flatnonzero(rec.dropout), lost_line=lost_line)


def gyro_units_source(units: Sequence[tuple[str | os.PathLike, str | None, int]]
                      ) -> NavSource:
    """Single gyros of simulated datasets as the axes of one otherwise ideal IMU.

    ``units``: (dataset, gyro axis or None for its first gyro, body axis it is mounted on:
    0 x, 1 y, 2 z) per unit, each dataset a run of the same scenario (the same motion, site
    and sample grid; another drawn unit and other noise). The first dataset gives the site,
    the power-on, the alignment segment and the true motion. The virtual IMU's increments are
    the exact ones of the motion (the truth), except on each unit's body axis, which carries the
    true increment of that axis plus the unit's own gyro error (its pulses × nominal weight
    minus the true increment along its input axis). Its law (``law_gyro``) sits on the same
    axis; the accelerometers are ideal (``law_accel`` None: no accelerometer oracle)."""
    import h5py

    from rlgsim.ground import dataset_format as fmt
    if not units or len({m for _, _, m in units}) != len(units):
        raise ValueError("gyro_units_source: one unit per body axis")
    opened: list[tuple[Any, int, int, float, int]] = []     # file, gyro col, body col, w, mount
    laws: list[tuple[int, np.ndarray]] = []
    base: NavSource | None = None
    try:
        for path, gyro, mount in units:
            p = pathlib.Path(path)
            with fmt.open_dataset(p):
                pass
            f = h5py.File(p, "r")
            opened.append((f, 0, 0, 0.0, mount))
            gyros = [_text(a) for a in f["imu/gyro"][...]]
            axis = gyro if gyro is not None else gyros[0]
            if axis not in gyros:
                raise UserInputError(f"{p}: no gyro {axis!r} (gyros: {', '.join(gyros)})")
            i = gyros.index(axis)
            bodies = [_text(a) for a in f["truth/body"][...]]
            if axis not in bodies:
                raise UserInputError(f"{p}: gyro {axis!r} is not a body axis "
                                     f"({', '.join(bodies)})")
            tr = f["truth"]
            coef = {_text(n): (float(v), _text(u)) for n, v, u in zip(
                tr["coefficient"][...], tr["coefficient_value"][...],
                tr["coefficient_units"][...])}
            w = 1.0 / _weight(coef, f"gyro.k0[{axis}]", "pulses/rad", p)
            opened[-1] = (f, i, bodies.index(axis), w, mount)
            laws.append((mount, np.asarray(tr["gyro_bias"][:, i])
                         - np.asarray(tr["gyro_bias_random"][:, i])))
            if base is None:
                base = _from_dataset_static(p)
            elif (int(f["imu/gyro_pulses"].shape[0]), float(f.attrs["sample_rate_hz"])) != (
                    base.n, base.rate_hz):
                raise UserInputError(f"{p}: {f['imu/gyro_pulses'].shape[0]} samples at "
                                     f"{float(f.attrs['sample_rate_hz']):g} Hz; the IMU's first "
                                     f"unit has {base.n} at {base.rate_hz:g} Hz")
    except BaseException:
        for f, *_ in opened:
            f.close()
        if base is not None:
            base.close()
        raise
    assert base is not None
    law = np.zeros((min(len(x) for _, x in laws), 3))
    for mount, x in laws:
        law[:, mount] = x[:law.shape[0]]
    truth = base.truth
    memo: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def exact(k0: int, k1: int) -> tuple[np.ndarray, np.ndarray]:
        """The motion's increments of samples k0..k1−1, kept for the chunk's second ask."""
        if (k0, k1) not in memo:
            memo.clear()
            memo[(k0, k1)] = truth(k0, k1)
        return memo[(k0, k1)]

    def read(k0: int, k1: int) -> tuple[np.ndarray, np.ndarray]:
        dth, dv = exact(k0, k1)
        out = dth.copy()
        for f, i, b, w, mount in opened:
            pulses = np.asarray(f["imu/gyro_pulses"][k0:k1, i], dtype=float)
            out[:, mount] = dth[:, mount] + (pulses * w - dth[:, b])
        return out, dv

    names = ", ".join(f"{pathlib.Path(p).name} gyro {g or 'first'} on {'xyz'[m]}"
                      for p, g, m in units)
    base.name = f"an ideal IMU with {names}" if len(units) > 1 else (
        f"{pathlib.Path(units[0][0]).name} (gyro {units[0][1] or 'first'} on body axis "
        f"{'xyz'[units[0][2]]} of an ideal IMU)")
    base.read = read
    base.truth = exact
    base.gyro_weight = np.ones(3)
    base.accel_weight = np.ones(3)
    base.law_gyro = law
    base.law_accel = None
    base.closers.extend(f.close for f, *_ in opened)
    return base


def single_gyro_source(path: str | os.PathLike, gyro: str | None = None,
                       mount: int = 1) -> NavSource:
    """One gyro of a simulated dataset as body axis ``mount`` (default 1: North for a table at
    zero) of an otherwise ideal IMU (:func:`gyro_units_source` with one unit)."""
    return gyro_units_source([(path, gyro, mount)])


def open_source(path: str | os.PathLike) -> NavSource:
    """A dataset (HDF5) or a recording (CSV/Parquet + sidecar) as a :class:`NavSource`."""
    from rlgsim.ground.recording import is_recording
    p = pathlib.Path(path)
    if not p.exists():
        raise UserInputError(f"{p}: no such file")
    return _from_recording(p) if is_recording(p) else _from_dataset(p)
