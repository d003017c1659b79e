"""The IMU *model* (nominal values + tolerances of a device preset) versus one drawn
*realisation* (the truth of one unit).

Model and realisation (as in pyins' ``sim`` or any Monte Carlo of a sensor lot): the device
preset's ``[gyro]``, ``[accelerometer]``, ``[uhfo]`` and ``[noise]`` tables give nominal laws and
noise levels; ``[tolerance]`` gives the unit-to-unit spread (1σ). :meth:`ImuModel.realise` draws
one unit: every coefficient of every law of every axis, and the noise levels, from keyed
sub-streams of the given generator (adding a coefficient never changes the others). The
realisation is the truth of that unit — stored in the dataset's ``truth`` group as a table
(:meth:`ImuRealisation.coefficient_table`). The block-by-block simulation of a realisation is
:class:`rlgsim.sim.sensors.imu.ImuSimulator`.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_table
from rlgsim.sim.sensors.accelerometer import AccelerometerModel, Accelerometers
from rlgsim.sim.sensors.gyro import BODY_AXES, GyroModel, Gyros
from rlgsim.sim.sensors.noise import NOISE_LEVELS, NoiseModel
from rlgsim.sim.sensors.uhfo import Uhfo, UhfoModel

__all__ = ["Tolerance", "ImuModel", "ImuRealisation"]

_NOISE_REL_KEYS = tuple(f"{k}_rel" for k in NOISE_LEVELS)


@dataclass(frozen=True)
class Tolerance:
    """The ``[tolerance]`` preset table: unit-to-unit spreads (1σ).

    Sub-tables ``gyro`` / ``accelerometer`` (one sub-table per law, same keys as the law),
    ``uhfo`` (law keys, ``wander_rel``, ``noise_rel``) and ``noise`` (relative spreads
    ``gyro_arw_rel``, ``gyro_bi_rel``, ``gyro_rrw_rel``, ``accel_vrw_rel``, ``accel_bi_rel``,
    ``accel_rrw_rel``). Law sub-tables are checked against their laws when the model is built.
    """

    gyro: Mapping | None
    accelerometer: Mapping | None
    uhfo: Mapping | None
    noise: Mapping[str, float]
    ctx: Ctx

    @classmethod
    def from_config(cls, table: Mapping, ctx: Ctx) -> "Tolerance":
        check_known_keys(table, ("gyro", "accelerometer", "uhfo", "noise"), ctx)
        noise = get_table(table, "noise", ctx, {})
        nctx = ctx.child("noise")
        check_known_keys(noise, _NOISE_REL_KEYS, nctx)
        rel = {k[:-4]: get_float(noise, k, nctx, 0.0, min=0.0, max=1.0) for k in _NOISE_REL_KEYS}
        return cls(gyro=get_table(table, "gyro", ctx, None),
                   accelerometer=get_table(table, "accelerometer", ctx, None),
                   uhfo=get_table(table, "uhfo", ctx, None), noise=rel, ctx=ctx)


def _keyed_draw(rng: np.random.Generator):
    """``draw(name, shape)``: standard normals from a sub-stream keyed by ``name``."""
    base = int(rng.integers(0, 2**63 - 1))

    def draw(name: str, shape: tuple[int, ...]) -> np.ndarray:
        sub = np.random.Generator(np.random.PCG64(
            np.random.SeedSequence(entropy=base, spawn_key=(zlib.crc32(name.encode()),))))
        return sub.standard_normal(shape)
    return draw


@dataclass(frozen=True)
class ImuModel:
    """A device's sensors: nominal laws + tolerances (the *model*, not a unit).

    ``gyro`` always; ``accel`` and ``uhfo`` optional; ``noise`` levels; ``noise_rel`` relative
    1σ spreads of the noise levels; ``source`` the preset file (for messages).
    """

    gyro: GyroModel
    accel: AccelerometerModel | None
    uhfo: UhfoModel | None
    noise: NoiseModel
    noise_rel: Mapping[str, float]
    source: str = ""

    @classmethod
    def from_device(cls, device) -> "ImuModel | None":
        """The model of a :class:`rlgsim.sim.run.scenario.Device` (None when it has no ``[gyro]``)."""
        parts = dict(getattr(device, "parts", {}) or {})
        tables = dict(getattr(device, "tables", {}) or {})
        return cls.from_tables(tables, device.source, parts=parts)

    @classmethod
    def from_tables(cls, tables: Mapping[str, Mapping], source: str = "",
                    parts: Mapping[str, Any] | None = None) -> "ImuModel | None":
        """Build from raw preset tables (``gyro``, ``accelerometer``, ``uhfo``, ``noise``,
        ``tolerance``); already validated ``parts`` are reused. Raises UserInputError."""
        parts = dict(parts or {})
        ctx = Ctx(source)

        def part(name: str, cls_):
            if name in parts:
                return parts[name]
            if name in tables:
                return cls_.from_config(tables[name], ctx.child(name))
            return None
        gyro = part("gyro", GyroModel)
        if gyro is None:
            for other in ("accelerometer", "uhfo", "noise", "tolerance"):
                if other in tables:
                    raise ctx.error(other, "needs a [gyro] table in the same device preset")
            return None
        accel = part("accelerometer", AccelerometerModel)
        uhfo = part("uhfo", UhfoModel)
        noise = part("noise", NoiseModel) or NoiseModel()
        tol = part("tolerance", Tolerance) or Tolerance(None, None, None, {}, ctx)
        tctx = ctx.child("tolerance")
        gyro = gyro.with_tolerance(tol.gyro, tctx.child("gyro"))
        if tol.accelerometer is not None:
            if accel is None:
                raise tctx.error("accelerometer", "there is no [accelerometer] table to spread")
            accel = accel.with_tolerance(tol.accelerometer, tctx.child("accelerometer"))
        if uhfo is not None:
            uhfo = uhfo.for_axes(len(gyro.axes)).with_tolerance(tol.uhfo, tctx.child("uhfo"))
        elif tol.uhfo is not None:
            raise tctx.error("uhfo", "there is no [uhfo] table to spread")
        if gyro.bias.nominal["uhfo"].any() and uhfo is None:
            raise ctx.child("gyro").child("bias").error(
                "uhfo_deg_per_h_per_v", "the bias depends on UHFO but the device has no [uhfo]")
        return cls(gyro=gyro, accel=accel, uhfo=uhfo, noise=noise,
                   noise_rel=dict(tol.noise), source=source)

    def realise(self, rng: np.random.Generator) -> "ImuRealisation":
        """Draw one unit from ``rng`` (see the module docstring)."""
        draw = _keyed_draw(rng)
        gyros = self.gyro.realise(draw)
        accels = self.accel.realise(draw) if self.accel is not None else None
        uhfo = (self.uhfo.realise(draw, gyros.axes, gyros.blocks)
                if self.uhfo is not None else None)
        levels = {}
        for key in NOISE_LEVELS:
            n = gyros.n if key.startswith("gyro") else (accels.n if accels else 0)
            rel = self.noise_rel.get(key, 0.0)
            z = draw(f"noise.{key}", (n,)) if rel > 0 else np.zeros(n)
            levels[key] = getattr(self.noise, key) * np.abs(1.0 + rel * z)
        return ImuRealisation(gyros=gyros, accels=accels, uhfo=uhfo, noise=self.noise,
                              levels=levels)


@dataclass
class ImuRealisation:
    """One unit: realised gyros, accelerometers, UHFO and per-axis noise levels (SI)."""

    gyros: Gyros
    accels: Accelerometers | None
    uhfo: Uhfo | None
    noise: NoiseModel
    levels: dict[str, np.ndarray]

    def bind(self, node_names: Sequence[str], source: str = "") -> None:
        """Resolve every law's nodes in the thermal network; a missing node is a
        UserInputError naming the preset and the node."""
        try:
            self.gyros.bind(node_names)
            if self.accels is not None:
                self.accels.bind(node_names)
            if self.uhfo is not None:
                self.uhfo.bind(node_names)
        except KeyError as exc:
            raise UserInputError(
                f"{source + ': ' if source else ''}sensor laws refer to thermal node "
                f"{exc.args[0]!r}, which the device's thermal network does not have; nodes: "
                f"{', '.join(node_names)}") from None

    def coefficient_table(self) -> tuple[list[str], np.ndarray, list[str]]:
        """(names, values, units) of every drawn coefficient, one row per component."""
        names, values, unit_list = [], [], []

        def add(law, comps: Sequence[str]):
            for name, vals, unit in law.table():
                for comp, v in zip(comps, vals):
                    names.append(f"{name}[{comp}]")
                    values.append(float(v))
                    unit_list.append(unit)
        g = self.gyros
        gm = [f"{a}{o}" for a in g.axes for o in BODY_AXES if o != a]
        add(g.bias, g.axes)
        add(g.scale_factor, g.axes)
        add(g.misalignment, gm)
        for a in g.axes:
            names.append(f"gyro.k0[{a}]")
            values.append(g.k0)
            unit_list.append("pulses/rad")
        if self.accels is not None:
            acc = self.accels
            am = [f"{a}{o}" for a in acc.axes for o in BODY_AXES if o != a]
            for law in acc.laws():
                add(law, am if law is acc.misalignment else acc.axes)
            for a in acc.axes:
                names.append(f"accel.k0[{a}]")
                values.append(acc.k0)
                unit_list.append("pulses/(m/s)")
        if self.uhfo is not None:
            add(self.uhfo.law, self.uhfo.axes)
            for a, w, e in zip(self.uhfo.axes, self.uhfo.wander_v, self.uhfo.noise_v):
                names += [f"uhfo.wander_v[{a}]", f"uhfo.noise_v[{a}]"]
                values += [float(w), float(e)]
                unit_list += ["V", "V"]
        si = {"gyro_arw": "rad/s^0.5", "gyro_bi": "rad/s", "gyro_rrw": "rad/s^1.5",
              "accel_vrw": "m/s^1.5", "accel_bi": "m/s^2", "accel_rrw": "m/s^2.5"}
        for key, vals in self.levels.items():
            axes = g.axes if key.startswith("gyro") else (self.accels.axes if self.accels else ())
            for a, v in zip(axes, vals):
                names.append(f"noise.{key}[{a}]")
                values.append(float(v))
                unit_list.append(si[key])
        return names, np.array(values), unit_list
