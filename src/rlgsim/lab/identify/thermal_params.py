"""The multipliers a thermal grey-box fit can adjust (:mod:`rlgsim.lab.identify.thermal_fit`,
whose docstring tables them): derived from a thermal preset's structure — its templates and
their instances, top-level nodes and links, probe lags — each with the edit that scales the
design values in the preset's own vocabulary, so that the fitted preset is an ordinary thermal
preset. Pure dict manipulation: the network itself is built by the simulator.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Callable

CHAMBER_AIR = "chamber_air"
_AREA_PARTS = ("conduction", "convection", "radiation", "radiation_exact", "natural_convection")

__all__ = ["CHAMBER_AIR", "ThermalParam", "thermal_parameters", "apply_multipliers"]


@dataclass(frozen=True)
class ThermalParam:
    """One multiplier: ``name``, ``description`` and ``edit(data, m, note)`` that scales the
    design values in a preset dict in place (``note(path, old, new)`` records each change)."""

    name: str
    description: str
    edit: Callable[[dict, float, Callable], None]


def _scale_link(link: dict, m: float, path: tuple, note) -> None:
    """Scale a link's conductance and every area of its parts by ``m``, noting each change."""
    if "conductance_w_per_k" in link:
        old = float(link["conductance_w_per_k"])
        link["conductance_w_per_k"] = old * m
        note(path + ("conductance_w_per_k",), old, old * m)
    for part in _AREA_PARTS:
        if isinstance(link.get(part), dict) and "area_cm2" in link[part]:
            old = float(link[part]["area_cm2"])
            link[part]["area_cm2"] = old * m
            note(path + (part, "area_cm2"), old, old * m)


def _instance_factor(inst: dict, table: str, key: str, m: float, path: tuple, note,
                     alt: str | None = None) -> None:
    """Multiply an instance's factor ``table[key]`` (or ``table[alt]`` when only that is set)
    by ``m``, noting the change."""
    facs = inst.setdefault(table, {})
    if alt is not None and alt in facs and key not in facs:
        key = alt
    old = float(facs.get(key, 1.0))
    facs[key] = old * m
    note(path + (table, key), old, old * m)


def _template_params(tname: str, tmpl: dict, insts: list[str]) -> list[ThermalParam]:
    """The multipliers of one template over all its instances ``insts``: capacity, heat
    sources (all, and each but the largest on its own), and its links grouped as internal, to
    the chamber air, and per port."""
    nodes = tmpl.get("nodes", {})
    ports = list(tmpl.get("ports", []))
    links = tmpl.get("links", [])
    out: list[ThermalParam] = []

    def inst_edit(kind: str, keys: list[tuple[str, str | None]], tname=tname, insts=insts):
        def edit(d: dict, m: float, note) -> None:
            for iname in insts:
                inst = d["thermal"]["instances"][iname]
                for key, alt in keys:
                    _instance_factor(inst, kind, key, m, ("thermal", "instances", iname),
                                     note, alt)
        return edit

    out.append(ThermalParam(f"{tname}.capacity",
                            f"heat capacity of every node of {tname}",
                            inst_edit("capacitance_factors", [(n, None) for n in nodes])))
    powered = [n for n, s in nodes.items() if float(s.get("power_w", 0.0)) > 0]
    if powered:
        out.append(ThermalParam(f"{tname}.power", f"heat sources of {tname} "
                                f"({', '.join(powered)})",
                                inst_edit("power_factors", [(n, None) for n in powered])))
        # each smaller source on its own (ballast against ballast: the arm-to-arm
        # asymmetry of a real block, paper 003 §2), the largest one held by the above
        main = max(powered, key=lambda n: float(nodes[n].get("power_w", 0.0)))
        for node in powered:
            if node != main:
                out.append(ThermalParam(f"{tname}.power.{node}",
                                        f"heat source {node} of {tname} on its own",
                                        inst_edit("power_factors", [(node, None)])))
    groups: dict[str, list[tuple[str, str]]] = {}
    for ln in links:
        a, b = ln["between"]
        if a in nodes and b in nodes:
            g = "internal_conductance"
        elif CHAMBER_AIR in (a, b):
            g = "chamber_air_conductance"
        else:
            port = a if a in ports else b
            g = f"{port}_conductance"
        groups.setdefault(g, []).append((f"{a}--{b}", f"{b}--{a}"))
    for g, keys in groups.items():
        what = {"internal_conductance": f"links between the nodes of {tname}",
                "chamber_air_conductance": f"links of {tname} to the chamber air"}.get(
                    g, f"links of {tname} to its port '{g[:-len('_conductance')]}'")
        out.append(ThermalParam(f"{tname}.{g}", what, inst_edit("link_factors", keys)))
    return out


def _node_params(th: dict) -> list[ThermalParam]:
    """Capacity and (when powered) heat source of each top-level node."""
    out: list[ThermalParam] = []
    for nname, spec in th.get("nodes", {}).items():
        def cap_edit(d: dict, m: float, note, nname=nname) -> None:
            s = d["thermal"]["nodes"][nname]
            for key in ("capacitance_j_per_k", "volume_cm3", "mass_kg"):
                if key in s:
                    old = float(s[key])
                    s[key] = old * m
                    note(("thermal", "nodes", nname, key), old, old * m)
        out.append(ThermalParam(f"{nname}.capacity", f"heat capacity of {nname}", cap_edit))
        if float(spec.get("power_w", 0.0)) > 0:
            def pow_edit(d: dict, m: float, note, nname=nname) -> None:
                s = d["thermal"]["nodes"][nname]
                old = float(s["power_w"])
                s["power_w"] = old * m
                note(("thermal", "nodes", nname, "power_w"), old, old * m)
            out.append(ThermalParam(f"{nname}.power", f"heat source of {nname}", pow_edit))
    return out


def _top_link_params(th: dict, boundaries: set[str]) -> list[ThermalParam]:
    """The top-level links grouped: to the chamber air, to each boundary, between nodes."""
    out: list[ThermalParam] = []
    tgroups: dict[str, list[int]] = {}
    for i, ln in enumerate(th.get("links", [])):
        a, b = ln["between"]
        if CHAMBER_AIR in (a, b):
            g = "chamber_air_conductance"
        elif a in boundaries or b in boundaries:
            g = f"{a if a in boundaries else b}_conductance"
        else:
            g = "internal_conductance"
        tgroups.setdefault(g, []).append(i)
    for g, idx in tgroups.items():
        def link_edit(d: dict, m: float, note, idx=idx) -> None:
            for i in idx:
                _scale_link(d["thermal"]["links"][i], m, ("thermal", "links", i), note)
        what = {"chamber_air_conductance": "top-level links to the chamber air",
                "internal_conductance": "top-level links between nodes"}.get(
                    g, f"links to the boundary {g[:-len('_conductance')]}")
        out.append(ThermalParam(g, what, link_edit))
    return out


def _probe_params(pr: dict, inst_of: dict[str, list[str]],
                  probe_names: tuple[str, ...] | None) -> list[ThermalParam]:
    """The lag ``tau_s`` of each probe group and point with a lag (only those among
    ``probe_names`` when given); ``inst_of`` {template: its instances}."""
    out: list[ThermalParam] = []
    default_tau = float(pr.get("defaults", {}).get("tau_s", 0.0))
    for gi, grp in enumerate(pr.get("groups", [])):
        tau = float(grp.get("tau_s", default_tau))
        members = [f"{inst}.{n}" for inst in grp.get("instances", inst_of.get(grp["template"], []))
                   for n in grp.get("nodes", [])]
        if tau <= 0 or (probe_names is not None and not set(members) & set(probe_names)):
            continue

        def lag_edit(d: dict, m: float, note, gi=gi, tau=tau) -> None:
            g = d["probes"]["groups"][gi]
            g["tau_s"] = tau * m
            note(("probes", "groups", gi, "tau_s"), tau, tau * m)
        out.append(ThermalParam(f"probe_lag.{grp['template']}[{gi}]",
                                f"lag of the probes {', '.join(grp.get('nodes', []))} on "
                                f"{grp['template']}", lag_edit))
    for pname, spec in pr.get("points", {}).items():
        tau = float(spec.get("tau_s", default_tau))
        if tau <= 0 or (probe_names is not None and pname not in probe_names):
            continue

        def pt_edit(d: dict, m: float, note, pname=pname, tau=tau) -> None:
            d["probes"]["points"][pname]["tau_s"] = tau * m
            note(("probes", "points", pname, "tau_s"), tau, tau * m)
        out.append(ThermalParam(f"probe_lag.{pname}", f"lag of the probe {pname}", pt_edit))
    return out


def thermal_parameters(data: dict, probe_names: tuple[str, ...] | None = None
                       ) -> list[ThermalParam]:
    """The candidate multipliers of a thermal preset dict (``[thermal]`` and ``[probes]``).
    With ``probe_names`` only the lags of probes in that list are candidates."""
    th = data["thermal"]
    templates = th.get("templates", {})
    instances = th.get("instances", {})
    boundaries = set(th.get("boundaries", {}))
    out: list[ThermalParam] = []
    used = []
    for inst in instances.values():
        if inst["template"] not in used:
            used.append(inst["template"])
    for tname in used:
        insts = [n for n, i in instances.items() if i["template"] == tname]
        out += _template_params(tname, templates[tname], insts)
    out += _node_params(th)
    out += _top_link_params(th, boundaries)
    inst_of = {t: [n for n, i in instances.items() if i["template"] == t] for t in used}
    out += _probe_params(data.get("probes", {}), inst_of, probe_names)
    return out


def apply_multipliers(data: dict, params: list[ThermalParam], mult: dict[str, float]
                      ) -> tuple[dict, dict[tuple, tuple[str, float, float]]]:
    """A deep copy of ``data`` with every multiplier applied; and the changes
    ``{path: (parameter names joined by '+', template value, new value)}``."""
    d = copy.deepcopy(data)
    changes: dict[tuple, tuple[str, float, float]] = {}
    for p in params:
        m = float(mult.get(p.name, 1.0))
        if m == 1.0:
            continue

        def note(path, old, new, name=p.name):
            if path in changes:              # a second multiplier on the same value
                names, first, _ = changes[path]
                changes[path] = (f"{names}+{name}", first, new)
            else:
                changes[path] = (name, old, new)
        p.edit(d, m, note)
    return d, changes
