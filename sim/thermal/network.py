"""The lumped thermal network of an RLG (or RLG-IMU): nodes, conductances, heat sources.

Model (docs/thermal.md; docs/design.md "Thermal network"): ``n`` isothermal nodes with heat
capacities ``C_i`` [J/K], node-to-node conductances ``G_ij = G_ji`` [W/K], conductances to the
chamber air ``g_i`` [W/K] and heat sources ``P_i`` [W] switched by the power state
``u(t) ∈ {0, 1}``::

    C_i dT_i/dt = Σ_j G_ij (T_j − T_i) + g_i (T_air − T_i) + u(t) P_i

or, with the weighted Laplacian ``L = diag(Σ_j G_ij) − G`` and the stiffness ``K = L + diag(g)``
(symmetric positive definite when every part of the network reaches the chamber air)::

    C dT/dt = −K T + g T_air + u P.

Numbers come from the thermal presets (``scenarios/thermal/*.toml``), never from this code: a
node's capacity is given directly or as material × volume/mass (ρ·c·V, paper 003 Table 1 for
Zerodur: 2530 kg/m³, 800 J/(kg·K), 1.46 W/(m·K)); a link's conductance directly or as
conduction ``k·A/ℓ``, convection ``h·A`` and linearised radiation ``4·ε·σ·T_ref³·A`` (summed).

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

Model vs realisation: the preset describes the *design* (nominal values + tolerances);
:meth:`ThermalNetwork.realise` draws one *unit* (each capacitance, conductance and power
multiplied by an independent log-normal factor ``exp(σ_rel·N(0,1))``, median 1), which is what
a Monte Carlo run simulates.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np
import scipy.linalg

from rlgsim.sim.config import (Ctx, check_known_keys, get_float, get_list, get_section, get_str,
                               get_table)
from rlgsim.ground.errors import UserInputError

#: Stefan–Boltzmann constant [W/(m²·K⁴)] (CODATA 2018, exact).
STEFAN_BOLTZMANN = 5.670374419e-8
#: 0 °C in kelvin.
ZERO_C_K = 273.15
#: The reserved name of the chamber air node (integrator state column 0).
CHAMBER_AIR = "chamber_air"

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


@dataclass(frozen=True)
class Heater:
    """A controlled heater (state-dependent heat source): a digital PI controller, sampled on
    the thermal grid, drives ``power ∈ [0, max_power_w]`` into ``node`` to hold the
    temperature of ``sensor`` at ``setpoint_c + track_gain·(T_track − track_reference_c)``
    (``track_node`` optional: a set point that follows another node, as the
    frequency-stabilisation heater of paper 001 §2.1 follows the cavity). Works only while the
    device is powered. Equations: docs/thermal.md §1.2b."""

    name: str
    node: int
    sensor: int
    setpoint_c: float
    max_power_w: float
    kp_w_per_k: float
    ti_s: float
    track_node: int = -1
    track_gain: float = 0.0
    track_reference_c: float = 0.0


@dataclass(frozen=True)
class NonlinearLink:
    """The part of a link's heat flow that the linear conductance does not carry.

    ``kind = "radiation"``: ``q = c·(T_a⁴ − T_b⁴)`` [K in kelvin], ``c = ε σ A``, of which
    ``4 c T_ref³ (T_a − T_b)`` is in the network's conductances; ``kind = "convection"``
    (natural convection): ``q = h_ref A (|ΔT|/ΔT_ref)^n ΔT``, of which ``h_ref A ΔT`` is in the
    conductances. ``a`` is a node index; ``b`` a node index, ``-1`` the chamber air or
    ``-2 − j`` boundary ``j``. docs/thermal.md §1.2c."""

    a: int
    b: int
    kind: str
    coefficient: float        # c = εσA [W/K⁴] or h_ref·A [W/K]
    linear_w_per_k: float     # the part already in the conductances [W/K]
    reference_dt_k: float = 1.0
    exponent: float = 0.25


@dataclass(frozen=True)
class Boundary:
    """A second boundary of the network (beside the chamber air) with a prescribed
    temperature ``temperature_c + amplitude_c·sin(2π t/period + phase)`` [°C] — e.g. the
    laboratory seen through the turntable shaft, with its air-conditioning or daily cycle.
    Sampled on the thermal grid and linear in between (the integrator's first-order hold)."""

    name: str
    temperature_c: float
    amplitude_c: float = 0.0
    period_s: float = 86400.0
    phase_rad: float = 0.0

    def __call__(self, t_s: Any) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        if self.amplitude_c == 0.0:
            return np.full(t.shape, self.temperature_c)
        return self.temperature_c + self.amplitude_c * np.sin(
            2.0 * np.pi * t / self.period_s + self.phase_rad)


@dataclass(frozen=True)
class Tolerance:
    """Relative 1-σ unit-to-unit spreads (log-normal factors ``exp(σ·N(0,1))``)."""

    capacitance_rel: float = 0.0
    conductance_rel: float = 0.0
    ambient_conductance_rel: float = 0.0
    power_rel: float = 0.0
    heater_setpoint_k: float = 0.0      # 1σ offset of a heater's set point [K] (sensor, trim)


@dataclass(frozen=True)
class Material:
    """Bulk thermal properties: density [kg/m³], specific heat [J/(kg·K)], conductivity [W/(m·K)]."""

    name: str
    density_kg_per_m3: float
    specific_heat_j_per_kg_k: float
    conductivity_w_per_m_k: float | None = None


# --------------------------------------------------------------------------- the network


@dataclass(frozen=True, eq=False)
class ThermalNetwork:
    """A linear lumped thermal network (see the module docstring for the equations).

    Attributes (SI): ``capacitance_j_per_k`` (n,), ``conductance_w_per_k`` (n, n) symmetric with
    zero diagonal, ``ambient_conductance_w_per_k`` (n,) to the chamber air, ``power_w`` (n,)
    heat injected when powered. ``templates`` maps a template name to its local node names and
    ``instances`` an instance name to its template (so probes can be placed "on every gyro
    block").
    """

    node_names: tuple[str, ...]
    capacitance_j_per_k: np.ndarray
    conductance_w_per_k: np.ndarray
    ambient_conductance_w_per_k: np.ndarray
    power_w: np.ndarray
    tolerance: Tolerance = field(default_factory=Tolerance)
    templates: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    instances: Mapping[str, str] = field(default_factory=dict)
    node_descriptions: tuple[str, ...] = ()
    description: str = ""
    #: further boundaries (prescribed temperatures) and the conductances (nb, n) to them
    boundaries: tuple[Boundary, ...] = ()
    boundary_conductance_w_per_k: Any = None
    #: controlled heaters (state-dependent sources, nonlinear through their limits)
    heaters: tuple[Heater, ...] = ()
    #: nonlinear parts of links (exact radiation, natural convection h(ΔT))
    nonlinear_links: tuple[NonlinearLink, ...] = ()

    def __post_init__(self) -> None:
        names = tuple(self.node_names)
        n = len(names)
        if n == 0:
            raise ValueError("a thermal network needs at least one node")
        if len(set(names)) != n:
            raise ValueError("node names must be unique")
        C = np.array(self.capacitance_j_per_k, dtype=float).reshape(-1)
        G = np.array(self.conductance_w_per_k, dtype=float)
        g = np.array(self.ambient_conductance_w_per_k, dtype=float).reshape(-1)
        P = np.array(self.power_w, dtype=float).reshape(-1)
        if C.shape != (n,) or g.shape != (n,) or P.shape != (n,) or G.shape != (n, n):
            raise ValueError("capacitance, ambient conductance and power must be (n,), "
                             "conductance (n, n)")
        for arr in (C, G, g, P):
            if not np.all(np.isfinite(arr)):
                raise ValueError("network parameters must be finite")
        if np.any(C <= 0):
            raise ValueError("capacitances must be > 0")
        if np.any(G < 0) or np.any(g < 0):
            raise ValueError("conductances must be >= 0")
        if not np.array_equal(G, G.T) or np.any(np.diag(G) != 0):
            raise ValueError("conductance matrix must be symmetric with a zero diagonal")
        for arr in (C, G, g, P):
            arr.setflags(write=False)
        object.__setattr__(self, "node_names", names)
        object.__setattr__(self, "capacitance_j_per_k", C)
        object.__setattr__(self, "conductance_w_per_k", G)
        object.__setattr__(self, "ambient_conductance_w_per_k", g)
        object.__setattr__(self, "power_w", P)
        if not self.node_descriptions:
            object.__setattr__(self, "node_descriptions", ("",) * n)
        nb = len(self.boundaries)
        Gb = (np.zeros((0, n)) if self.boundary_conductance_w_per_k is None
              else np.array(self.boundary_conductance_w_per_k, dtype=float).reshape(-1, n))
        if Gb.shape != (nb, n) or not np.all(np.isfinite(Gb)) or np.any(Gb < 0):
            raise ValueError("boundary conductances must be finite, >= 0, one row per "
                             "boundary")
        names_b = [b.name for b in self.boundaries]
        if len(set(names_b)) != nb or set(names_b) & set(names):
            raise ValueError("boundary names must be unique and differ from node names")
        Gb.setflags(write=False)
        object.__setattr__(self, "heaters", tuple(self.heaters))
        object.__setattr__(self, "nonlinear_links", tuple(self.nonlinear_links))
        for h in self.heaters:
            if not (0 <= h.node < n and 0 <= h.sensor < n and -1 <= h.track_node < n):
                raise ValueError(f"heater {h.name!r}: node index out of range")
        object.__setattr__(self, "boundaries", tuple(self.boundaries))
        object.__setattr__(self, "boundary_conductance_w_per_k", Gb)
        _check_grounded(names, G, g + Gb.sum(axis=0) if nb else g)

    # ----------------------------------------------------------------- basics

    @property
    def n_nodes(self) -> int:
        return len(self.node_names)

    def index(self, name: str) -> int:
        """Position of node ``name`` (``KeyError`` with a suggestion if unknown)."""
        try:
            return self.node_names.index(name)
        except ValueError:
            same_case = [n for n in self.node_names if n.lower() == str(name).lower()]
            close = same_case or difflib.get_close_matches(name, self.node_names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise KeyError(f"no node {name!r}{hint}") from None

    def template_nodes(self, instance: str) -> tuple[str, ...]:
        """Full node names of one template instance (``gx`` → ``gx.A``, ...)."""
        local = self.templates[self.instances[instance]]
        return tuple(f"{instance}.{node}" for node in local)

    def stiffness_w_per_k(self) -> np.ndarray:
        """``K = diag(Σ_j G_ij) − G + diag(g) + diag(Σ_b G_b)`` [W/K] (symmetric positive
        definite)."""
        G = self.conductance_w_per_k
        if self.boundaries:
            return np.diag(G.sum(axis=1) + self.ambient_conductance_w_per_k
                           + self.boundary_conductance_w_per_k.sum(axis=0)) - G
        return np.diag(G.sum(axis=1) + self.ambient_conductance_w_per_k) - G

    @property
    def boundary_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.boundaries)

    def boundary_temperatures_c(self, t_s: Any) -> np.ndarray:
        """Temperatures of the further boundaries at times ``t_s`` [s]: (…, nb) [°C]."""
        t = np.asarray(t_s, dtype=float)
        if not self.boundaries:
            return np.zeros(t.shape + (0,))
        return np.stack([b(t) for b in self.boundaries], axis=-1)

    def heat_to_boundaries_w(self, T: Any, boundary_c: Any) -> np.ndarray:
        """Heat flowing from the nodes into the further boundaries [W], summed (…)."""
        T = np.asarray(T, dtype=float)
        if not self.boundaries:
            return np.zeros(T.shape[:-1])
        Tb = np.asarray(boundary_c, dtype=float)
        Gb = self.boundary_conductance_w_per_k
        return np.sum(T * Gb.sum(axis=0), axis=-1) - np.sum(Tb * (Gb.sum(axis=1)), axis=-1)

    # ----------------------------------------------------------------- physics

    def derivative(self, T: Any, ambient_c: Any, powered: Any, boundary_c: Any = None,
                   heater_w: Any = None) -> np.ndarray:
        """dT/dt [K/s] for node temperatures ``T`` (…, n) [°C], chamber air ``ambient_c``
        (scalar or (…,)) [°C], power state ``powered`` (bool/0..1, scalar or (…,)) and the
        further boundaries' temperatures ``boundary_c`` (…, nb) [°C] (default: at t = 0) and
        the heaters' powers ``heater_w`` (…, H) [W] (default: none)."""
        T = np.asarray(T, dtype=float)
        Ta = np.asarray(ambient_c, dtype=float)[..., None]
        u = np.asarray(powered, dtype=float)[..., None]
        G = self.conductance_w_per_k
        flow = T @ G - T * G.sum(axis=1)            # Σ_j G_ij (T_j − T_i), G symmetric
        flow = flow + self.ambient_conductance_w_per_k * (Ta - T) + u * self.power_w
        if self.boundaries:
            Tb = (self.boundary_temperatures_c(0.0) if boundary_c is None
                  else np.asarray(boundary_c, dtype=float))
            Gb = self.boundary_conductance_w_per_k
            flow = flow + Tb @ Gb - T * Gb.sum(axis=0)
        if heater_w is not None and self.heaters:
            Ph = np.asarray(heater_w, dtype=float)
            for i, h in enumerate(self.heaters):
                flow[..., h.node] += Ph[..., i]
        if self.nonlinear_links:
            flow = flow + self.nonlinear_heat_w(T, ambient_c, boundary_c)
        return flow / self.capacitance_j_per_k

    def steady_state(self, ambient_c: float, powered: bool | float,
                     boundary_c: Any = None) -> np.ndarray:
        """Node temperatures [°C] at equilibrium with constant chamber air ``ambient_c`` [°C]
        (and the further boundaries at ``boundary_c``, default their value at t = 0): the
        solution of ``K T = g·T_air + Σ_b G_b T_b + u·P``."""
        rhs = self._steady_rhs(ambient_c, powered, boundary_c)
        if self.nonlinear_links:
            return self._steady_nonlinear(rhs, ambient_c, powered, boundary_c)[0]
        if self.heaters and float(powered) > 0:
            return self._steady_with_heaters(rhs)[0]
        return scipy.linalg.solve(self.stiffness_w_per_k(), rhs, assume_a="pos")

    def _steady_rhs(self, ambient_c: float, powered: bool | float,
                    boundary_c: Any) -> np.ndarray:
        """Right-hand side [W] of the steady state: ``g·T_air + Σ_b G_b T_b + u·P`` (the
        boundaries at ``boundary_c``, default their value at t = 0)."""
        rhs = self.ambient_conductance_w_per_k * float(ambient_c) + float(powered) * self.power_w
        if self.boundaries:
            Tb = (self.boundary_temperatures_c(0.0) if boundary_c is None
                  else np.asarray(boundary_c, dtype=float).reshape(-1))
            rhs = rhs + Tb @ self.boundary_conductance_w_per_k
        return rhs

    def _steady_nonlinear(self, rhs: np.ndarray, ambient_c: float, powered: bool | float,
                          boundary_c: Any) -> tuple[np.ndarray, np.ndarray]:
        """Equilibrium with the nonlinear link parts: the fixed point of
        ``K T = rhs + N(T)`` (N is the small deviation from the linearised links, so the
        iteration contracts), heaters included."""
        heat = self.heaters and float(powered) > 0
        T = None
        powers = np.zeros(len(self.heaters))
        extra = np.zeros(self.n_nodes)
        for _ in range(200):
            if heat:
                Tn, powers = self._steady_with_heaters(rhs + extra)
            else:
                Tn = scipy.linalg.solve(self.stiffness_w_per_k(), rhs + extra, assume_a="pos")
            if T is not None and np.max(np.abs(Tn - T)) <= 1e-12 * max(1.0, np.max(np.abs(Tn))):
                return Tn, powers
            T = Tn
            extra = self.nonlinear_heat_w(T, float(ambient_c), boundary_c)
        raise ValueError("the steady state with nonlinear links did not converge")

    def steady_heater_power_w(self, ambient_c: float, powered: bool | float,
                              boundary_c: Any = None) -> np.ndarray:
        """The heaters' powers [W] (H,) in the steady state of :meth:`steady_state`."""
        if not self.heaters or float(powered) <= 0:
            return np.zeros(len(self.heaters))
        rhs = self._steady_rhs(ambient_c, powered, boundary_c)
        if self.nonlinear_links:
            return self._steady_nonlinear(rhs, ambient_c, powered, boundary_c)[1]
        return self._steady_with_heaters(rhs)[1]

    def nonlinear_heat_w(self, T: Any, ambient_c: Any, boundary_c: Any = None) -> np.ndarray:
        """Heat [W] (…, n) into each node from the nonlinear parts of its links (the true flow
        minus the linear part already in the conductances); zeros without such links."""
        T = np.asarray(T, dtype=float)
        out = np.zeros(T.shape)
        if not self.nonlinear_links:
            return out
        Ta = np.asarray(ambient_c, dtype=float)
        Tb = (None if not self.boundaries else
              (self.boundary_temperatures_c(0.0) if boundary_c is None
               else np.asarray(boundary_c, dtype=float)))
        for ln in self.nonlinear_links:
            ta = T[..., ln.a]
            if ln.b >= 0:
                tb = T[..., ln.b]
            elif ln.b == -1:
                tb = Ta
            else:
                tb = Tb[..., -2 - ln.b]
            q = nonlinear_flow_w(ln, ta, tb)               # from a to b
            out[..., ln.a] -= q
            if ln.b >= 0:
                out[..., ln.b] += q
        return out

    def heater_setpoints_c(self, T: Any) -> np.ndarray:
        """Set points (…, H) [°C] of the heaters for node temperatures ``T`` (…, n)."""
        T = np.asarray(T, dtype=float)
        out = []
        for h in self.heaters:
            sp = np.full(T.shape[:-1], h.setpoint_c)
            if h.track_node >= 0:
                sp = sp + h.track_gain * (T[..., h.track_node] - h.track_reference_c)
            out.append(sp)
        return np.stack(out, axis=-1) if out else np.zeros(T.shape[:-1] + (0,))

    def _steady_with_heaters(self, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Equilibrium with the heaters' integral action: every unsaturated heater holds its
        sensor at its set point; a heater whose power would leave [0, max] sits at the limit
        (active-set iteration, at most 2H + 1 linear solves)."""
        n, H = self.n_nodes, len(self.heaters)
        K = self.stiffness_w_per_k()
        fixed: dict[int, float] = {}
        for _ in range(2 * H + 2):
            free = [i for i in range(H) if i not in fixed]
            A = np.zeros((n + len(free), n + len(free)))
            b = np.zeros(n + len(free))
            A[:n, :n] = K
            b[:n] = rhs
            for i, P in fixed.items():
                b[self.heaters[i].node] += P
            for r, i in enumerate(free):
                h = self.heaters[i]
                A[h.node, n + r] = -1.0
                A[n + r, h.sensor] = 1.0
                if h.track_node >= 0:
                    A[n + r, h.track_node] -= h.track_gain
                b[n + r] = h.setpoint_c - h.track_gain * h.track_reference_c * (h.track_node >= 0)
            x = np.linalg.solve(A, b)
            powers = np.zeros(H)
            for i, P in fixed.items():
                powers[i] = P
            changed = False
            for r, i in enumerate(free):
                P = x[n + r]
                h = self.heaters[i]
                if P < 0.0 or P > h.max_power_w:
                    fixed[i] = min(max(P, 0.0), h.max_power_w)
                    changed = True
                powers[i] = P
            if not changed:
                return x[:n], powers
        raise ValueError("no steady state of the heater controllers found")

    def heat_to_ambient_w(self, T: Any, ambient_c: Any) -> np.ndarray:
        """Heat flowing from the nodes into the chamber air [W], summed over nodes (…)."""
        T = np.asarray(T, dtype=float)
        Ta = np.asarray(ambient_c, dtype=float)[..., None]
        return np.sum(self.ambient_conductance_w_per_k * (T - Ta), axis=-1)

    def total_power_w(self, powered: bool | float = True) -> float:
        """Heat injected into the network [W]."""
        return float(powered) * float(self.power_w.sum())

    def time_constants_s(self) -> np.ndarray:
        """Time constants of the network's modes at fixed chamber air [s], longest first
        (``1/λ`` for the eigenvalues ``λ`` of ``C⁻¹K``)."""
        d = 1.0 / np.sqrt(self.capacitance_j_per_k)
        lam = np.linalg.eigvalsh(d[:, None] * self.stiffness_w_per_k() * d[None, :])
        return np.sort(1.0 / lam)[::-1]

    # ----------------------------------------------------------------- realisation

    def realise(self, rng: np.random.Generator) -> "ThermalNetwork":
        """One unit drawn from this design: every capacitance, every link conductance, every
        ambient conductance and every heat source is multiplied by an independent factor
        ``exp(σ_rel·N(0,1))`` with the :class:`Tolerance` of its kind.

        Draw order (fixed, so a seed always gives the same unit): capacities (node order),
        links (upper triangle, row-major), ambient links (node order, only non-zero ones), heat
        sources (node order, only non-zero ones). Zero entries stay zero.
        """
        tol = self.tolerance
        n = self.n_nodes
        iu, ju = np.triu_indices(n, k=1)
        link = self.conductance_w_per_k[iu, ju] > 0
        iu, ju = iu[link], ju[link]
        amb = np.flatnonzero(self.ambient_conductance_w_per_k > 0)
        src = np.flatnonzero(self.power_w != 0)
        z = rng.standard_normal(n + iu.size + amb.size + src.size)
        zc, zl = z[:n], z[n:n + iu.size]
        za = z[n + iu.size:n + iu.size + amb.size]
        zp = z[n + iu.size + amb.size:]
        C = self.capacitance_j_per_k * np.exp(tol.capacitance_rel * zc)
        G = np.zeros((n, n))
        G[iu, ju] = self.conductance_w_per_k[iu, ju] * np.exp(tol.conductance_rel * zl)
        G = G + G.T
        g = self.ambient_conductance_w_per_k.copy()
        g[amb] *= np.exp(tol.ambient_conductance_rel * za)
        P = self.power_w.copy()
        P[src] *= np.exp(tol.power_rel * zp)
        extra = {}
        if self.boundaries:
            Gb = self.boundary_conductance_w_per_k.copy()
            nz = np.nonzero(Gb > 0)
            Gb[nz] *= np.exp(tol.ambient_conductance_rel * rng.standard_normal(nz[0].size))
            extra["boundary_conductance_w_per_k"] = Gb
        if self.heaters:
            # after every other draw: per heater a power-limit factor and a set-point offset
            z = rng.standard_normal((len(self.heaters), 2))
            extra["heaters"] = tuple(
                replace(h, max_power_w=h.max_power_w * math.exp(tol.power_rel * z[i, 0]),
                        setpoint_c=h.setpoint_c + tol.heater_setpoint_k * z[i, 1])
                for i, h in enumerate(self.heaters))
        if self.nonlinear_links:
            Gb_new = extra.get("boundary_conductance_w_per_k", self.boundary_conductance_w_per_k)
            links = []
            for ln in self.nonlinear_links:
                if ln.b >= 0:
                    f = G[ln.a, ln.b] / self.conductance_w_per_k[ln.a, ln.b]
                elif ln.b == -1:
                    f = g[ln.a] / self.ambient_conductance_w_per_k[ln.a]
                else:
                    j = -2 - ln.b
                    f = Gb_new[j, ln.a] / self.boundary_conductance_w_per_k[j, ln.a]
                links.append(replace(ln, coefficient=ln.coefficient * f,
                                     linear_w_per_k=ln.linear_w_per_k * f))
            extra["nonlinear_links"] = tuple(links)
        return replace(self, capacitance_j_per_k=C, conductance_w_per_k=G,
                       ambient_conductance_w_per_k=g, power_w=P, **extra)

    # ----------------------------------------------------------------- configuration

    @classmethod
    def from_config(cls, table: Mapping[str, Any], ctx: Ctx) -> "ThermalNetwork":
        """Build from a thermal preset's ``[thermal]`` table (format: module docstring,
        docs/thermal.md). Every key is validated; mistakes raise
        :class:`~rlgsim.ground.errors.UserInputError` naming file, key and value."""
        return _Builder(table, ctx).build()


def nonlinear_flow_w(link: NonlinearLink, ta: Any, tb: Any) -> np.ndarray:
    """Heat [W] from end ``a`` to end ``b`` carried by the nonlinear part of ``link``
    (temperatures in °C)."""
    ta = np.asarray(ta, dtype=float)
    tb = np.asarray(tb, dtype=float)
    d = ta - tb
    if link.kind == "radiation":
        full = link.coefficient * ((ta + ZERO_C_K) ** 4 - (tb + ZERO_C_K) ** 4)
    else:
        full = link.coefficient * (np.abs(d) / link.reference_dt_k) ** link.exponent * d
    return full - link.linear_w_per_k * d


def _check_grounded(names: tuple[str, ...], G: np.ndarray, g: np.ndarray) -> None:
    """Every connected part of the network must reach the chamber air or another boundary
    (``g`` holds the sum of both; else no steady state)."""
    n = len(names)
    seen = np.zeros(n, dtype=bool)
    for start in range(n):
        if seen[start]:
            continue
        part, stack = [], [start]
        seen[start] = True
        while stack:
            i = stack.pop()
            part.append(i)
            for j in np.flatnonzero(G[i] > 0):
                if not seen[j]:
                    seen[j] = True
                    stack.append(j)
        if not np.any(g[part] > 0):
            members = ", ".join(names[i] for i in sorted(part)[:6])
            raise ValueError(f"nodes {members}{' ...' if len(part) > 6 else ''} have no path "
                             f"to the chamber air (add a link to '{CHAMBER_AIR}')")


# --------------------------------------------------------------------------- builder


@dataclass
class _Node:
    name: str
    capacitance: float
    power: float
    description: str


class _Builder:
    """Reads the ``[thermal]`` table into node and link lists, then into matrices."""

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

    def build(self) -> ThermalNetwork:
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
            air, actx = get_section(t, "airflow", ctx, _AIRFLOW_KEYS)
            get_str(air, "description", actx, "")
            get_str(air, "source", actx, "")
            faces = get_table(air, "face_factors", actx)
            fctx = actx.child("face_factors")
            self.face_factors = {f: get_float(faces, f, fctx, min=0.0, min_exclusive=True,
                                              max=100.0) for f in faces}

        templates: dict[str, dict] = {}
        tctx = ctx.child("templates")
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

        # nodes: template instances first (in file order), then top-level nodes
        ictx = ctx.child("instances")
        inst_info: list[tuple[str, dict, dict, Ctx]] = []
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
        nctx = ctx.child("nodes")
        for name, nspec in top_nodes.items():
            self._check_name(name, nctx, "node")
            self._add_node(name, nspec, nctx.child(name))

        # links
        for inst, tmpl, bound, c, lf in inst_info:
            local_nodes = set(tmpl["nodes"])

            def resolve(ref: str, lctx: Ctx, inst=inst, bound=bound, local_nodes=local_nodes,
                        tmpl=tmpl) -> str:
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
        for k, lspec in enumerate(top_links):
            self._add_link(lspec, ctx.child("links").item(k), lambda ref, lctx: ref)

        if not self.nodes:
            raise ctx.error("nodes", "the network has no nodes")
        heaters = self._heaters(get_table(t, "heaters", ctx, {}), ctx.child("heaters"))
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
        try:
            return ThermalNetwork(
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
        except ValueError as exc:
            where = f"{ctx.source}: " if ctx.source else ""
            raise UserInputError(f"{where}{ctx.path or 'thermal'}: {exc}") from None

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
