"""Thermometer probes on thermal-network nodes: first-order lag, white noise, resolution.

The compensators never see node truth, only these readings (docs/design.md "Thermal network").
Each probe ``p`` sits on node ``i(p)``; its sensing element follows the node with a first-order
lag (docs/thermal.md, eq. (5))::

    τ_p dθ_p/dt = T_i(p)(t) − θ_p,

with the node temperature linear between the thermal grid points (the same first-order hold
the thermal integrator uses), so the exact discretisation over a step ``h`` is::

    θ[k+1] = a θ[k] + (1 − a) T[k] + c (T[k+1] − T[k]),  a = e^{−h/τ},  c = 1 − (τ/h)(1 − a).

The reading is ``round((θ[k] + σ·n[k]) / q)·q`` with ``n[k]`` standard normal draws from the
generator handed in (resolution ``q``; ``q = 0`` means no quantisation, ``τ = 0`` no lag).
The lag runs as :func:`scipy.signal.lfilter` recurrences (one per distinct ``τ``) with their
state carried between calls, so splitting a trace into blocks gives bit-identical lags. Once
numba is loaded a block is read in one compiled pass instead (:mod:`rlgsim.sim.thermal._probe_kernel`:
the same operations, the same readings).

Preset format (``[probes]`` table of a thermal preset, next to ``[thermal]``)::

    [probes.defaults]            # values every probe inherits unless it sets its own
    tau_s = 5.0
    noise_sigma_c = 0.01
    resolution_c = 0.0625

    [[probes.groups]]            # one probe per listed node on every instance of a template
    template = "rlg_block"       # probes named "<instance>.<node>", e.g. "gx.A"
    nodes = ["A", "B", "C", "D", "E", "F", "G", "H"]
    # instances = ["gx"]         # optional subset; tau_s/noise_sigma_c/resolution_c optional

    [probes.points.housing]      # a single probe named "housing"
    node = "housing_air"
    tau_s = 20.0
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import scipy.signal

from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_list, get_str, get_table
from rlgsim.ground.errors import UserInputError
from rlgsim.sim.thermal.network import ThermalNetwork

_PARAMS = ("tau_s", "noise_sigma_c", "resolution_c")
#: Upper limits that catch unit mistakes (a lag of more than a day, noise above 10 K ...).
_LIMITS = {"tau_s": 86400.0, "noise_sigma_c": 10.0, "resolution_c": 10.0}


@dataclass(frozen=True, eq=False)
class ProbeSet:
    """Probes ``names`` on nodes ``node_index`` with lag ``tau_s`` [s], white-noise standard
    deviation ``noise_sigma_c`` [K] and resolution ``resolution_c`` [K] (all (n_probes,))."""

    names: tuple[str, ...]
    node_index: np.ndarray
    tau_s: np.ndarray
    noise_sigma_c: np.ndarray
    resolution_c: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.names)
        idx = np.asarray(self.node_index, dtype=np.int64).reshape(-1)
        arrays = {k: np.asarray(getattr(self, k), dtype=float).reshape(-1) for k in _PARAMS}
        if idx.shape != (n,) or any(a.shape != (n,) for a in arrays.values()):
            raise ValueError("every probe needs a node, tau_s, noise_sigma_c and resolution_c")
        if len(set(self.names)) != n:
            raise ValueError("probe names must be unique")
        if any(np.any(~np.isfinite(a) | (a < 0)) for a in arrays.values()):
            raise ValueError("tau_s, noise_sigma_c and resolution_c must be finite and >= 0")
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "node_index", idx)
        for k, a in arrays.items():
            a.setflags(write=False)
            object.__setattr__(self, k, a)
        object.__setattr__(self, "_coeff_cache", {})

    @property
    def n_probes(self) -> int:
        return len(self.names)

    # ----------------------------------------------------------------- configuration

    @classmethod
    def from_config(cls, table: Mapping[str, Any], network: ThermalNetwork,
                    ctx: Ctx) -> "ProbeSet":
        """Build from a thermal preset's ``[probes]`` table (format: module docstring)."""
        if not isinstance(table, Mapping):
            where = f"{ctx.source}: " if ctx.source else ""
            raise UserInputError(f"{where}{ctx.path or 'probes'}: expected a table")
        check_known_keys(table, ("defaults", "groups", "points"), ctx)
        dctx = ctx.child("defaults")
        defaults_raw = get_table(table, "defaults", ctx, {})
        check_known_keys(defaults_raw, _PARAMS, dctx)
        defaults = {k: _param(defaults_raw, k, dctx, None) for k in _PARAMS}

        names: list[str] = []
        nodes: list[int] = []
        params: dict[str, list[float]] = {k: [] for k in _PARAMS}

        def add(name: str, node: int, spec: Mapping[str, Any], sctx: Ctx, where: str) -> None:
            if name in names:
                raise sctx.error(where, f"probe {name!r} defined twice")
            names.append(name)
            nodes.append(node)
            for k in _PARAMS:
                value = _param(spec, k, sctx, defaults[k])
                if value is None:
                    raise sctx.error(k, "missing required key (set it here or in "
                                        "[probes.defaults])")
                params[k].append(value)

        gctx = ctx.child("groups")
        for gi, group in enumerate(get_list(table, "groups", ctx, [])):
            c = gctx.item(gi)
            if not isinstance(group, Mapping):
                raise UserInputError(f"{c.source + ': ' if c.source else ''}{c.path}: "
                                     f"expected a table")
            check_known_keys(group, ("template", "nodes", "instances", *_PARAMS), c)
            template = get_str(group, "template", c, choices=list(network.templates) or None)
            if template not in network.templates:
                raise c.error("template", f"value {template!r} not allowed; the network has "
                                          f"no templates")
            local = network.templates[template]
            wanted = get_list(group, "nodes", c, min_len=1)
            for node in wanted:
                get_str({"nodes": node}, "nodes", c, choices=local)
            instances = [i for i, t in network.instances.items() if t == template]
            if "instances" in group:
                chosen = get_list(group, "instances", c, min_len=1)
                for inst in chosen:
                    get_str({"instances": inst}, "instances", c, choices=instances)
                instances = [i for i in instances if i in chosen]
            for inst in instances:
                for node in wanted:
                    full = f"{inst}.{node}"
                    add(full, network.index(full), group, c, "nodes")

        pctx = ctx.child("points")
        for name, spec in get_table(table, "points", ctx, {}).items():
            c = pctx.child(name)
            if not isinstance(spec, Mapping):
                raise pctx.error(name, "expected a table")
            check_known_keys(spec, ("node", *_PARAMS), c)
            node = get_str(spec, "node", c, choices=network.node_names)
            add(name, network.index(node), spec, c, "node")
        if not names:
            raise ctx.error("groups", "no probes defined (give [[probes.groups]] or "
                                      "[probes.points.<name>])")
        return cls(names=tuple(names), node_index=np.array(nodes, dtype=np.int64),
                   **{k: np.array(v) for k, v in params.items()})

    # ----------------------------------------------------------------- reading

    def initial_state(self, node_temps: Any) -> np.ndarray:
        """Probe state at equilibrium with node temperatures ``node_temps`` (n,) [°C]:
        ``(2, n_probes)`` — row 0 the sensing elements ``θ``, row 1 the probed node
        temperatures at the same instant (needed for the first-order hold of the next step)."""
        T = np.asarray(node_temps, dtype=float).reshape(-1)[self.node_index]
        return np.vstack((T, T))

    def _coefficients(self, step_s: float) -> tuple[np.ndarray, np.ndarray]:
        cache = self._coeff_cache            # type: ignore[attr-defined]
        if step_s not in cache:
            tau = self.tau_s
            lagged = tau > 0
            x = np.where(lagged, step_s / np.where(lagged, tau, 1.0), np.inf)
            a = np.where(lagged, np.exp(-x), 0.0)
            # c = 1 − (τ/h)(1 − a), with 1 − a = −expm1(−h/τ) for accuracy at small h/τ
            c = np.where(lagged, 1.0 + np.expm1(-x) / np.where(lagged, x, 1.0), 1.0)
            cache[step_s] = (a, c)
        return cache[step_s]

    def _lagged(self) -> np.ndarray:
        cache = self._coeff_cache            # type: ignore[attr-defined]
        if "lagged" not in cache:
            cache["lagged"] = self.tau_s > 0
        return cache["lagged"]

    def read(self, state: Any, node_temps: Any, step_s: float, rng: np.random.Generator,
             compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Readings (m, n_probes) [°C] at the grid points of ``node_temps`` (m, n) — the node
        temperatures one step ``step_s`` [s] apart, following the instant of ``state`` — and
        the new state. Noise: one ``rng.standard_normal((m, n_probes))`` draw.

        ``compiled``: compute the block in one call of compiled code
        (:func:`rlgsim.sim.thermal._probe_kernel.read_block`, the same operations in the same order);
        None (default): when this process has imported numba already (importing it costs
        more than a short run saves); False: the NumPy path below."""
        T = np.asarray(node_temps, dtype=float)
        if T.ndim != 2:
            raise ValueError("node_temps must be (m, n_nodes)")
        st = np.asarray(state, dtype=float)
        if st.shape != (2, self.n_probes):
            raise ValueError(f"probe state must be (2, {self.n_probes}), got {st.shape}")
        if not (np.isfinite(step_s) and step_s > 0):
            raise ValueError("step_s must be > 0")
        m = T.shape[0]
        if m == 0:
            return np.empty((0, self.n_probes)), st.copy()
        kernel = _compiled_reader(compiled)
        if kernel is not None:
            a, c = self._coefficients(float(step_s))
            reading = rng.standard_normal((m, self.n_probes))
            new_state = np.empty((2, self.n_probes))
            kernel(T, self.node_index, st, a, c, self._lagged(), self.noise_sigma_c,
                   self.resolution_c, reading, new_state)
            return reading, new_state
        # work probe-major (n_probes, m): each probe's trace contiguous for lfilter
        X = T.T[self.node_index]                        # probed node temperatures
        prev = np.empty_like(X)                         # T[k] for the step k → k+1
        prev[:, 0] = st[1]
        prev[:, 1:] = X[:, :-1]
        a, c = self._coefficients(float(step_s))
        theta = np.empty_like(X)
        for tau in np.unique(self.tau_s):
            rows = np.flatnonzero(self.tau_s == tau)
            if tau == 0:
                theta[rows] = X[rows]
                continue
            ag, cg = a[rows[0]], c[rows[0]]
            forcing = (1.0 - ag - cg) * prev[rows]
            forcing += cg * X[rows]
            theta[rows], _ = scipy.signal.lfilter([1.0], [1.0, -ag], forcing, axis=-1,
                                                  zi=(ag * st[0, rows])[:, None])
        new_state = np.vstack((theta[:, -1], X[:, -1]))
        reading = rng.standard_normal((m, self.n_probes))
        reading *= self.noise_sigma_c
        reading += theta.T
        q = self.resolution_c
        if np.all(q > 0):
            reading /= q
            np.round(reading, out=reading)
            reading *= q
        elif np.any(q > 0):
            cols = np.flatnonzero(q > 0)
            reading[:, cols] = np.round(reading[:, cols] / q[cols]) * q[cols]
        return reading, new_state


def _compiled_reader(compiled: bool | None) -> Any:
    """:func:`rlgsim.sim.thermal._probe_kernel.read_block` if it is to be used (see
    :meth:`ProbeSet.read`) and numba is importable, else None."""
    if compiled is None:
        compiled = "numba" in sys.modules
    if not compiled:
        return None
    try:
        from rlgsim.sim.thermal._probe_kernel import read_block
    except ImportError:                          # pragma: no cover - numba is optional
        return None
    return read_block


def _param(spec: Mapping[str, Any], key: str, ctx: Ctx, default: Any) -> float | None:
    return get_float(spec, key, ctx, default, min=0.0, max=_LIMITS[key])
