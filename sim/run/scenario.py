"""The validating scenario loader: a TOML scenario (by shipped name or path) → :class:`Scenario`.

A scenario names a device preset, a site, the acquisition rates, the power schedule, the
chamber programme, the turntable programme, the duration and the seed (docs/scenarios.md lists
every key with its unit). This module validates the top level and the small tables it owns
(``site``, ``acquisition``, ``power``); each other table is validated by the module that owns
it (``[chamber]`` by :class:`rlgsim.sim.thermal.chamber.ChamberProgram`, ``[turntable]`` by
:mod:`rlgsim.sim.motion.turntable`, the device's ``[thermal]`` by
:class:`rlgsim.sim.thermal.network.ThermalNetwork`, its sensor tables by the sensor modules — see
:data:`DEVICE_TABLES`). Every user mistake is a one-line
:class:`~rlgsim.ground.errors.UserInputError` naming file, key, value and what is allowed.
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np

from rlgsim.sim import presets
from rlgsim.sim.sensors.accelerometer import AccelerometerModel
from rlgsim.sim.sensors.anomaly_model import AnomalyModel
from rlgsim.sim.thermal.chamber import ChamberProgram
from rlgsim.sim.config import (TIME_UNITS, Ctx, check_known_keys, get_bool, get_float, get_int,
                               get_quantity, get_str, get_table, unit_keys)
from rlgsim.sim.motion.site import Site
from rlgsim.sim.sensors.gyro import GyroModel
from rlgsim.sim.sensors.imu_model import Tolerance
from rlgsim.sim.sensors.noise import NoiseModel
from rlgsim.sim.rng import BLOCK_S, generator
from rlgsim.sim.run.run_to_run import RunToRun
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.thermometers import ProbeSet
from rlgsim.sim.motion.turntable import TurntableProgram
from rlgsim.sim.sensors.uhfo import UhfoModel

__all__ = ["ThermalPreset", "Device", "load_thermal_preset", "load_device", "Acquisition",
           "PowerSchedule", "Scenario", "parse_scenario", "load_scenario"]

#: A device-table validator: ``f(table, ctx)`` -> the validated object (UserInputError if bad).
TableValidator = Callable[[Mapping[str, Any], Ctx], Any]

#: Tables a device preset may hold besides ``[device]``, each with the validator of the module
#: that owns it, called as ``f(table, ctx)``; the result is stored in ``Device.parts[name]``.
#: ``None`` = accepted as is (kept raw in ``Device.tables``). Sensor modules add their tables
#: here.
DEVICE_TABLES: dict[str, TableValidator | None] = {
    "gyro": GyroModel.from_config,
    "accelerometer": AccelerometerModel.from_config,
    "uhfo": UhfoModel.from_config,
    "noise": NoiseModel.from_config,
    "tolerance": Tolerance.from_config,
    "anomalies": AnomalyModel.from_config,          # optional sensor anomalies (anomaly_model.py)
    "run_to_run": RunToRun.from_config,             # optional turn-on and lab spreads (sim/run/run_to_run.py)
}

#: Keys of a device preset's ``[device]`` table.
DEVICE_KEYS = ("name", "description", "source", "thermal_preset")

#: Top-level keys of a scenario (tables included). Later issues add theirs here and parse them.
SCENARIO_KEYS = ("name", "description", "seed", "device_seed", "run_seed", "device",
                 *unit_keys("duration", TIME_UNITS), "site", "acquisition", "power", "chamber",
                 "turntable", "trajectory", "vehicle_bay")

_TOLERANCE = 1e-9


# --------------------------------------------------------------------------- device presets


@dataclass(frozen=True)
class ThermalPreset:
    """A thermal network preset: the network (nodes, links, heat) and the probes on it."""

    name: str
    source: str
    text: str
    network: ThermalNetwork
    probes: ProbeSet


@dataclass(frozen=True)
class Device:
    """A device preset: identity, its thermal preset, and the tables sensor modules read."""

    name: str
    description: str
    reference: str                        # where the numbers come from (paper, datasheet)
    source: str                           # the preset file
    text: str
    thermal: ThermalPreset
    tables: dict[str, dict] = field(default_factory=dict)   # raw tables, by name
    parts: dict[str, Any] = field(default_factory=dict)     # validated tables (DEVICE_TABLES)
    base_dir: Any = None                  # where the preset's relative references resolve

    def with_changes(self, changes: Mapping[str, Any]) -> "Device":
        """This preset with dotted keys changed (``{"gyro.bias.c1_deg_per_h_per_k": 2e-4}``),
        validated again; its ``text`` is the preset's TOML edited in place (comments kept)
        under a comment naming the changes — the text every dataset embeds."""
        from rlgsim.ground.toml_text import value_text, with_values
        said = ", ".join(f"{k} = {value_text(v) if v is not None else '(removed)'}"
                         for k, v in changes.items())
        text = (f"# device {self.name}, from {self.source}, with {said}\n"
                + with_values(self.text, dict(changes)))
        source = f"{self.source} (changed: {', '.join(changes)})"
        return device_from_file(presets.TomlFile(
            name=self.name, source=source, base_dir=self.base_dir, text=text,
            data=presets.parse_toml(text, source)))


def load_thermal_preset(ref: str, *, base_dir: pathlib.Path | None = None,
                        context: str | None = None) -> ThermalPreset:
    """Load a thermal preset (``scenarios/thermal/<name>.toml`` or a path): its ``[thermal]``
    network and its ``[probes]``."""
    f = presets.load_thermal_file(ref, base_dir=base_dir, context=context)
    ctx = Ctx(f.source)
    check_known_keys(f.data, ("thermal", "probes"), ctx)
    network = ThermalNetwork.from_config(get_table(f.data, "thermal", ctx), ctx.child("thermal"))
    probes = ProbeSet.from_config(get_table(f.data, "probes", ctx), network, ctx.child("probes"))
    return ThermalPreset(name=f.name, source=f.source, text=f.text, network=network, probes=probes)


def validate_device_tables(data: Mapping[str, Any], ctx: Ctx) -> tuple[dict, dict]:
    """The sensor tables of a device preset's ``data`` (:data:`DEVICE_TABLES`), each checked by
    its module's validator: (raw tables, validated parts); a mistake is one UserInputError
    line naming ``ctx``'s file and the key."""
    tables: dict[str, dict] = {}
    parts: dict[str, Any] = {}
    for key, validate in DEVICE_TABLES.items():
        if key in data:
            tables[key] = get_table(data, key, ctx)
            if validate is not None:
                parts[key] = validate(tables[key], ctx.child(key))
    return tables, parts


def load_device(ref: str, *, base_dir: pathlib.Path | None = None,
                context: str | None = None) -> Device:
    """Load and validate a device preset (``scenarios/devices/<name>.toml`` or a path)."""
    return device_from_file(presets.load_device_file(ref, base_dir=base_dir, context=context))


def device_from_file(f: "presets.TomlFile") -> Device:
    """The validated :class:`Device` of a parsed preset file."""
    ctx = Ctx(f.source)
    check_known_keys(f.data, ["device", *DEVICE_TABLES], ctx)
    dev = get_table(f.data, "device", ctx)
    dctx = ctx.child("device")
    check_known_keys(dev, DEVICE_KEYS, dctx)
    thermal_ref = get_str(dev, "thermal_preset", dctx)
    thermal = load_thermal_preset(thermal_ref, base_dir=f.base_dir,
                                  context=f"{f.source}: device.thermal_preset")
    tables, parts = validate_device_tables(f.data, ctx)
    if "run_to_run" in parts:
        parts["run_to_run"].check_network(thermal.network, ctx.child("run_to_run"))
    return Device(name=get_str(dev, "name", dctx, f.name),
                  description=get_str(dev, "description", dctx, ""),
                  reference=get_str(dev, "source", dctx, ""),
                  source=f.source, text=f.text, thermal=thermal, tables=tables, parts=parts,
                  base_dir=f.base_dir)


# --------------------------------------------------------------------------- scenario tables


@dataclass(frozen=True)
class Acquisition:
    sample_rate_hz: float = 100.0   # IMU output rate [Hz]
    thermal_step_s: float = 1.0     # thermal grid step [s]
    chunk_s: float = 3600.0         # simulated time buffered per write [s]
    truth_samples: bool = False     # also store the true increments per IMU sample (rlgsim.sim.sensors.imu)


@dataclass(frozen=True)
class PowerSchedule:
    on_at_s: float = 0.0            # power switched on [s from start]
    off_at_s: float | None = None   # switched off again (None: stays on)


def _divides_block(value: float, per: str) -> bool:
    n = BLOCK_S / value if per == "step" else BLOCK_S * value
    if not math.isfinite(n):        # a subnormal step: BLOCK_S / value overflows to inf
        return False
    return abs(n - round(n)) < 1e-6 * max(1.0, n) and round(n) >= 1


def _parse_site(table: dict, ctx: Ctx) -> Site:
    return Site.from_config(table, ctx)


def _parse_acquisition(table: dict, ctx: Ctx) -> Acquisition:
    check_known_keys(table, ("sample_rate_hz", "thermal_step_s", "chunk_s", "truth_samples"), ctx)
    rate = get_float(table, "sample_rate_hz", ctx, 100.0, min=0.0, min_exclusive=True,
                     max=100000.0)
    if not _divides_block(rate, "sample"):
        raise ctx.error("sample_rate_hz", f"value {rate:g} not allowed; {BLOCK_S:g} s must hold "
                                          f"a whole number of samples (e.g. 1, 10, 100, 400)")
    step = get_float(table, "thermal_step_s", ctx, 1.0, min=0.0, min_exclusive=True,
                     max=BLOCK_S)
    if not _divides_block(step, "step"):
        raise ctx.error("thermal_step_s", f"value {step:g} not allowed; must divide {BLOCK_S:g} s "
                                          f"exactly (e.g. 0.1, 0.5, 1, 2, 5, 10)")
    chunk = get_float(table, "chunk_s", ctx, 3600.0, min=0.0, min_exclusive=True)
    return Acquisition(sample_rate_hz=rate, thermal_step_s=step, chunk_s=chunk,
                       truth_samples=get_bool(table, "truth_samples", ctx, False))


def _parse_power(table: dict, ctx: Ctx) -> PowerSchedule:
    check_known_keys(table, (*unit_keys("on_at", TIME_UNITS), *unit_keys("off_at", TIME_UNITS)),
                     ctx)
    on = get_quantity(table, "on_at", ctx, TIME_UNITS, 0.0, min=0.0)
    off = get_quantity(table, "off_at", ctx, TIME_UNITS, None, min=0.0)
    if off is not None and off <= on:
        key = next(k for k in unit_keys("off_at", TIME_UNITS) if k in table)
        raise ctx.error(key, f"value {table[key]!r} not allowed; must be after power-on "
                             f"({on:g} s)")
    return PowerSchedule(on_at_s=on, off_at_s=off)


# --------------------------------------------------------------------------- the scenario


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. Times in s, temperatures in °C (see docs/scenarios.md)."""

    name: str
    description: str
    source: str                  # the file (or "<string>")
    text: str                    # the raw TOML, embedded in every dataset
    seed: int
    device: Device
    site: Site                   # rlgsim.sim.motion.site.Site
    acquisition: Acquisition
    power: PowerSchedule
    chamber: ChamberProgram
    turntable: TurntableProgram  # program = "static" when the scenario has no [turntable]
    duration_s: float            # on the thermal grid
    tables: dict = field(default_factory=dict, repr=False)   # the parsed TOML, for later issues
    device_seed: int | None = None   # seed of the unit's drawn realisation (None: ``seed``)
    unit: int = 0                    # Monte Carlo unit index in the seed tree (runs: 0)
    #: a vehicle's route instead of the turntable (rlgsim.sim.motion.trajectory_config; None:
    #: the turntable)
    trajectory: Any = None
    #: the airflow of the vehicle's bay (rlgsim.sim.thermal.vehicle_bay; None: still air)
    vehicle_bay: Any = None
    run_seed: int | None = None      # draws the run-to-run spreads (sim/run/run_to_run.py)

    @property
    def realisation_seed(self) -> int:
        """Seed of the device realisation: ``device_seed`` if given, else ``seed``. Two runs
        with the same device seed and unit are the same physical unit (paper 001's train and
        test runs), while their noise (keyed by ``seed``) differs."""
        return self.seed if self.device_seed is None else self.device_seed

    def chamber_rng(self) -> np.random.Generator:
        """The generator that expands the chamber programme (repeat/random segments)."""
        return generator(self.seed, 0, "chamber", "programme", 0)

    def with_changes(self, changes: dict | None = None, /, **keys) -> "Scenario":
        """This scenario with TOML keys changed (dotted paths, e.g. ``{"chamber.start_c": 25}``,
        or top-level keywords ``seed=3``), validated again; its ``text`` is the changed TOML
        (:mod:`rlgsim.sim.run.scenario_changes`)."""
        from rlgsim.sim.run.scenario_changes import changed_text
        todo = {**(changes or {}), **keys}
        # "device.<table>.<key>" changes a key of the device preset the scenario names
        dev = {k[len("device."):]: v for k, v in todo.items() if k.startswith("device.")}
        todo = {k: v for k, v in todo.items() if not k.startswith("device.")}
        out = self
        if todo:
            src = pathlib.Path(self.source)
            out = parse_scenario(changed_text(self, todo),
                                 f"{self.source} (changed: {', '.join(todo)})",
                                 base_dir=src.parent if src.is_file() else None,
                                 default_name=self.name)
        if dev:
            import dataclasses
            out = dataclasses.replace(out, device=out.device.with_changes(dev))
        return out


def _parse_turntable(table: dict | None, ctx: Ctx) -> TurntableProgram:
    return TurntableProgram.from_config(table, ctx)


def _parse_trajectory(data: Mapping[str, Any], ctx: Ctx, base_dir: pathlib.Path | None) -> Any:
    """The ``[trajectory]`` table (a vehicle): no ``[turntable]`` and no ``[site]`` beside it
    (the route's start is the site)."""
    from rlgsim.sim.motion.trajectory_config import TrajectoryProgram
    for other in ("turntable", "site"):
        if other in data:
            raise ctx.error(other, f"not allowed with [trajectory]: the IMU rides the vehicle "
                                   f"(its start is the site); give one of [{other}] and "
                                   f"[trajectory]")
    return TrajectoryProgram.from_config(get_table(data, "trajectory", ctx),
                                         ctx.child("trajectory"), base_dir)


def parse_scenario(text: str, source: str = "<string>", *,
                   base_dir: pathlib.Path | None = None, default_name: str = "scenario"
                   ) -> Scenario:
    """Parse and validate scenario TOML ``text`` (``source`` names it in messages)."""
    data = presets.parse_toml(text, source)
    ctx = Ctx(source)
    check_known_keys(data, SCENARIO_KEYS, ctx)
    name = get_str(data, "name", ctx, default_name)
    description = get_str(data, "description", ctx, "")
    seed = get_int(data, "seed", ctx, 0, min=0, max=2**63 - 1)
    device_seed = get_int(data, "device_seed", ctx, None, min=0, max=2**63 - 1)
    run_seed = get_int(data, "run_seed", ctx, None, min=0, max=2**63 - 1)
    device = load_device(get_str(data, "device", ctx), base_dir=base_dir,
                         context=f"{source}: device")
    trajectory = vehicle_bay = None
    if "vehicle_bay" in data:
        if "trajectory" not in data:
            raise ctx.error("vehicle_bay", "only with [trajectory]: the bay's airflow follows "
                                           "the vehicle's speed")
        from rlgsim.sim.thermal.vehicle_bay import VehicleBay
        vehicle_bay = VehicleBay.from_config(get_table(data, "vehicle_bay", ctx),
                                             ctx.child("vehicle_bay"))
    if "trajectory" in data:
        trajectory = _parse_trajectory(data, ctx, base_dir)
        site = Site(latitude_deg=math.degrees(trajectory.initial.lat_rad),
                    height_m=trajectory.initial.height_m)
    else:
        site = _parse_site(get_table(data, "site", ctx, {}), ctx.child("site"))
    acquisition = _parse_acquisition(get_table(data, "acquisition", ctx, {}),
                                     ctx.child("acquisition"))
    power = _parse_power(get_table(data, "power", ctx, {}), ctx.child("power"))
    chamber = ChamberProgram.from_config(get_table(data, "chamber", ctx), ctx.child("chamber"))
    turntable = _parse_turntable(get_table(data, "turntable", ctx, None), ctx.child("turntable"))
    step = acquisition.thermal_step_s
    duration = get_quantity(data, "duration", ctx, TIME_UNITS, None, min=0.0, min_exclusive=True)
    key = "duration"
    if duration is None and trajectory is not None:
        duration, key = trajectory.duration_s, "trajectory"     # the run lasts the route
    if duration is None:
        rng = generator(seed, 0, "chamber", "programme", 0)
        duration = float(chamber.rate_limited(chamber.setpoint(rng)).end_s)
        if duration <= 0:
            raise ctx.error("duration_h", "missing: the chamber programme has no length, so give "
                                          "the run's duration (duration_s, duration_min or "
                                          "duration_h)")
    steps = max(1, round(duration / step))
    if steps > 10**9:
        raise ctx.error(key, f"{duration:g} s at a {step:g} s thermal step is too long "
                             f"(more than 1e9 steps)"
                        + ("; the run lasts the route: give the scenario a duration_s, or "
                           "shorten the segments" if key == "trajectory" else ""))
    return Scenario(name=name, description=description, source=source, text=text, seed=seed,
                    device=device, site=site, acquisition=acquisition, power=power,
                    chamber=chamber, turntable=turntable, duration_s=steps * step, tables=data,
                    device_seed=device_seed, trajectory=trajectory, vehicle_bay=vehicle_bay,
                    run_seed=run_seed)


def load_scenario(ref: str) -> Scenario:
    """Load a scenario by shipped name (``rlgsim list``) or by path."""
    f = presets.load_scenario_file(ref)
    return parse_scenario(f.text, f.source, base_dir=f.base_dir, default_name=f.name)
