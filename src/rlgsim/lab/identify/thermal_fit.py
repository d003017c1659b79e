"""Thermal grey-box identification: the template's network with a few physically meaningful
multipliers fitted so the twin's probes follow the recorded ones, given the recorded chamber
air and power state.

Parameters (derived from the template's structure, each a multiplier ``m = exp(x)`` of design
values, so a parameter is always positive and ``x`` is its relative change):

==========================================  ===================================================
``<template>.capacity``                     every node capacity of every instance of a template
                                            (the gyro block's glass, discharge, ballasts, board)
``<template>.power``                        its heat sources (discharge, ballasts, pre-amplifier)
``<template>.power.<node>``                 each source but the largest on its own (ballast
                                            against ballast: a real block's arm asymmetry)
``<template>.internal_conductance``         links between its own nodes (the glass web, bonds)
``<template>.<port>_conductance``           its links to a port (``air``: its faces to the
                                            cabinet; ``mount``: the dither mount and standoffs)
``<node>.capacity``, ``<node>.power``       a top-level node (housing, electronics)
``chamber_air_conductance``                 every link to the chamber air (the convection and
                                            radiation of the housing, a mounting flange)
``internal_conductance``                    the other top-level links
``probe_lag.<group or point>``              the lag ``tau_s`` of a probe group or point
==========================================  ===================================================

The network topology is the template's; the multipliers are written back into the preset in
its own vocabulary (instance ``capacitance_factors`` / ``power_factors`` / ``link_factors``,
scaled masses, volumes, areas and conductances of top-level nodes and links, probe ``tau_s``),
so the fitted preset is an ordinary thermal preset that :func:`ThermalNetwork.from_config`
reads — the same text the fit evaluated.

Model of a recording: :class:`~rlgsim.sim.thermal.integrator.ThermalIntegrator` with the
recorded chamber air as its input (``air_tau_s = 0``: the air *is* the input, piecewise linear
between its samples, the integrator's exact first-order hold) and the recorded power state
(held over each step), from the equilibrium at the first air sample; the probe lags of
:class:`~rlgsim.sim.thermal.thermometers.ProbeSet` without noise or quantisation. During the fit the
network is integrated on a grid of at most 15,000 steps, 7,500 for a network with a
controlled heater (every k-th recorded sample: the air is smooth, so its piecewise-linear
hold stays exact to the millikelvin; a heater's PI controller then acts every k seconds: for
trplg_001_cabinet through the 20 h programme of benchmarks/bench_identify.py, 10 s steps
against the 1 s integration differ by at most 0.8 mK in a probe reading, 0.04 mK RMS, its
fastest mode 7.7 s) and at most 30,000
probe residuals are used (every j-th grid point): the probes' lags and the network's time
constants make neighbouring seconds redundant. The final twin runs on the recorded grid. Residuals are
twin − recorded probe readings (missing readings carry zero weight). Fit:
:func:`rlgsim.estimators.identify.lsq_stats.fit` on the log-multipliers; identifiability:
:func:`rlgsim.estimators.identify.lsq_stats.screen` first at the template (Jacobian at ``x = 0``),
then at the solution, where a parameter that ran to its bound (a factor 10 either way) or whose
log-multiplier has a standard error above 1 (more than a factor e) is refused too; a refused
parameter keeps the template's value and the reason is
reported.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable

import numpy as np

from rlgsim.estimators.identify.lsq_stats import LsqFit, fit, screen
from rlgsim.estimators.identify.quantisation import quantised_covariance
from rlgsim.lab.identify.batch_twin import batchable, twin_readings_batch
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.integrator import ThermalIntegrator
from rlgsim.sim.thermal.thermometers import ProbeSet

__all__ = ["ThermalParam", "ThermalFit", "thermal_parameters", "apply_multipliers",
           "twin_response", "fit_thermal", "CHAMBER_AIR"]

CHAMBER_AIR = "chamber_air"
_AREA_PARTS = ("conduction", "convection", "radiation", "radiation_exact", "natural_convection")
#: log-multiplier bounds: a factor of 10 either way of the design
_BOUND = math.log(10.0)
#: most residuals used per fit (probes × time, decimated in time beyond this)
MAX_RESIDUALS = 30_000
#: most integration steps per evaluation during the fit (a coarser grid beyond this)
MAX_FIT_STEPS = 15_000
#: the same for a network integrated step by step (a controlled heater): its evaluations cost
#: several times a linear network's, and its fit runs on the coarser grid (module docstring)
MAX_FIT_STEPS_STEPWISE = 7_500
#: evaluate the finite-difference Jacobian of a heater network in one batch
#: (:mod:`rlgsim.lab.identify.batch_twin`); False: scipy's column by column
BATCH_JACOBIAN = True
#: the batch is cut into this many fixed parts (whatever the number of workers, so the result
#: does not depend on it); each part runs in its own process when workers allow
BATCH_PARTS = 2

#: the batch job of the fit in progress, inherited by forked workers
_JOB: dict = {}


def _batch_part(args: tuple[list[str], list[np.ndarray]]) -> list[np.ndarray]:
    names, xs = args
    return _JOB["fun"](names, xs)


def _workers() -> int:
    import os
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:                          # pragma: no cover (not Linux)
        n = os.cpu_count() or 1
    return max(1, min(BATCH_PARTS, n))


@dataclass(frozen=True)
class ThermalParam:
    """One multiplier: ``name``, ``description`` and ``edit(data, m, note)`` that scales the
    design values in a preset dict in place (``note(path, old, new)`` records each change)."""

    name: str
    description: str
    edit: Callable[[dict, float, Callable], None]


def _link_key(link: dict) -> str:
    a, b = link["between"]
    return f"{a}--{b}"


def _scale_link(link: dict, m: float, path: tuple, note) -> None:
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
    facs = inst.setdefault(table, {})
    if alt is not None and alt in facs and key not in facs:
        key = alt
    old = float(facs.get(key, 1.0))
    facs[key] = old * m
    note(path + (table, key), old, old * m)


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
        tmpl = templates[tname]
        nodes = tmpl.get("nodes", {})
        ports = list(tmpl.get("ports", []))
        links = tmpl.get("links", [])
        insts = [n for n, i in instances.items() if i["template"] == tname]

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
    pr = data.get("probes", {})
    default_tau = float(pr.get("defaults", {}).get("tau_s", 0.0))
    inst_of = {t: [n for n, i in instances.items() if i["template"] == t] for t in used}
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


def build(data: dict, source: str = "twin") -> tuple[ThermalNetwork, ProbeSet]:
    """Network and probes of a preset dict."""
    ctx = Ctx(source, "")
    net = ThermalNetwork.from_config(data["thermal"], ctx.child("thermal"))
    probes = ProbeSet.from_config(data["probes"], net, ctx.child("probes"))
    return net, probes


def twin_response(network: ThermalNetwork, probes: ProbeSet, air_c: np.ndarray,
                  power: np.ndarray, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Node temperatures (m, n) and noise-free probe readings (m, p) of ``network`` driven by
    the chamber air samples ``air_c`` (m,) at the ends of the steps and the power (m,) held
    over each step, from the equilibrium at ``air_c[0]``."""
    integ = ThermalIntegrator(network, step_s, 0.0)
    st = integ.initial_state(float(air_c[0]), bool(power[0] > 0.5))
    setpoint = np.concatenate(([air_c[0]], air_c))
    states, _ = integ.propagate(st, setpoint, power)
    nodes = np.asarray(states[:, 1:])
    quiet = replace(probes, noise_sigma_c=np.zeros(probes.n_probes),
                    resolution_c=np.zeros(probes.n_probes))
    ps = quiet.initial_state(np.asarray(st)[1:])
    reading, _ = quiet.read(ps, nodes, step_s, np.random.default_rng(0))
    return nodes, reading


@dataclass
class ThermalFit:
    """Result: ``fitted`` preset dict and its ``changes``; the fitted parameters (``fit``,
    log-multipliers) and ``multipliers`` with relative standard errors; ``refused``
    {parameter: reason}; per-probe RMS of the twin at the template and after the fit;
    the twin's ``nodes_c`` and ``network``/``probes``."""

    params: list[ThermalParam]
    fit: LsqFit | None
    multipliers: dict[str, float]
    rel_se: dict[str, float]
    refused: dict[str, str]
    probe_names: tuple[str, ...]
    rms_template_c: dict[str, float]
    rms_fitted_c: dict[str, float]
    fitted: dict
    changes: dict
    network: ThermalNetwork
    probes: ProbeSet
    nodes_c: np.ndarray
    probe_fit_c: np.ndarray
    notes: list[str] = field(default_factory=list)
    #: standard errors of the log-multipliers from the probes' error model alone
    #: (:func:`rlgsim.estimators.identify.quantisation.quantised_covariance`); ``rel_se`` is
    #: the larger of these and the batch-means sandwich (``fit.se``)
    se_quantised: dict = field(default_factory=dict)


#: largest standard error of a log-multiplier still reported as identified (a factor e)
MAX_LOG_SE = 1.0


def _undetermined(res: LsqFit, names: list[str]) -> tuple[int, str] | None:
    """A parameter that ended on its bound or whose standard error exceeds a factor e."""
    at_bound = np.flatnonzero(np.abs(np.abs(res.x) - _BOUND) < 1e-6)
    if at_bound.size:
        i = int(at_bound[np.argmax(res.se[at_bound])])
        return i, (f"the fit ran to its bound (×{math.exp(res.x[i]):.3g} of the template): the "
                   f"recording does not determine it")
    i = int(np.argmax(res.se))
    if res.se[i] > MAX_LOG_SE:
        return i, (f"standard error of its logarithm {res.se[i]:.2f} > {MAX_LOG_SE:g} (more than "
                   f"a factor e): the recording does not determine it")
    return None


SCALE_REASON = ("multiplying every capacity, conductance and heat source by one factor leaves "
                "every temperature unchanged (divide the heat equation by it): the overall scale "
                "is invisible in temperatures; the capacities (masses and materials of the "
                "design) are the best known of the three, so this one keeps the template's "
                "value and the other multipliers are relative to it")


def _overall_scale(names: list[str], residual: Callable[[list[str], np.ndarray], np.ndarray]
                   ) -> int | None:
    """Index of the capacity parameter to keep at the template when the recording cannot see
    the network's overall scale, else ``None``.

    Tested exactly rather than through the Jacobian's conditioning (whose near-degeneracies
    would pick an arbitrary member): every capacity, conductance and heat-source multiplier
    (not the probe lags nor the single-source refinements, which are relative to their
    template's block-wide source) × 1.01 must change no probe reading by more than 10⁻⁷ °C. It holds
    for a network of capacities, linear links, constant sources and fixed-temperature
    boundaries; a controlled heater or a nonlinear link breaks it, and then nothing is pinned
    here (the screen still refuses what the recording cannot separate). The capacity pinned
    is the first one (the gyro block's, for a template with one)."""
    # not the probe lags, nor the single-source refinements (relative to the block-wide one)
    scale = [i for i, n in enumerate(names)
             if not n.startswith("probe_lag.") and ".power." not in n]
    caps = [i for i in scale if n_is_capacity(names[i])]
    if not caps:
        return None
    x = np.zeros(len(names))
    r0 = residual(names, x)
    x[scale] = math.log(1.01)
    if np.max(np.abs(residual(names, x) - r0)) > 1e-7:
        return None
    return caps[0]


def n_is_capacity(name: str) -> bool:
    return name.endswith(".capacity")


def fit_thermal(template: dict, air_c: np.ndarray, power: np.ndarray, step_s: float,
                probe_names: tuple[str, ...], probes_c: np.ndarray, *, source: str = "",
                max_corr: float = 0.99, workers: int | None = None) -> ThermalFit:
    """Fit the multipliers of ``template`` (a thermal preset dict) to the recorded probes
    ``probes_c`` (m, p) named ``probe_names`` (module docstring). ``workers``: processes for
    the batched Jacobian of a heater network (default: up to 2 of the available cores; the
    result does not depend on it)."""
    if workers is None:
        workers = _workers()
    try:
        return _fit_thermal(template, air_c, power, step_s, probe_names, probes_c,
                            source=source, max_corr=max_corr, workers=workers)
    finally:
        if _JOB.get("pool") is not None:
            _JOB["pool"].terminate()
            _JOB["pool"].join()
        _JOB.clear()


class _Problem:
    """The fit's residuals and Jacobians: the template's twin with multipliers on the fit's
    coarser grid (and on the recorded grid for the result), one residual series per probe,
    forward-difference Jacobians batched over processes for a heater network."""

    def __init__(self, template: dict, air_c: np.ndarray, power: np.ndarray, step_s: float,
                 probe_names: tuple[str, ...], probes_c: np.ndarray, *, source: str,
                 workers: int) -> None:
        net0, pr0 = build(template, "thermal template")
        unknown = [n for n in probe_names if n not in pr0.names]
        if unknown:
            raise UserInputError(f"{source}: probe {unknown[0]!r} of the recording is not a probe "
                                 f"of the thermal template (its probes: {', '.join(pr0.names)}); "
                                 f"name the probes as the template does or give another "
                                 f"--thermal-template")
        cols = np.array([pr0.names.index(n) for n in probe_names])
        m_full = air_c.size
        # the fit integrates on a coarser grid (every `coarse` recorded steps): the air is
        # smooth and the first-order hold stays exact to the millikelvin; the final twin is on
        # the full grid
        batched = BATCH_JACOBIAN and batchable(net0)
        most = MAX_FIT_STEPS_STEPWISE if batchable(net0) else MAX_FIT_STEPS
        coarse = max(1, int(math.ceil(m_full / most)))
        sel = np.arange(coarse - 1, m_full, coarse)
        air_f, power_f, step_f = air_c[sel], power[sel], step_s * coarse
        m = sel.size
        stride = max(1, int(math.ceil(m * len(probe_names) / MAX_RESIDUALS)))
        rows = np.arange(stride - 1, m, stride)
        obs = probes_c[sel][rows]
        mask = np.isfinite(obs)
        obs0 = np.where(mask, obs, 0.0)
        params = thermal_parameters(template, probe_names)

        self.template, self.air_c, self.power, self.step_s = template, air_c, power, step_s
        self.probe_names, self.probes_c, self.pr0, self.cols = probe_names, probes_c, pr0, cols
        self.air_f, self.power_f, self.step_f, self.batched = air_f, power_f, step_f, batched
        self.rows, self.obs, self.mask, self.obs0 = rows, obs, mask, obs0
        self.params = params
        pool = None
        if batched and workers > 1:
            import multiprocessing
            _JOB["fun"] = self.residuals_part
            try:
                pool = multiprocessing.get_context("fork").Pool(workers)
                _JOB["pool"] = pool                      # closed by fit_thermal
            except (ValueError, OSError, AssertionError):   # no fork, or a daemon: one process
                pool = None

        self.pool = pool

    def model(self, mult: dict[str, float], full: bool = False):
        d, _ = apply_multipliers(self.template, self.params, mult)
        net, pr = build(d)
        if full:
            nodes, read = twin_response(net, pr, self.air_c, self.power, self.step_s)
        else:
            nodes, read = twin_response(net, pr, self.air_f, self.power_f, self.step_f)
        return nodes, read[:, self.cols], net, pr, d

    def residual_for(self, names: list[str]):
        def fun(x: np.ndarray) -> np.ndarray:
            _, read, *_ = self.model(dict(zip(names, np.exp(x))))
            r = np.where(self.mask, read[self.rows] - self.obs0, 0.0)
            return r.T.reshape(-1)               # probe-major: one series per probe
        return fun

    def residuals_part(self, names: list[str], xs: list[np.ndarray]) -> list[np.ndarray]:
        """Residual vectors at several points, integrated together (a heater network)."""
        models = []
        for x in xs:
            d, _ = apply_multipliers(self.template, self.params, dict(zip(names, np.exp(x))))
            models.append(build(d))
        out = []
        for read in twin_readings_batch(models, self.air_f, self.power_f, self.step_f):
            r = np.where(self.mask, read[:, self.cols][self.rows] - self.obs0, 0.0)
            out.append(r.T.reshape(-1))
        return out

    def residuals_batch(self, names: list[str], xs: list[np.ndarray]) -> list[np.ndarray]:
        """The points in BATCH_PARTS fixed parts, in parallel when there is a pool."""
        k = int(math.ceil(len(xs) / BATCH_PARTS))
        parts = [(names, xs[i:i + k]) for i in range(0, len(xs), k)]
        if self.pool is not None:
            done = self.pool.map(_batch_part, parts, chunksize=1)
        else:
            done = [self.residuals_part(*a) for a in parts]
        return [r for part in done for r in part]

    def fd_jac(self, names: list[str], x: np.ndarray, rel: float, bounded: bool) -> np.ndarray:
        """Forward differences with scipy's 2-point step (``rel·max(1, |x|)``, sign of x,
        reversed at an upper bound), the base point and every column in one batch."""
        x = np.asarray(x, dtype=float)
        h = rel * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0, np.abs(x))
        if bounded:
            h = np.where((x + h > _BOUND) | (x + h < -_BOUND), -h, h)
        pts = [x]
        dx = []
        for j in range(x.size):
            xp = x.copy()
            xp[j] += h[j]
            dx.append(xp[j] - x[j])
            pts.append(xp)
        res = self.residuals_batch(names, pts)
        J = np.empty((res[0].size, x.size))
        for j in range(x.size):
            J[:, j] = (res[j + 1] - res[0]) / dx[j]
        return J

    def jac_at(self, names: list[str], x: np.ndarray, h: float = 1e-4) -> np.ndarray:
        if self.batched:
            J = np.empty((self.obs.size, len(names)))
            pts = [x] + [x + h * np.eye(len(names))[j] for j in range(len(names))]
            res = self.residuals_batch(names, pts)
            for j in range(len(names)):
                J[:, j] = (res[j + 1] - res[0]) / h
            return J
        fun = self.residual_for(names)
        r0 = fun(x)
        J = np.empty((r0.size, len(names)))
        for j in range(len(names)):
            xp = x.copy()
            xp[j] += h
            J[:, j] = (fun(xp) - r0) / h
        return J


def _optional(names: list[str]) -> list[bool]:
    """Which parameters the screen may drop first (the heat sources' powers)."""
    return [n.count(".power.") > 0 for n in names]


def _fit_thermal(template: dict, air_c: np.ndarray, power: np.ndarray, step_s: float,
                 probe_names: tuple[str, ...], probes_c: np.ndarray, *, source: str,
                 max_corr: float, workers: int) -> ThermalFit:
    pb = _Problem(template, air_c, power, step_s, probe_names, probes_c, source=source,
                  workers=workers)
    free, refused = _screen_at_template(pb, max_corr)
    res = _fit_screened(pb, free, refused, max_corr)
    return _result(pb, res, free, refused)


def _screen_at_template(pb: _Problem, max_corr: float) -> tuple[list[str], dict[str, str]]:
    """The free parameters after the overall-scale pin and the screen at the template."""
    free = [p.name for p in pb.params]
    refused: dict[str, str] = {}
    pin = _overall_scale(free, lambda names, x: pb.residual_for(names)(x))
    if pin is not None:
        refused[free[pin]] = SCALE_REASON
        free.pop(pin)
    J = pb.jac_at(free, np.zeros(len(free)))
    while free:
        s = screen(J, free, max_corr=max_corr, optional=_optional(free))
        if s is None:
            break
        i, why = s
        refused[free[i]] = why + " (at the template)"
        free.pop(i)
        J = np.delete(J, i, axis=1)
    return free, refused


def _fit_screened(pb: _Problem, free: list[str], refused: dict[str, str], max_corr: float):
    """Fit ``free`` (refusing in place, one refusal per refit, until the screen passes at the
    fitted values); the last fit, or None when nothing is left free."""
    res = None
    x = np.zeros(len(free))
    # one refusal per refit, until the screen passes: every refusal is followed by a fit on
    # the remaining parameters, so the estimates are always those of the reported set (the
    # loop used to stop after 8 fits and could pair the last fit's values with a set that
    # had lost one more name)
    while True:
        if not free:
            res = None
            break
        names = list(free)
        res = fit(pb.residual_for(free), x, free, bounds=(-_BOUND, _BOUND),
                  segments=len(pb.probe_names), diff_step=1e-6, batches=8,
                  jac=(lambda x, names=names: pb.fd_jac(names, x, 1e-6, True)) if pb.batched
                  else None)
        s = (screen(res.jac, free, max_corr=max_corr, optional=_optional(free))
             or _undetermined(res, free))
        if s is None:
            break
        i, why = s
        refused[free[i]] = why + " (at the fitted values)"
        x = np.delete(res.x, i)
        free.pop(i)
    return res


def _result(pb: _Problem, res, free: list[str], refused: dict[str, str]) -> ThermalFit:
    """The fitted twin on the recorded grid, its standard errors and the probes' RMS."""
    template, params, probe_names, probes_c = pb.template, pb.params, pb.probe_names, pb.probes_c
    assert res is None or list(res.names) == free
    mult = dict(zip(free, np.exp(res.x))) if res is not None else {}
    rel_se = dict(zip(free, res.se)) if res is not None else {}
    se_q = {}
    if res is not None:
        # the probes' own error model (resolution, noise) carried through the Jacobian; the
        # reported standard error is the larger of it and the batch means (which also see
        # what the error model does not: a template family that cannot follow the unit)
        _, read_fit, *_ = pb.model(mult)
        cq = quantised_covariance(res.jac, read_fit[pb.rows], pb.mask,
                                  pb.pr0.noise_sigma_c[pb.cols], pb.pr0.resolution_c[pb.cols])
        se_q = dict(zip(free, np.sqrt(np.clip(np.diag(cq), 0, None))))
        rel_se = {k: max(v, se_q[k]) for k, v in rel_se.items()}
    nodes, fitted_read, net, pr, fitted = pb.model(mult, full=True)
    _, template_read, *_ = pb.model({}, full=True)
    fitted, changes = apply_multipliers(template, params, mult)

    def rms(pred):
        out = {}
        for j, n in enumerate(probe_names):
            d = pred[:, j] - probes_c[:, j]
            d = d[np.isfinite(d)]
            out[n] = float(np.sqrt(np.mean(d ** 2))) if d.size else float("nan")
        return out
    return ThermalFit(params=params, fit=res, multipliers=mult, rel_se=rel_se, refused=refused,
                      probe_names=tuple(probe_names), rms_template_c=rms(template_read),
                      rms_fitted_c=rms(fitted_read), fitted=fitted, changes=changes,
                      network=net, probes=pr, nodes_c=nodes, probe_fit_c=fitted_read,
                      se_quantised=se_q)
