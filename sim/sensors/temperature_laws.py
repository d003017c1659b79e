"""Temperature laws: how one sensor parameter (a bias, a scale factor, a misalignment, the UHFO)
follows the thermal state.

Paper 000 (§2, §3.3) makes every parameter of the measurement equations a function of the
temperature field, and builds its case on those functions being *complex nonlinear* — a cubic
least-squares fit captures only the trend. Paper 001 (§2.1, Table 1) adds the temperature rate
and the discharge excitation (UHFO); paper 003 (§2, Table 3) the gradients between points of
the block. One law covers all of them, each term optional:

    p(θ) = value
         + c1·x + c2·x² + c3·x³                    x = T − t_ref   (polynomial, the "cubic")
         + knee · tanh((T − knee_c) / knee_width)                 (a knee: saturating change)
         + step / (1 + exp(−(T − step_c) / step_width))           (a smooth mode-hop-like step)
         + rate · dT/dt                                            (dT/dt in °C/min)
         + Σ_g coeff_g · (T_a,g − T_b,g)                           (multi-point gradients)
         + langmuir · leg_imbalance · (T_D − T_E)                  (gyro bias: Langmuir flow)
         + uhfo · (U − U_0)                                        (discharge excitation)

T is the true temperature of the law's node (the thermal network node, not a probe: the
compensators only ever see probes), dT/dt its backward difference on the thermal grid, the
gradients node-to-node differences, U the true excitation voltage of the gyro's light-intensity
loop (:mod:`rlgsim.sim.sensors.uhfo`). Laws are evaluated on the thermal grid, one value per step (held over
the step's samples).

**Langmuir term.** A two-anode laser gyro cancels the Langmuir (gas-flow) bias of its two
discharge legs only while the leg currents are equal; the residual is ≈ 0.0066 °/h per mA of
imbalance (the figure quoted in docs/design.md after Aronowitz & Lim, 1979). The imbalance is tied to
the arm-to-arm gradient: in a ballast-balanced discharge the sustaining voltage of a leg scales
with its gas number density, ∝ 1/T_abs, i.e. −0.33 %/K of ≈ 500 V, ≈ −1.7 V/K; over an
effective leg resistance (ballast ≈ 100 kΩ minus the plasma's negative dynamic resistance
≈ 50 kΩ) of ≈ 50 kΩ that is ≈ 0.033 mA per kelvin of anode-arm difference T_D − T_E — the
``leg_imbalance_ma_per_k`` default. So the arm gradient is a small but explicit bias term
(≈ 2·10⁻⁴ °/h per K); presets may raise it and give other gradient pairs directly.

Preset keys carry units; ``u`` is the parameter's unit suffix (``deg_per_h``, ``ppm``,
``arcsec``, ``ug``, ``v``): ``value_<u>``, ``c1_<u>_per_k``, ``c2_<u>_per_k2``,
``c3_<u>_per_k3``, ``knee_<u>``, ``knee_c``, ``knee_width_k``, ``step_<u>``, ``step_c``,
``step_width_k``, ``rate_<u>_per_c_per_min``, ``uhfo_<u>_per_v``, ``gradients`` (array of tables
``{a, b, coeff_<u>_per_k}``), ``node``, ``t_ref_c``; gyro bias also ``langmuir_<u>_per_ma`` and
``leg_imbalance_ma_per_k``. Every number may be a scalar (all components) or an array with one
value per component. The ``[tolerance.…]`` table of the same name gives one standard deviation
of the unit-to-unit spread for each key (``gradients_rel``: relative spread of every gradient
coefficient); :meth:`LawSpec.realise` draws a unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from rlgsim.sim.config import Ctx, check_known_keys, get_float, get_list, get_str

#: Canonical coefficient names, in the order they are drawn and reported.
COEFFS = ("value", "c1", "c2", "c3", "knee", "knee_c", "knee_width", "step", "step_c",
          "step_width", "rate", "uhfo", "langmuir", "leg_imbalance")

#: Smallest knee/step width a realisation may draw [K] (keeps tanh/logistic finite and smooth).
MIN_WIDTH_K = 0.2


def _keys(u: str, langmuir: bool) -> dict[str, str]:
    """Preset key → canonical coefficient for unit suffix ``u``."""
    keys = {f"value_{u}": "value", f"c1_{u}_per_k": "c1", f"c2_{u}_per_k2": "c2",
            f"c3_{u}_per_k3": "c3", f"knee_{u}": "knee", "knee_c": "knee_c",
            "knee_width_k": "knee_width", f"step_{u}": "step", "step_c": "step_c",
            "step_width_k": "step_width", f"rate_{u}_per_c_per_min": "rate",
            f"uhfo_{u}_per_v": "uhfo"}
    if langmuir:
        keys[f"langmuir_{u}_per_ma"] = "langmuir"
        keys["leg_imbalance_ma_per_k"] = "leg_imbalance"
    return keys


_DEFAULTS = {"knee_c": 25.0, "knee_width": 5.0, "step_c": 40.0, "step_width": 1.0}


def _numbers(table: Mapping, key: str, ctx: Ctx, n: int, default: float) -> np.ndarray:
    """A scalar or an array of ``n`` numbers → (n,) float array."""
    if key not in table:
        return np.full(n, float(default))
    v = table[key]
    if isinstance(v, list):
        if len(v) != n:
            raise ctx.error(key, f"expected one number or {n} numbers (one per component), "
                                 f"got {len(v)}")
        return np.array([get_float({key: x}, key, ctx) for x in v])
    return np.full(n, get_float(table, key, ctx))


@dataclass(frozen=True)
class Gradient:
    """A gradient term coeff · (T_a − T_b); ``a``/``b`` node names (relative or absolute)."""

    a: str
    b: str
    coeff: np.ndarray            # (C,) in <u> per K


@dataclass(frozen=True)
class LawSpec:
    """A parameter's nominal temperature law plus its unit-to-unit tolerance.

    ``unit`` the preset unit suffix, ``to_si`` the factor from it to SI, ``n`` the number of
    components (sensors, or sensors × 2 for misalignments), ``node`` the temperature node
    (relative to the sensor's block, or absolute), ``t_ref_c`` [°C], ``nominal``/``sigma``
    canonical coefficient → (n,) arrays, ``gradients`` and ``gradient_rel``.
    """

    name: str
    unit: str
    to_si: float
    n: int
    node: str
    t_ref_c: float
    nominal: Mapping[str, np.ndarray]
    sigma: Mapping[str, np.ndarray]
    gradients: tuple[Gradient, ...] = ()
    gradient_rel: float = 0.0
    arm_nodes: tuple[str, str] = ("D", "E")

    @classmethod
    def from_config(cls, table: Mapping | None, ctx: Ctx, *, name: str, unit: str,
                    to_si: float, n: int, node: str, langmuir: bool = False,
                    default_langmuir: float = 0.0, default_imbalance: float = 0.0,
                    t_ref_c: float = 20.0, extra_keys: Sequence[str] = ()) -> "LawSpec":
        """Validate a law table (keys listed in the module docstring; ``extra_keys`` are
        allowed and ignored — the caller reads them); tolerance is added later."""
        table = {} if table is None else table
        keys = _keys(unit, langmuir)
        allowed = [*keys, "node", "t_ref_c", "gradients", *extra_keys]
        if langmuir:
            allowed.append("arm_nodes")
        check_known_keys(table, allowed, ctx)
        nominal: dict[str, np.ndarray] = {}
        for key, coef in keys.items():
            default = _DEFAULTS.get(coef, 0.0)
            if coef == "langmuir":
                default = default_langmuir
            elif coef == "leg_imbalance":
                default = default_imbalance
            nominal[coef] = _numbers(table, key, ctx, n, default)
        for coef in ("knee_width", "step_width"):
            if np.any(nominal[coef] <= 0):
                key = next(k for k, c in keys.items() if c == coef)
                raise ctx.error(key, f"value {nominal[coef].min():g} not allowed; must be > 0")
        grads = []
        for i, g in enumerate(get_list(table, "gradients", ctx, [])):
            gctx = ctx.child("gradients").item(i)
            if not isinstance(g, Mapping):
                raise gctx.error("", "expected a table {a, b, coeff_...}")
            ckey = f"coeff_{unit}_per_k"
            check_known_keys(g, ("a", "b", ckey), gctx)
            if ckey not in g:
                raise gctx.error(ckey, "missing required key")
            grads.append(Gradient(get_str(g, "a", gctx), get_str(g, "b", gctx),
                                  _numbers(g, ckey, gctx, n, 0.0)))
        arm = ("D", "E")
        if langmuir and "arm_nodes" in table:
            arm_list = get_list(table, "arm_nodes", ctx)
            if len(arm_list) != 2 or not all(isinstance(a, str) for a in arm_list):
                raise ctx.error("arm_nodes", "expected two node names, e.g. [\"D\", \"E\"]")
            arm = (arm_list[0], arm_list[1])
        return cls(name=name, unit=unit, to_si=to_si, n=n,
                   node=get_str(table, "node", ctx, node),
                   t_ref_c=get_float(table, "t_ref_c", ctx, t_ref_c, min=-100.0, max=200.0),
                   nominal=nominal, sigma={c: np.zeros(n) for c in nominal},
                   gradients=tuple(grads), arm_nodes=arm)

    def tolerance_keys(self) -> list[str]:
        return [*_keys(self.unit, "langmuir" in self.nominal), "gradients_rel"]

    def with_tolerance(self, table: Mapping | None, ctx: Ctx) -> "LawSpec":
        """This law with the 1σ spreads of a ``[tolerance.<sensor>.<parameter>]`` table."""
        if not table:
            return self
        keys = _keys(self.unit, "langmuir" in self.nominal)
        check_known_keys(table, [*keys, "gradients_rel"], ctx)
        sigma = {c: np.zeros(self.n) for c in self.nominal}
        for key, coef in keys.items():
            if key in table:
                sigma[coef] = np.abs(_numbers(table, key, ctx, self.n, 0.0))
        rel = get_float(table, "gradients_rel", ctx, 0.0, min=0.0)
        return LawSpec(name=self.name, unit=self.unit, to_si=self.to_si, n=self.n,
                       node=self.node, t_ref_c=self.t_ref_c, nominal=self.nominal, sigma=sigma,
                       gradients=self.gradients, gradient_rel=rel, arm_nodes=self.arm_nodes)

    def realise(self, draw) -> "Law":
        """Draw one unit. ``draw(name, shape)`` returns standard normals for a named
        coefficient (keyed draws: adding a coefficient never shifts the others)."""
        coef = {}
        for c in COEFFS:
            if c not in self.nominal:
                continue
            nom, sig = self.nominal[c], self.sigma[c]
            coef[c] = nom + sig * draw(f"{self.name}.{c}", (self.n,)) if np.any(sig > 0) \
                else nom.copy()
        for c in ("knee_width", "step_width"):
            coef[c] = np.maximum(np.abs(coef[c]), MIN_WIDTH_K)
        grads = []
        for i, g in enumerate(self.gradients):
            k = g.coeff
            if self.gradient_rel > 0:
                k = k * (1.0 + self.gradient_rel * draw(f"{self.name}.gradient{i}", (self.n,)))
            grads.append(Gradient(g.a, g.b, k))
        return Law(spec=self, coef=coef, gradients=tuple(grads))


def resolve_node(name: str, block: str, node_names: Sequence[str]) -> int:
    """Index of node ``name`` for a sensor whose block (node prefix) is ``block``:
    ``"<block>.<name>"`` if that exists, else ``name`` itself; ``"self"`` is the node named
    ``block`` (an accelerometer's own node). Raises KeyError naming the node when none exists.
    """
    names = list(node_names)
    cands = [block] if name == "self" else ([f"{block}.{name}"] if block else []) + [name]
    for cand in cands:
        if cand in names:
            return names.index(cand)
    raise KeyError(cands[0])


def _as_slice(index: np.ndarray) -> np.ndarray | slice:
    """Node columns ``index`` as a slice when they are evenly spaced (each component's node in
    its own block of the network: a gyro triad's), else the array. ``nodes_c[:, slice]`` is a
    view of the same numbers, where an index array made a copy in a call that released and
    retook the GIL (eight laws, several columns each, every block)."""
    if index.size and index.min() >= 0:
        step = int(index[1] - index[0]) if index.size > 1 else 1
        if step > 0 and np.array_equal(index, np.arange(index.size) * step + index[0]):
            return slice(int(index[0]), int(index[-1]) + 1, step)
    return index


@dataclass
class Law:
    """A realised law: coefficient arrays (n,) in the preset unit, evaluated in SI."""

    spec: LawSpec
    coef: dict[str, np.ndarray]
    gradients: tuple[Gradient, ...]
    _idx: dict[str, np.ndarray | slice] = field(default_factory=dict, repr=False)
    _terms: dict[str, bool] = field(default_factory=dict, repr=False, compare=False)
    _langmuir: np.ndarray | None = field(default=None, repr=False, compare=False)
    _gradient_idx: tuple = field(default=(), repr=False, compare=False)

    def bind(self, blocks: Sequence[str], node_names: Sequence[str]) -> None:
        """Resolve node names for components whose sensor blocks are ``blocks`` (n,), and fix
        which optional terms :meth:`evaluate` adds (a term whose coefficients are all zero is
        skipped — decided here once, not at every block: the coefficients of a realised law do
        not change after it is bound).

        Raises KeyError (with the node name) for a node not in the network.
        """
        def idx(name: str) -> np.ndarray | slice:
            return _as_slice(np.array([resolve_node(name, blk, node_names) for blk in blocks]))
        c = self.coef
        self._idx = {"T": idx(self.spec.node)}
        for i, g in enumerate(self.gradients):
            self._idx[f"a{i}"] = idx(g.a)
            self._idx[f"b{i}"] = idx(g.b)
        if "langmuir" in c and np.any(c["langmuir"] * c["leg_imbalance"]):
            self._idx["D"] = idx(self.spec.arm_nodes[0])
            self._idx["E"] = idx(self.spec.arm_nodes[1])
        self._terms = {k: bool(np.any(c[k])) for k in ("knee", "step", "rate", "uhfo")}
        self._langmuir = (c["langmuir"] * c["leg_imbalance"]) if "D" in self._idx else None
        self._gradient_idx = tuple((g.coeff, self._idx[f"a{k}"], self._idx[f"b{k}"])
                                   for k, g in enumerate(self.gradients))

    @property
    def uses_uhfo(self) -> bool:
        return bool(np.any(self.coef["uhfo"]))

    def evaluate(self, nodes_c: np.ndarray, start_c: np.ndarray, dt: float,
                 uhfo_dev_v: np.ndarray | None = None) -> np.ndarray:
        """The parameter in SI on the thermal grid, (m, n) (after :meth:`bind`).

        ``nodes_c`` (m, N) node temperatures at the step ends [°C], ``start_c`` (N,) at the
        block start (for dT/dt of the first step), ``dt`` the step [s], ``uhfo_dev_v`` (m, n)
        U − U_0 [V] of each component's gyro (required when the law has a UHFO term).

        The terms in the order of the module docstring, each added to the sum so far.
        """
        c = self.coef
        terms = self._terms
        i = self._idx["T"]
        temp = nodes_c[:, i]
        x = temp - self.spec.t_ref_c
        out = c["value"] + x * (c["c1"] + x * (c["c2"] + x * c["c3"]))
        if terms["knee"]:
            out = out + c["knee"] * np.tanh((temp - c["knee_c"]) / c["knee_width"])
        if terms["step"]:
            out = out + c["step"] / (1.0 + np.exp(-(temp - c["step_c"]) / c["step_width"]))
        if terms["rate"]:
            diff = np.empty_like(temp)                 # backward difference, first step from
            np.subtract(temp[0], start_c[i], out=diff[0])          # the block start
            np.subtract(temp[1:], temp[:-1], out=diff[1:])
            out = out + c["rate"] * (diff * (60.0 / dt))
        for coeff, a, b in self._gradient_idx:
            out = out + coeff * (nodes_c[:, a] - nodes_c[:, b])
        if self._langmuir is not None:
            out = out + self._langmuir * (nodes_c[:, self._idx["D"]] - nodes_c[:, self._idx["E"]])
        if terms["uhfo"]:
            if uhfo_dev_v is None:
                raise ValueError(f"{self.spec.name}: law has a UHFO term but no UHFO was given")
            out = out + c["uhfo"] * uhfo_dev_v
        return out * self.spec.to_si

    def table(self) -> list[tuple[str, np.ndarray, str]]:
        """The drawn coefficients as (name, values (n,), unit) rows for the dataset."""
        u = self.spec.unit
        units = {"value": u, "c1": f"{u}/K", "c2": f"{u}/K^2", "c3": f"{u}/K^3", "knee": u,
                 "knee_c": "degC", "knee_width": "K", "step": u, "step_c": "degC",
                 "step_width": "K", "rate": f"{u}/(degC/min)", "uhfo": f"{u}/V",
                 "langmuir": f"{u}/mA", "leg_imbalance": "mA/K"}
        rows = [(f"{self.spec.name}.{k}", v, units[k]) for k, v in self.coef.items()]
        for i, g in enumerate(self.gradients):
            rows.append((f"{self.spec.name}.gradient[{g.a}-{g.b}]", g.coeff, f"{u}/K"))
        return rows
