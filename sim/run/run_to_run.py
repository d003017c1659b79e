"""One run is not the next: what changes between two turn-ons of the same unit in the same lab.

A device preset's optional ``[run_to_run]`` table gives the 1-σ spreads (docs/sensors.md,
"Run to run", derives each number); a scenario's ``run_seed`` draws them. Without a
``run_seed`` (or without the table) nothing is drawn and the run is exactly what it was before
this module existed — the same bytes. With both, the run gets

* a **turn-on bias** ``Δb_i ~ N(0, σ_b)`` [°/h] per gyro, added to the bias law's constant:
  the datasheet line "bias repeatability (turn-on to turn-on)" of IEEE Std 647-2006 §B (bias
  repeatability, as distinct from the in-run bias stability); the gyro's bias settles at another
  value each time its discharge and dither start, while its temperature law stays;
* a **laboratory offset** ``ΔT_lab ~ N(0, σ_lab)`` [K] on every boundary of the thermal network
  (the laboratory air seen through the turntable shaft or the mounting plate's bolts: another
  day, another air-conditioning state);
* a **chamber offset** ``ΔT_ch ~ N(0, σ_ch)`` [K] on the chamber programme's temperatures (the
  air at the unit's place after it was mounted again: chamber spatial uniformity; the rate
  limit and air lag stay);
* a **film factor** ``f_film = exp(σ_film·N(0,1))`` on every conductance to the chamber air (the
  fan's flow over the unit differs with its position and the chamber's load; the linearised
  radiative share of those links is scaled with it — docs/sensors.md says by how much that
  widens the spread of the convective part);
* a **mount factor** ``f_mount = exp(σ_mount·N(0,1))`` on the links named in ``mount_links``
  (a bolted contact's conductance after re-mounting: torque, flatness, contact pressure).

Every quantity has its own stream ``generator(run_seed, unit, "run_to_run", <name>, 0)``
(:mod:`rlgsim.sim.rng`), so switching one mechanism off (a spread of 0, the ablation of
benchmarks/ablation_run_to_run.py) leaves the others' draws as they were, and "the same unit
on a new day" is the same ``device_seed`` with another ``run_seed``. The unit's own drawn
realisation (``device_seed``, :meth:`rlgsim.sim.thermal.network.ThermalNetwork.realise`, the
sensor tolerances) is not touched: the factors here multiply whatever the unit is.

:func:`applied` returns the scenario as the run sees it (device network, gyro law and chamber
programme changed); :func:`rlgsim.sim.run.simulate.simulate` calls it once, before anything is
built, and writes :func:`attrs` into the dataset's root attributes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_list, get_str
from rlgsim.sim.rng import generator

__all__ = ["RunToRun", "RunDraw", "draw", "applied", "attrs"]

_KEYS = ("description", "source", "turn_on_bias_deg_per_h", "lab_offset_c", "chamber_offset_c",
         "film_coefficient_rel", "mount_conductance_rel", "mount_links")
#: the spreads, in the order the report prints them
SPREADS = ("turn_on_bias_deg_per_h", "lab_offset_c", "chamber_offset_c", "film_coefficient_rel",
           "mount_conductance_rel")


@dataclass(frozen=True)
class RunToRun:
    """The ``[run_to_run]`` table: 1-σ spreads of what changes between runs (module docstring).
    ``mount_links`` are node-name pairs of the device's thermal network."""

    turn_on_bias_deg_per_h: float = 0.0
    lab_offset_c: float = 0.0
    chamber_offset_c: float = 0.0
    film_coefficient_rel: float = 0.0
    mount_conductance_rel: float = 0.0
    mount_links: tuple[tuple[str, str], ...] = ()
    source: str = ""

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "RunToRun":
        """Validate ``[run_to_run]`` (every spread >= 0; relative spreads <= 1)."""
        check_known_keys(table, _KEYS, ctx)
        values = {k: get_float(table, k, ctx, 0.0, min=0.0,
                               max=1.0 if k.endswith("_rel") else math.inf) for k in SPREADS}
        links = []
        for i, pair in enumerate(get_list(table, "mount_links", ctx, [])):
            if (not isinstance(pair, list) or len(pair) != 2
                    or not all(isinstance(p, str) and p for p in pair)):
                raise ctx.item(i).error("mount_links", f"value {pair!r} not allowed; each entry "
                                        "is a pair of node names, e.g. [\"base\", \"table\"]")
            links.append((pair[0], pair[1]))
        if values["mount_conductance_rel"] > 0 and not links:
            raise ctx.error("mount_links", "missing: mount_conductance_rel > 0 needs the links "
                                           "it spreads (pairs of node names)")
        get_str(table, "description", ctx, "")
        return cls(**values, mount_links=tuple(links), source=get_str(table, "source", ctx, ""))

    def check_network(self, network, ctx: Ctx) -> None:
        """Every mount link joins two nodes of ``network`` by a conductance > 0; a laboratory
        offset needs a boundary to act on."""
        names = list(network.node_names)
        for a, b in self.mount_links:
            for n in (a, b):
                if n not in names:
                    raise ctx.error("mount_links", f"node {n!r} is not in the thermal network")
            if network.conductance_w_per_k[names.index(a), names.index(b)] <= 0:
                raise ctx.error("mount_links", f"there is no link between {a!r} and {b!r}")
        if self.lab_offset_c > 0 and not network.boundaries:
            raise ctx.error("lab_offset_c", "the thermal network has no boundary (laboratory) "
                                            "to offset; use 0 or give the network one")

    @property
    def active(self) -> bool:
        return any(getattr(self, k) > 0 for k in SPREADS)


@dataclass(frozen=True)
class RunDraw:
    """The values drawn for one run: turn-on bias per gyro [°/h], offsets [K], factors."""

    run_seed: int
    turn_on_bias_deg_per_h: tuple[float, ...]
    lab_offset_c: float
    chamber_offset_c: float
    film_factor: float
    mount_factor: float


def _normal(run_seed: int, unit: int, name: str, n: int = 1) -> np.ndarray:
    return generator(run_seed, unit, "run_to_run", name, 0).standard_normal(n)


def draw(scenario) -> RunDraw | None:
    """The run-to-run values of ``scenario`` (None without ``run_seed`` or ``[run_to_run]``)."""
    spec = scenario.device.parts.get("run_to_run")
    seed = getattr(scenario, "run_seed", None)
    if spec is None or seed is None:
        return None
    unit = scenario.unit
    gyro = scenario.device.parts.get("gyro")
    n = len(gyro.axes) if gyro is not None else 0
    bias = spec.turn_on_bias_deg_per_h * _normal(seed, unit, "turn_on_bias", n) if n else ()
    return RunDraw(
        run_seed=int(seed), turn_on_bias_deg_per_h=tuple(float(v) for v in bias),
        lab_offset_c=float(spec.lab_offset_c * _normal(seed, unit, "lab_offset")[0]),
        chamber_offset_c=float(spec.chamber_offset_c * _normal(seed, unit, "chamber_offset")[0]),
        film_factor=float(np.exp(spec.film_coefficient_rel * _normal(seed, unit, "film")[0])),
        mount_factor=float(np.exp(spec.mount_conductance_rel * _normal(seed, unit, "mount")[0])))


def varied_network(network, d: RunDraw, mount_links: tuple[tuple[str, str], ...]):
    """``network`` with the film factor on the chamber-air conductances, the mount factor on
    ``mount_links`` and the laboratory offset on every boundary; the nonlinear parts of the
    changed links are scaled with them."""
    names = list(network.node_names)
    g = network.ambient_conductance_w_per_k * d.film_factor
    G = np.array(network.conductance_w_per_k, dtype=float)
    mount = set()
    for a, b in mount_links:
        i, j = names.index(a), names.index(b)
        G[i, j] *= d.mount_factor
        G[j, i] = G[i, j]
        mount.add(frozenset((i, j)))
    links = []
    for ln in network.nonlinear_links:
        f = (d.film_factor if ln.b == -1
             else d.mount_factor if ln.b >= 0 and frozenset((ln.a, ln.b)) in mount else 1.0)
        links.append(dataclasses.replace(ln, coefficient=ln.coefficient * f,
                                         linear_w_per_k=ln.linear_w_per_k * f))
    bounds = tuple(dataclasses.replace(b, temperature_c=b.temperature_c + d.lab_offset_c)
                   for b in network.boundaries)
    return dataclasses.replace(network, ambient_conductance_w_per_k=g, conductance_w_per_k=G,
                               nonlinear_links=tuple(links), boundaries=bounds)


def _gyro_with_offset(gyro, offsets: tuple[float, ...]):
    """The gyro model with ``offsets`` [°/h] added to each gyro's nominal bias constant."""
    nominal = dict(gyro.bias.nominal)
    nominal["value"] = np.asarray(nominal["value"], dtype=float) + np.asarray(offsets)
    return dataclasses.replace(gyro, bias=dataclasses.replace(gyro.bias, nominal=nominal))


def applied(scenario):
    """``scenario`` as its run sees it: unchanged when :func:`draw` is None, else with the
    varied thermal network, gyro bias constant and chamber programme (module docstring)."""
    d = draw(scenario)
    if d is None:
        return scenario
    spec = scenario.device.parts["run_to_run"]
    device = scenario.device
    thermal = dataclasses.replace(device.thermal, network=varied_network(
        device.thermal.network, d, spec.mount_links))
    parts = dict(device.parts)
    if "gyro" in parts and any(d.turn_on_bias_deg_per_h):
        parts["gyro"] = _gyro_with_offset(parts["gyro"], d.turn_on_bias_deg_per_h)
    device = dataclasses.replace(device, thermal=thermal, parts=parts)
    chamber = scenario.chamber
    if d.chamber_offset_c != 0.0:
        from rlgsim.sim.run.unit_variations import vary_program
        chamber = vary_program(chamber, d.chamber_offset_c, 1.0)
    return dataclasses.replace(scenario, device=device, chamber=chamber)


def attrs(scenario) -> dict[str, Any]:
    """Root attributes of a run with a ``run_seed`` (none without one): the seed and the drawn
    values, so a dataset says which day it was."""
    seed = getattr(scenario, "run_seed", None)
    if seed is None:
        return {}
    out: dict[str, Any] = {"run_seed": np.int64(seed)}
    d = draw(scenario)
    if d is not None:
        out.update({"run_turn_on_bias_deg_per_h": np.asarray(d.turn_on_bias_deg_per_h),
                    "run_lab_offset_c": d.lab_offset_c,
                    "run_chamber_offset_c": d.chamber_offset_c,
                    "run_film_factor": d.film_factor, "run_mount_factor": d.mount_factor})
    return out
