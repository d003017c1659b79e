"""The thermal fit's networks for many multiplier sets without rebuilding each from its preset
dict (:mod:`rlgsim.lab.identify.thermal_problem`'s batched Jacobian): a multiplier scales design
values, and for a network of capacities, linear links, constant sources and fixed boundaries
each entry of the network's arrays — capacities, the conductance matrix, the links to the
chamber air and to the boundaries, the sources, the probes' lags — is its template value times
the multipliers that reach it. Which ones reach it is read once from the builder itself: the
network built with one multiplier at 2 must show every entry either unchanged or doubled
(doubling is exact in floating point); anything else — an entry that depends on a multiplier
otherwise (``rlg_single``: one conductance entry sums a mount link and an air link, each with its
own multiplier), a changed heater, boundary or topology, a nonlinear link — switches this off, as does a check at
uneven values of every multiplier at once against a full build (1e-12 relative). Then a set's
network is the template's with its arrays scaled, instead of a copied dict validated and
assembled by :meth:`ThermalNetwork.from_config` (1.3 ms a network, some 4,300 networks in the
20 h identification of ``benchmarks/bench_identify.py``). The products are rounded in another
order than the builder's, so a network agrees with a full build to the last bits, not bit for
bit: the fit's residuals and Jacobians use these networks, its result full builds.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from rlgsim.lab.identify.thermal_params import ThermalParam, apply_multipliers
from rlgsim.sim.thermal.network import ThermalNetwork
from rlgsim.sim.thermal.thermometers import ProbeSet

__all__ = ["ScaledTwin"]

_ARRAYS = ("capacitance_j_per_k", "conductance_w_per_k", "ambient_conductance_w_per_k",
           "power_w", "boundary_conductance_w_per_k")
_SAME = ("node_names", "heaters", "boundaries", "nonlinear_links")


def _arrays(net: ThermalNetwork, pr: ProbeSet) -> dict[str, np.ndarray]:
    out = {k: np.asarray(getattr(net, k), dtype=float) for k in _ARRAYS}
    out["tau_s"] = np.asarray(pr.tau_s, dtype=float)
    return out


class ScaledTwin:
    """Networks and probes of ``template`` (a thermal preset dict) for multiplier sets, scaled
    from the template's (module docstring); ``ok`` False when this does not hold for it."""

    def __init__(self, template: dict, params: list[ThermalParam],
                 build: Callable[[dict], tuple[ThermalNetwork, ProbeSet]]) -> None:
        self.net0, self.pr0 = build(template)
        self.base = _arrays(self.net0, self.pr0)
        self.names = [p.name for p in params]
        self.masks: dict[str, dict[str, np.ndarray]] = {}
        self.ok = not self.net0.nonlinear_links
        for p in params if self.ok else []:
            d, _ = apply_multipliers(template, params, {p.name: 2.0})
            net, pr = build(d)
            if any(getattr(net, k) != getattr(self.net0, k) for k in _SAME):
                self.ok = False
                break
            masks = {}
            for k, v in _arrays(net, pr).items():
                b = self.base[k]
                doubled = v == 2.0 * b
                if v.shape != b.shape or not np.all(doubled | (v == b)):
                    self.ok = False
                    break
                masks[k] = doubled & (b != 0.0)
            if not self.ok:
                break
            self.masks[p.name] = masks
        if self.ok:                       # every multiplier at once, at uneven values
            mult = {n: 1.0 + 0.07 * (i + 1) for i, n in enumerate(self.names)}
            d, _ = apply_multipliers(template, params, mult)
            want = _arrays(*build(d))
            got = _arrays(*self.model(mult))
            self.ok = all(np.allclose(got[k], want[k], rtol=1e-12, atol=0) for k in want)

    def model(self, mult: dict[str, float]) -> tuple[ThermalNetwork, ProbeSet]:
        """The network and probes with the multipliers ``mult`` {parameter: factor}."""
        arr = {k: v.copy() for k, v in self.base.items()}
        for name in self.names:               # the order apply_multipliers applies them
            m = float(mult.get(name, 1.0))
            if m != 1.0:
                for k, mask in self.masks[name].items():
                    arr[k][mask] *= m
        tau = arr.pop("tau_s")
        return replace(self.net0, **arr), replace(self.pr0, tau_s=tau)
