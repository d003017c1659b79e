"""The lumped thermal network of an RLG (or RLG-IMU): nodes, conductances, heat sources.

Model (docs/thermal.md; docs/design.md "Thermal network"): ``n`` isothermal nodes with heat
capacities ``C_i`` [J/K], node-to-node conductances ``G_ij = G_ji`` [W/K], conductances to the
chamber air ``g_i`` [W/K] and heat sources ``P_i`` [W] switched by the power state
``u(t) ∈ {0, 1}``::

    C_i dT_i/dt = Σ_j G_ij (T_j − T_i) + g_i (T_air − T_i) + u(t) P_i

or, with the weighted Laplacian ``L = diag(Σ_j G_ij) − G`` and the stiffness ``K = L + diag(g)``
(symmetric positive definite when every part of the network reaches the chamber air)::

    C dT/dt = −K T + g T_air + u P.

Numbers come from the thermal presets (``scenarios/thermal/*.toml``, read by
:mod:`rlgsim.sim.thermal.network_builder`), never from this code: a
node's capacity is given directly or as material × volume/mass (ρ·c·V, paper 003 Table 1 for
Zerodur: 2530 kg/m³, 800 J/(kg·K), 1.46 W/(m·K)); a link's conductance directly or as
conduction ``k·A/ℓ``, convection ``h·A`` and linearised radiation ``4·ε·σ·T_ref³·A`` (summed).

Model vs realisation: the preset describes the *design* (nominal values + tolerances);
:meth:`ThermalNetwork.realise` draws one *unit* (each capacitance, conductance and power
multiplied by an independent log-normal factor ``exp(σ_rel·N(0,1))``, median 1), which is what
a Monte Carlo run simulates.

Why this file is over 400 lines: it is one class, the network's physics — its matrices, the
heat flows (linear, nonlinear, to boundaries, from heaters), the steady states with and without
heaters and nonlinear links, and the drawn unit (:meth:`ThermalNetwork.realise`) — whose
methods share the same few arrays; the preset reader and the elements are apart.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field, replace
from typing import Any, Mapping

import numpy as np
import scipy.linalg

from rlgsim.ground.errors import UserInputError
from rlgsim.sim.config import Ctx
from rlgsim.sim.thermal.network_builder import network_fields
from rlgsim.sim.thermal.network_parts import (CHAMBER_AIR, Boundary, Heater, NonlinearLink,
                                               Tolerance, nonlinear_flow_w)

__all__ = ["ThermalNetwork"]


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
        :class:`~rlgsim.ground.errors.UserInputError` naming file, key and value
        (:mod:`rlgsim.sim.thermal.network_builder` reads it)."""
        fields = network_fields(table, ctx)
        try:
            return cls(**fields)
        except ValueError as exc:
            where = f"{ctx.source}: " if ctx.source else ""
            raise UserInputError(f"{where}{ctx.path or 'thermal'}: {exc}") from None


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
