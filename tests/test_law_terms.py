"""Law.evaluate with its terms fixed at bind time gives, bit for bit, the law written out term
by term (the module docstring's formula in its order, every term tested at every call), for
laws with every term, with none, and with only some."""

from __future__ import annotations

import numpy as np
import pytest

from rlgsim.sim.config import Ctx
from rlgsim.sim.sensors.temperature_laws import LawSpec

NODES = ("g.A", "g.G", "g.D", "g.E", "g.discharge", "base", "h.A", "h.G", "h.D", "h.E")


def _reference(law, nodes_c, start_c, dt, uhfo_dev_v):
    """The formula term by term, each optional term tested on the coefficients."""
    c = law.coef
    i = law._idx["T"]
    temp = nodes_c[:, i]
    x = temp - law.spec.t_ref_c
    out = c["value"] + x * (c["c1"] + x * (c["c2"] + x * c["c3"]))
    if np.any(c["knee"]):
        out = out + c["knee"] * np.tanh((temp - c["knee_c"]) / c["knee_width"])
    if np.any(c["step"]):
        out = out + c["step"] / (1.0 + np.exp(-(temp - c["step_c"]) / c["step_width"]))
    if np.any(c["rate"]):
        prev = np.vstack([start_c[i][None, :], temp[:-1]])
        out = out + c["rate"] * ((temp - prev) * (60.0 / dt))
    for k, g in enumerate(law.gradients):
        out = out + g.coeff * (nodes_c[:, law._idx[f"a{k}"]] - nodes_c[:, law._idx[f"b{k}"]])
    if "langmuir" in c and np.any(c["langmuir"] * c["leg_imbalance"]):
        d, e = (np.array([NODES.index(f"{b}.{n}") for b in ("g", "h")])
                for n in law.spec.arm_nodes)
        out = out + (c["langmuir"] * c["leg_imbalance"]) * (nodes_c[:, d] - nodes_c[:, e])
    if np.any(c["uhfo"]):
        out = out + c["uhfo"] * uhfo_dev_v
    return out * law.spec.to_si


TABLES = {
    "all": {"value_u": 0.1, "c1_u_per_k": 3e-4, "c2_u_per_k2": -4e-6, "c3_u_per_k3": 8e-8,
            "knee_u": 0.008, "knee_c": 30.0, "knee_width_k": 4.0, "step_u": -0.006,
            "step_c": 25.0, "step_width_k": 1.0, "rate_u_per_c_per_min": [-0.01, 0.02],
            "uhfo_u_per_v": -0.005, "langmuir_u_per_ma": 0.0066,
            "leg_imbalance_ma_per_k": 0.033,
            "gradients": [{"a": "A", "b": "G", "coeff_u_per_k": 0.004},
                          {"a": "D", "b": "base", "coeff_u_per_k": [0.001, -0.002]}]},
    "polynomial": {"c1_u_per_k": 0.3, "c2_u_per_k2": -0.004},
    "some": {"knee_u": [0.0, 0.8], "rate_u_per_c_per_min": [0.0, 0.0], "value_u": 5.0},
    "none": {},
}


@pytest.mark.parametrize("name", list(TABLES))
def test_evaluate_equals_the_formula_term_by_term(name):
    spec = LawSpec.from_config(TABLES[name], Ctx("test"), name="law", unit="u", to_si=1e-6,
                               n=2, node="A", langmuir=True)
    rng = np.random.default_rng(7)
    sigma = {k: np.abs(v) * 0.3 + 0.01 for k, v in spec.nominal.items()}
    law = LawSpec(**{**spec.__dict__, "sigma": sigma}).realise(
        lambda key, shape: rng.standard_normal(shape))
    if name == "none":
        law = spec.realise(lambda key, shape: rng.standard_normal(shape))
    law.bind(("g", "h"), NODES)
    m = 50
    nodes_c = 20.0 + np.cumsum(rng.normal(0, 0.5, (m, len(NODES))), axis=0)
    start_c = nodes_c[0] - rng.normal(0, 0.5, len(NODES))
    uhfo = rng.normal(0, 0.1, (m, 2))
    got = law.evaluate(nodes_c, start_c, 5.0, uhfo)
    ref = _reference(law, nodes_c, start_c, 5.0, uhfo)
    assert got.shape == (m, 2)
    assert got.tobytes() == ref.tobytes()
