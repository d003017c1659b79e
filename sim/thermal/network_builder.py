"""The reader of a thermal preset's ``[thermal]`` table: every key checked, nodes and links
gathered, the matrices of :class:`rlgsim.sim.thermal.network.ThermalNetwork` assembled
(:func:`network_fields`; the network's ``from_config`` calls it).

Preset format (``[thermal]`` table; docs/thermal.md has the full reference):

* ``[thermal.materials.<name>]``: ``density_kg_per_m3``, ``specific_heat_j_per_kg_k``,
  ``conductivity_w_per_m_k`` (optional), ``source``.
* ``[thermal.templates.<template>]``: a sub-network written once (``nodes``, ``links``) with
  named ``ports`` (placeholders for outside nodes, e.g. ``mount``, ``air``);
  ``[thermal.instances.<instance>]`` instantiates it (``template``, ``ports = {mount = "base"}``),
  giving nodes ``<instance>.<node>`` (``gx.A``, ``gx.discharge``, ``gx.ballast_D`` ...).
* ``[thermal.nodes.<name>]`` top-level nodes (``ax``, ``base``, ``electronics``,
  ``housing_air``), ``[[thermal.links]]`` top-level links. The reserved node name
  ``chamber_air`` is the chamber air (state column 0 of the integrator).
* ``[thermal.tolerance]``: relative 1-σ unit-to-unit spreads used by :meth:`realise`.

Why this file is over 400 lines: it is one reader of one TOML table, whose checks share the
reader's state (materials, node and boundary indices, face factors, the radiation reference
temperature); each part of the table has its own method.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import (Ctx, check_known_keys, get_float, get_list, get_section, get_str,
                               get_table)
from rlgsim.sim.thermal.network_parts import (CHAMBER_AIR, STEFAN_BOLTZMANN, ZERO_C_K, Boundary,
                                               Heater, Material, NonlinearLink, Tolerance)

__all__ = ["network_fields"]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

_MATERIAL_KEYS = ("density_kg_per_m3", "specific_heat_j_per_kg_k", "conductivity_w_per_m_k",
                  "source", "description")
_NODE_KEYS = ("description", "capacitance_j_per_k", "material", "volume_cm3", "mass_kg",
              "specific_heat_j_per_kg_k", "power_w", "source")
_LINK_KEYS = ("between", "description", "conductance_w_per_k", "conduction", "convection",
              "radiation", "source", "radiation_exact", "natural_convection")
_NATURAL_KEYS = ("h_ref_w_per_m2_k", "reference_dt_k", "area_cm2", "exponent")
_CONDUCTION_KEYS = ("material", "conductivity_w_per_m_k", "area_cm2", "length_mm")
_CONVECTION_KEYS = ("h_w_per_m2_k", "area_cm2", "face")
_RADIATION_KEYS = ("emissivity", "area_cm2")
_TOLERANCE_KEYS = ("capacitance_rel", "conductance_rel", "ambient_conductance_rel", "power_rel",
                   "heater_setpoint_k")
_TEMPLATE_KEYS = ("description", "ports", "nodes", "links")
_INSTANCE_KEYS = ("template", "ports", "description", "power_factors",
                  "capacitance_factors", "link_factors", "source")
_BOUNDARY_KEYS = ("description", "source", "temperature_c", "amplitude_c", "period_h",
                  "phase_deg")
_AIRFLOW_KEYS = ("description", "source", "face_factors")
_HEATER_KEYS = ("description", "source", "node", "sensor", "setpoint_c", "max_power_w",
                "kp_w_per_k", "ti_s", "track_node", "track_gain", "track_reference_c")
_THERMAL_KEYS = ("description", "source", "radiation_reference_c", "materials", "tolerance",
                 "templates", "instances", "nodes", "links", "boundaries", "airflow",
                 "heaters")


@dataclass
class _Node:
    name: str
    capacitance: float
    power: float
    description: str


class _Builder:
    """Reads the ``[thermal]`` table into node and link lists, then into matrices
    (:func:`network_fields`)."""

    def __init__(self, table: Mapping[str, Any], ctx: Ctx) -> None:
        if not isinstance(table, Mapping):
            where = f"{ctx.source}: " if ctx.source else ""
            raise UserInputError(f"{where}{ctx.path or 'thermal'}: expected a table")
        self.table = table
        self.ctx = ctx
        self.nodes: list[_Node] = []
        self.index: dict[str, int] = {}
        # (i, j) -> conductance; j == -1 for the chamber air, j == -2 - b for boundary b
        self.links: dict[tuple[int, int], float] = {}
        self.boundaries: list[Boundary] = []
        self.boundary_index: dict[str, int] = {}
        self.face_factors: dict[str, float] | None = None
        self.nonlinear: list[tuple[tuple[int, int], str, float, float, float, float]] = []

    # ----------------------------------------------------------------- top level

    def build(self) -> dict[str, Any]:
        """The keyword arguments of :class:`rlgsim.sim.thermal.network.ThermalNetwork`, every
        key checked in the order the preset is read (the first mistake is the one named)."""
        t, ctx = self.table, self.ctx
        check_known_keys(t, _THERMAL_KEYS, ctx)
        description = get_str(t, "description", ctx, "")
        get_str(t, "source", ctx, "")
        self.t_ref_k = get_float(t, "radiation_reference_c", ctx, 20.0, min=-100.0,
                                 max=200.0) + ZERO_C_K
        self.materials = self._materials(get_table(t, "materials", ctx, {}), ctx.child("materials"))
        tolerance = self._tolerance(get_table(t, "tolerance", ctx, {}), ctx.child("tolerance"))
        templates_raw = get_table(t, "templates", ctx, {})
        instances = get_table(t, "instances", ctx, {})
        top_nodes = get_table(t, "nodes", ctx, {})
        top_links = get_list(t, "links", ctx, [])
        self._boundaries(get_table(t, "boundaries", ctx, {}), ctx.child("boundaries"))
        if "airflow" in t:
            self._airflow(t, ctx)
        templates = self._templates(templates_raw, ctx.child("templates"))
        # nodes: template instances first (in file order), then top-level nodes
        ictx = ctx.child("instances")
        inst_info = self._instances(instances, templates, ictx)
        nctx = ctx.child("nodes")
        for name, nspec in top_nodes.items():
            self._check_name(name, nctx, "node")
            self._add_node(name, nspec, nctx.child(name))
        # links
        for info in inst_info:
            self._instance_links(*info)
        for k, lspec in enumerate(top_links):
            self._add_link(lspec, ctx.child("links").item(k), lambda ref, lctx: ref)

        if not self.nodes:
            raise ctx.error("nodes", "the network has no nodes")
        heaters = self._heaters(get_table(t, "heaters", ctx, {}), ctx.child("heaters"))
        G, g, Gb = self._matrices()
        return dict(
            node_names=tuple(nd.name for nd in self.nodes),
            capacitance_j_per_k=np.array([nd.capacitance for nd in self.nodes]),
            conductance_w_per_k=G, ambient_conductance_w_per_k=g,
            power_w=np.array([nd.power for nd in self.nodes]), tolerance=tolerance,
            templates={name: tuple(tm["nodes"]) for name, tm in templates.items()},
            instances={inst: get_str(instances[inst], "template", ictx.child(inst))
                       for inst in instances},
            node_descriptions=tuple(nd.description for nd in self.nodes),
            description=description, boundaries=tuple(self.boundaries),
            boundary_conductance_w_per_k=Gb, heaters=heaters,
            nonlinear_links=tuple(NonlinearLink(a=i, b=j, kind=kind, coefficient=c,
                                                linear_w_per_k=lin, reference_dt_k=dt,
                                                exponent=ex)
                                  for (i, j), kind, c, lin, dt, ex in self.nonlinear))

    def _airflow(self, t: Mapping[str, Any], ctx: Ctx) -> None:
        """``[thermal.airflow]``: the convection factors of the faces."""
        air, actx = get_section(t, "airflow", ctx, _AIRFLOW_KEYS)
        get_str(air, "description", actx, "")
        get_str(air, "source", actx, "")
        faces = get_table(air, "face_factors", actx)
        fctx = actx.child("face_factors")
        self.face_factors = {f: get_float(faces, f, fctx, min=0.0, min_exclusive=True,
                                          max=100.0) for f in faces}

    def _templates(self, templates_raw: Mapping[str, Any], tctx: Ctx) -> dict[str, dict]:
        """``[thermal.templates.<name>]``: each template's ports, nodes, links and context."""
        templates: dict[str, dict] = {}
        for name, tmpl in templates_raw.items():
            c = tctx.child(name)
            self._check_name(name, tctx, "template")
            if not isinstance(tmpl, Mapping):
                raise tctx.error(name, "expected a table")
            check_known_keys(tmpl, _TEMPLATE_KEYS, c)
            get_str(tmpl, "description", c, "")
            ports = [get_str({"port": p}, "port", c.child("ports")) for p in
                     get_list(tmpl, "ports", c, [])]
            nodes = get_table(tmpl, "nodes", c)
            if not nodes:
                raise c.error("nodes", "a template needs at least one node")
            for p in ports:
                self._check_name(p, c, "port")
                if p in nodes:
                    raise c.error("ports", f"port {p!r} has the name of a template node")
            templates[name] = {"ports": ports, "nodes": nodes,
                               "links": get_list(tmpl, "links", c, []), "ctx": c}
        return templates

    def _instances(self, instances: Mapping[str, Any], templates: Mapping[str, dict],
                   ictx: Ctx) -> list[tuple[str, dict, dict, Ctx, dict[int, float]]]:
        """``[thermal.instances.<name>]``: adds each instance's nodes (in file order); returns
        ``(instance, template, bound ports, context, link factors)`` for its links."""
        inst_info: list[tuple[str, dict, dict, Ctx, dict[int, float]]] = []
        for inst, spec in instances.items():
            c = ictx.child(inst)
            self._check_name(inst, ictx, "instance")
            if not isinstance(spec, Mapping):
                raise ictx.error(inst, "expected a table")
            check_known_keys(spec, _INSTANCE_KEYS, c)
            get_str(spec, "description", c, "")
            tname = get_str(spec, "template", c, choices=list(templates) or None)
            if tname not in templates:
                raise c.error("template", f"value {tname!r} not allowed; no templates defined")
            tmpl = templates[tname]
            bound = get_table(spec, "ports", c, {})
            check_known_keys(bound, tmpl["ports"], c.child("ports"))
            for p in tmpl["ports"]:
                get_str(bound, p, c.child("ports"))
            get_str(spec, "source", c, "")
            pf = self._factors(spec, "power_factors", c, tmpl["nodes"])
            cf = self._factors(spec, "capacitance_factors", c, tmpl["nodes"])
            lf = self._link_factors(spec, c, tmpl)
            for local, nspec in tmpl["nodes"].items():
                self._check_name(local, tmpl["ctx"].child("nodes"), "node")
                self._add_node(f"{inst}.{local}", nspec, tmpl["ctx"].child("nodes").child(local),
                               power_factor=pf.get(local, 1.0),
                               capacitance_factor=cf.get(local, 1.0))
            inst_info.append((inst, tmpl, bound, c, lf))
        return inst_info

    def _instance_links(self, inst: str, tmpl: dict, bound: dict, c: Ctx,
                        lf: dict[int, float]) -> None:
        """The links of one template instance, their ends resolved to the instance's nodes,
        its bound ports, the chamber air or a boundary."""
        local_nodes = set(tmpl["nodes"])

        def resolve(ref: str, lctx: Ctx) -> str:
            if ref in local_nodes:
                return f"{inst}.{ref}"
            if ref in tmpl["ports"]:
                return bound[ref]
            if ref == CHAMBER_AIR or ref in self.boundary_index:
                return ref
            allowed = sorted(local_nodes) + list(tmpl["ports"]) + [CHAMBER_AIR]
            close = difflib.get_close_matches(ref, allowed, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise lctx.error("between", f"unknown node {ref!r}{hint}; a template link joins "
                                        f"its own nodes, its ports "
                                        f"({', '.join(tmpl['ports']) or 'none'}) or "
                                        f"{CHAMBER_AIR}")

        for k, lspec in enumerate(tmpl["links"]):
            self._add_link(lspec, tmpl["ctx"].child("links").item(k), resolve,
                           bound_ctx=c.child("ports"), factor=lf.get(k, 1.0))

    def _matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The conductances (n, n) between nodes, (n,) to the chamber air and (nb, n) to the
        boundaries, parallel paths summed."""
        n = len(self.nodes)
        G = np.zeros((n, n))
        g = np.zeros(n)
        Gb = np.zeros((len(self.boundaries), n))
        for (i, j), value in self.links.items():
            if j <= -2:
                Gb[-2 - j, i] += value
            elif j < 0:
                g[i] += value
            else:
                G[i, j] += value
                G[j, i] += value
        return G, g, Gb

    # ----------------------------------------------------------------- pieces

    @staticmethod
    def _check_name(name: str, ctx: Ctx, what: str) -> None:
        if not _NAME.match(name) or name == CHAMBER_AIR:
            raise ctx.error(name, f"{what} name {name!r} not allowed; use letters, digits and "
                                  f"'_', starting with a letter (and not '{CHAMBER_AIR}')")

    def _entries(self, table: Mapping[str, Any], ctx: Ctx, keys: tuple[str, ...],
                 what: str | None = None):
        """``(name, spec, its Ctx)`` of each named sub-table (a material, boundary, heater):
        a table with only ``keys``, whose ``description``/``source`` are strings; ``what``
        also checks the name (:meth:`_check_name`)."""
        for name, spec in table.items():
            if what is not None:
                self._check_name(name, ctx, what)
            c = ctx.child(name)
            if not isinstance(spec, Mapping):
                raise ctx.error(name, "expected a table")
            check_known_keys(spec, keys, c)
            get_str(spec, "source", c, "")
            get_str(spec, "description", c, "")
            yield name, spec, c

    def _materials(self, table: Mapping[str, Any], ctx: Ctx) -> dict[str, Material]:
        out = {}
        for name, spec, c in self._entries(table, ctx, _MATERIAL_KEYS):
            out[name] = Material(
                name=name,
                density_kg_per_m3=get_float(spec, "density_kg_per_m3", c, min=0.0,
                                            min_exclusive=True),
                specific_heat_j_per_kg_k=get_float(spec, "specific_heat_j_per_kg_k", c,
                                                   min=0.0, min_exclusive=True),
                conductivity_w_per_m_k=get_float(spec, "conductivity_w_per_m_k", c, None,
                                                 min=0.0, min_exclusive=True))
        return out

    @staticmethod
    def _tolerance(table: Mapping[str, Any], ctx: Ctx) -> Tolerance:
        check_known_keys(table, _TOLERANCE_KEYS, ctx)
        return Tolerance(**{k: get_float(table, k, ctx, 0.0, min=0.0,
                                         max=10.0 if k == "heater_setpoint_k" else 1.0)
                            for k in _TOLERANCE_KEYS})

    def _material(self, spec: Mapping[str, Any], key: str, ctx: Ctx) -> Material:
        name = get_str(spec, key, ctx, choices=list(self.materials) or None)
        if name not in self.materials:
            raise ctx.error(key, f"value {name!r} not allowed; define it under "
                                 f"[thermal.materials.{name}]")
        return self.materials[name]

    def _boundaries(self, table: Mapping[str, Any], ctx: Ctx) -> None:
        for name, spec, c in self._entries(table, ctx, _BOUNDARY_KEYS, "boundary"):
            b = Boundary(name=name,
                         temperature_c=get_float(spec, "temperature_c", c, min=-100.0,
                                                 max=200.0),
                         amplitude_c=get_float(spec, "amplitude_c", c, 0.0, min=0.0, max=50.0),
                         period_s=3600.0 * get_float(spec, "period_h", c, 24.0, min=0.01,
                                                     max=1e4, min_exclusive=True),
                         phase_rad=math.radians(get_float(spec, "phase_deg", c, 0.0,
                                                          min=-360.0, max=360.0)))
            self.boundary_index[name] = len(self.boundaries)
            self.boundaries.append(b)

    def _heaters(self, table: Mapping[str, Any], ctx: Ctx) -> tuple[Heater, ...]:
        out = []
        for name, spec, c in self._entries(table, ctx, _HEATER_KEYS, "heater"):

            def node(key: str, default: Any = None) -> int:
                if default is not None and key not in spec:
                    return -1
                ref = get_str(spec, key, c)
                if ref not in self.index:
                    close = difflib.get_close_matches(ref, list(self.index), n=1)
                    hint = f" (did you mean '{close[0]}'?)" if close else ""
                    raise c.error(key, f"unknown node {ref!r}{hint}")
                return self.index[ref]
            track = node("track_node", default=-1)
            if track < 0 and ("track_gain" in spec or "track_reference_c" in spec):
                raise c.error("track_node", "track_gain / track_reference_c need a track_node")
            out.append(Heater(
                name=name, node=node("node"), sensor=node("sensor"),
                setpoint_c=get_float(spec, "setpoint_c", c, min=-100.0, max=200.0),
                max_power_w=get_float(spec, "max_power_w", c, min=0.0, min_exclusive=True,
                                      max=1e4),
                kp_w_per_k=get_float(spec, "kp_w_per_k", c, min=0.0, min_exclusive=True,
                                     max=1e6),
                ti_s=get_float(spec, "ti_s", c, min=0.0, min_exclusive=True, max=1e7),
                track_node=track,
                track_gain=get_float(spec, "track_gain", c, 0.0, min=-100.0, max=100.0),
                track_reference_c=get_float(spec, "track_reference_c", c, 0.0, min=-100.0,
                                            max=200.0)))
        return tuple(out)

    @staticmethod
    def _factors(spec: Mapping[str, Any], key: str, ctx: Ctx, nodes: Mapping[str, Any]
                 ) -> dict[str, float]:
        """Fixed factors of the nominal unit on template node values (``{node: factor}``)."""
        table = get_table(spec, key, ctx, {})
        c = ctx.child(key)
        check_known_keys(table, list(nodes), c)
        return {k: get_float(table, k, c, min=0.0, min_exclusive=True, max=100.0)
                for k in table}

    @staticmethod
    def _link_factors(spec: Mapping[str, Any], ctx: Ctx, tmpl: Mapping[str, Any]
                      ) -> dict[int, float]:
        """``{"a--b": factor}`` on the template's links, by the names they are written with
        (either order); returns {link index: factor}."""
        table = get_table(spec, "link_factors", ctx, {})
        c = ctx.child("link_factors")
        names: dict[str, int] = {}
        for k, lspec in enumerate(tmpl["links"]):
            between = lspec.get("between") if isinstance(lspec, Mapping) else None
            if isinstance(between, list) and len(between) == 2:
                a, b = (str(x) for x in between)
                names[f"{a}--{b}"] = k
                names[f"{b}--{a}"] = k
        check_known_keys(table, sorted(names), c)
        out: dict[int, float] = {}
        for key in table:
            out[names[key]] = out.get(names[key], 1.0) * get_float(
                table, key, c, min=0.0, min_exclusive=True, max=100.0)
        return out

    def _add_node(self, full: str, spec: Any, ctx: Ctx, power_factor: float = 1.0,
                  capacitance_factor: float = 1.0) -> None:
        if not isinstance(spec, Mapping):
            raise UserInputError(f"{ctx.source + ': ' if ctx.source else ''}{ctx.path}: "
                                 f"expected a table")
        if full in self.index:
            raise UserInputError(f"{ctx.source + ': ' if ctx.source else ''}{ctx.path}: node "
                                 f"{full!r} defined twice")
        check_known_keys(spec, _NODE_KEYS, ctx)
        description = get_str(spec, "description", ctx, "")
        get_str(spec, "source", ctx, "")
        ways = [k for k in ("capacitance_j_per_k", "volume_cm3", "mass_kg") if k in spec]
        if len(ways) != 1:
            raise ctx.error("capacitance_j_per_k", "give exactly one of capacitance_j_per_k, "
                                                   "volume_cm3 (with material) or mass_kg (with "
                                                   "material or specific_heat_j_per_kg_k)")
        if ways[0] == "capacitance_j_per_k":
            check_known_keys(spec, ("description", "source", "capacitance_j_per_k", "power_w"),
                             ctx)
            cap = get_float(spec, "capacitance_j_per_k", ctx, min=0.0, min_exclusive=True)
        elif ways[0] == "volume_cm3":
            check_known_keys(spec, ("description", "source", "material", "volume_cm3",
                                    "power_w"), ctx)
            mat = self._material(spec, "material", ctx)
            vol = get_float(spec, "volume_cm3", ctx, min=0.0, min_exclusive=True) * 1e-6
            cap = mat.density_kg_per_m3 * vol * mat.specific_heat_j_per_kg_k
        else:
            mass = get_float(spec, "mass_kg", ctx, min=0.0, min_exclusive=True)
            if ("material" in spec) == ("specific_heat_j_per_kg_k" in spec):
                raise ctx.error("mass_kg", "give mass_kg with exactly one of material or "
                                           "specific_heat_j_per_kg_k")
            if "material" in spec:
                cap = mass * self._material(spec, "material", ctx).specific_heat_j_per_kg_k
            else:
                cap = mass * get_float(spec, "specific_heat_j_per_kg_k", ctx, min=0.0,
                                       min_exclusive=True)
        power = get_float(spec, "power_w", ctx, 0.0, min=0.0, max=1e4)
        if power_factor != 1.0:
            power = power * power_factor
        if capacitance_factor != 1.0:
            cap = cap * capacitance_factor
        self.index[full] = len(self.nodes)
        self.nodes.append(_Node(full, cap, power, description))

    def _add_link(self, spec: Any, ctx: Ctx, resolve, bound_ctx: Ctx | None = None,
                  factor: float = 1.0) -> None:
        if not isinstance(spec, Mapping):
            raise UserInputError(f"{ctx.source + ': ' if ctx.source else ''}{ctx.path}: "
                                 f"expected a table")
        check_known_keys(spec, _LINK_KEYS, ctx)
        get_str(spec, "description", ctx, "")
        get_str(spec, "source", ctx, "")
        between = get_list(spec, "between", ctx)
        if len(between) != 2 or not all(isinstance(b, str) for b in between):
            raise ctx.error("between", f"expected two node names, got {between!r}")
        a, b = (resolve(x, ctx) for x in between)
        ends = []
        for ref in (a, b):
            if ref == CHAMBER_AIR:
                ends.append(-1)
            elif ref in self.boundary_index:
                ends.append(-2 - self.boundary_index[ref])
            elif ref in self.index:
                ends.append(self.index[ref])
            else:
                close = difflib.get_close_matches(
                    ref, list(self.index) + [CHAMBER_AIR] + list(self.boundary_index), n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                c = bound_ctx if bound_ctx is not None and ref not in between else ctx
                raise c.error("between" if c is ctx else "ports",
                              f"unknown node {ref!r}{hint}")
        if ends[0] == ends[1]:
            raise ctx.error("between", f"a link needs two different nodes, got {between!r}")
        if ends[0] < 0 and ends[1] < 0:
            raise ctx.error("between", f"a link joins at least one node, got {between!r} "
                                       f"(boundaries only)")
        i, j = (ends[1], ends[0]) if ends[0] < 0 else (ends[0], ends[1])
        key = (i, j) if j < 0 else (min(i, j), max(i, j))
        # parallel paths between one pair (e.g. two ports bound to the same node) add up
        value = self._conductance(spec, ctx)
        nl = self._nonlinear(spec, ctx)
        if factor != 1.0:
            value = value * factor
            nl = [(kind, c * factor, lin * factor, dt, ex) for kind, c, lin, dt, ex in nl]
        for kind, c, lin, dt, ex in nl:
            self.nonlinear.append(((i, j), kind, c, lin, dt, ex))
            value += lin
        self.links[key] = self.links.get(key, 0.0) + value

    def _nonlinear(self, spec: Mapping[str, Any], ctx: Ctx
                   ) -> list[tuple[str, float, float, float, float]]:
        """(kind, coefficient, linear part, ΔT_ref, exponent) of the nonlinear link parts."""
        out = []
        if "radiation_exact" in spec:
            c = ctx.child("radiation_exact")
            t = get_table(spec, "radiation_exact", ctx)
            check_known_keys(t, _RADIATION_KEYS, c)
            eps = get_float(t, "emissivity", c, min=0.0, max=1.0, min_exclusive=True)
            area = get_float(t, "area_cm2", c, min=0.0, min_exclusive=True) * 1e-4
            coef = eps * STEFAN_BOLTZMANN * area
            out.append(("radiation", coef, 4.0 * coef * self.t_ref_k ** 3, 1.0, 0.0))
        if "natural_convection" in spec:
            c = ctx.child("natural_convection")
            t = get_table(spec, "natural_convection", ctx)
            check_known_keys(t, _NATURAL_KEYS, c)
            h = get_float(t, "h_ref_w_per_m2_k", c, min=0.0, min_exclusive=True, max=1e4)
            dt = get_float(t, "reference_dt_k", c, min=0.0, min_exclusive=True, max=1e3)
            area = get_float(t, "area_cm2", c, min=0.0, min_exclusive=True) * 1e-4
            ex = get_float(t, "exponent", c, 0.25, min=0.0, max=1.0)
            out.append(("convection", h * area, h * area, dt, ex))
        return out

    def _conductance(self, spec: Mapping[str, Any], ctx: Ctx) -> float:
        kinds = [k for k in ("conductance_w_per_k", "conduction", "convection", "radiation")
                 if k in spec]
        if not kinds and ("radiation_exact" in spec or "natural_convection" in spec):
            return 0.0
        if not kinds:
            raise ctx.error("conductance_w_per_k", "give at least one of conductance_w_per_k, "
                                                   "conduction, convection, radiation, "
                                                   "radiation_exact, natural_convection")
        total = 0.0
        if "conductance_w_per_k" in spec:
            total += get_float(spec, "conductance_w_per_k", ctx, min=0.0, min_exclusive=True)
        if "conduction" in spec:
            c = ctx.child("conduction")
            t = get_table(spec, "conduction", ctx)
            check_known_keys(t, _CONDUCTION_KEYS, c)
            if ("material" in t) == ("conductivity_w_per_m_k" in t):
                raise c.error("material", "give exactly one of material or "
                                          "conductivity_w_per_m_k")
            if "material" in t:
                mat = self._material(t, "material", c)
                if mat.conductivity_w_per_m_k is None:
                    raise c.error("material", f"material {mat.name!r} has no "
                                              f"conductivity_w_per_m_k")
                k = mat.conductivity_w_per_m_k
            else:
                k = get_float(t, "conductivity_w_per_m_k", c, min=0.0, min_exclusive=True)
            area = get_float(t, "area_cm2", c, min=0.0, min_exclusive=True) * 1e-4
            length = get_float(t, "length_mm", c, min=0.0, min_exclusive=True) * 1e-3
            total += k * area / length
        if "convection" in spec:
            c = ctx.child("convection")
            t = get_table(spec, "convection", ctx)
            check_known_keys(t, _CONVECTION_KEYS, c)
            h = get_float(t, "h_w_per_m2_k", c, min=0.0, min_exclusive=True)
            if "face" in t:
                face = get_str(t, "face", c)
                if self.face_factors is not None:
                    if face not in self.face_factors:
                        raise c.error("face", f"value {face!r} not allowed; one of "
                                              f"{', '.join(sorted(self.face_factors))} "
                                              f"([thermal.airflow] face_factors)")
                    h = h * self.face_factors[face]
            total += h * get_float(t, "area_cm2", c, min=0.0, min_exclusive=True) * 1e-4
        if "radiation" in spec:
            c = ctx.child("radiation")
            t = get_table(spec, "radiation", ctx)
            check_known_keys(t, _RADIATION_KEYS, c)
            eps = get_float(t, "emissivity", c, min=0.0, max=1.0, min_exclusive=True)
            area = get_float(t, "area_cm2", c, min=0.0, min_exclusive=True) * 1e-4
            total += 4.0 * eps * STEFAN_BOLTZMANN * self.t_ref_k ** 3 * area
        if not math.isfinite(total) or total <= 0:
            raise ctx.error("conductance_w_per_k", f"conductance {total!r} W/K not allowed")
        return total


def network_fields(table: Mapping[str, Any], ctx: Ctx) -> dict[str, Any]:
    """The keyword arguments of :class:`rlgsim.sim.thermal.network.ThermalNetwork` read from a
    ``[thermal]`` table; a mistake raises :class:`~rlgsim.ground.errors.UserInputError`
    naming file, key and value."""
    return _Builder(table, ctx).build()
