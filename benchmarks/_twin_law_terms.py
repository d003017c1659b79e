"""The true bias law of a dataset on its 100 s windows, split by term group (docs/identify.md).

For the digital twin's closed loop (``benchmarks/bench_identify.py`` part B): the original
unit's and its twin's laws are compared group by group, so the report says which part of the
law the twin misses.
"""

from __future__ import annotations

import pathlib

import numpy as np


def window_bias(path) -> tuple[np.ndarray, np.ndarray, object]:
    import rlgsim
    w = rlgsim.window_table(str(path))
    law = np.asarray(w["true_bias_deg_per_h"] - w["true_random_deg_per_h"])
    return law, np.asarray(w["bias_deg_per_h"]), w


#: the law's terms grouped for the decomposition of the bias-law difference (docs/identify.md)
LAW_GROUPS = ("intercept and T polynomial", "knee/step", "rate", "gradients", "uhfo law",
              "uhfo wander", "hops and the rest")


def law_terms(path) -> dict[str, np.ndarray]:
    """The true bias law of a dataset split into :data:`LAW_GROUPS`, each on the 100 s windows
    of :func:`window_bias` [°/h]: every term evaluated as the simulator's law evaluates it
    (sim/sensors/temperature_laws.py ``Law.evaluate``) from the truth record's drawn coefficients, true
    node temperatures and true UHFO; the UHFO term split into the UHFO law's part (its own law
    on the discharge node, sim/sensors/uhfo.py) and the discharge wander's (the true UHFO less its law:
    a Gauss–Markov process each run draws anew); "hops and the rest" is the window law less
    the terms (the mode hops' offsets, which are not a coefficient)."""
    import re
    import tomllib
    import rlgsim
    from rlgsim.estimators.features import window_average
    from rlgsim.sim import presets
    law, _, w = window_bias(path)
    with rlgsim.open_tree(str(path), load=True) as t:
        co = {re.sub(r"\[z\]$", "", str(k)): float(v)
              for k, v in zip(t["truth"]["coefficient"].values,
                              t["truth"]["coefficient_value"].values)}
        nodes = np.asarray(t["thermal"]["node_temperature"].values)
        names = [str(n) for n in t["thermal"]["node"].values]
        u_dev = (np.asarray(t["truth"]["uhfo_true"].values)[:, 0]
                 - float(np.asarray(t["truth"]["uhfo_u0"].values)[0])
                 if "uhfo_true" in t["truth"] else np.zeros(nodes.shape[0]))
        dev = tomllib.loads(str(t.attrs["scenario_text"]))["device"]
        src = pathlib.Path(str(t.attrs["scenario_source"])).parent
    device = presets.load_device_file(str(src / dev) if dev.endswith(".toml") else dev).data
    gyro = device["gyro"]
    block = (gyro.get("blocks") or [""])[0]
    bias = gyro.get("bias", {})
    node = str(bias.get("node", gyro.get("node", "A")))
    t_ref = float(bias.get("t_ref_c", gyro.get("t_ref_c", 20.0)))

    def col(n: str) -> np.ndarray:
        return nodes[:, names.index(f"{block}.{n}" if block else n)]
    c = {k.split(".", 2)[2]: v for k, v in co.items() if k.startswith("gyro.bias.")}
    T = col(node)
    x = T - t_ref
    parts = {g: np.zeros_like(T) for g in LAW_GROUPS[:-1]}
    parts["intercept and T polynomial"] = c.get("value", 0.0) + x * (
        c.get("c1", 0.0) + x * (c.get("c2", 0.0) + x * c.get("c3", 0.0)))
    if c.get("knee"):
        parts["knee/step"] = parts["knee/step"] + c["knee"] * np.tanh(
            (T - c["knee_c"]) / c["knee_width"])
    if c.get("step"):
        parts["knee/step"] = parts["knee/step"] + c["step"] / (
            1.0 + np.exp(-(T - c["step_c"]) / c["step_width"]))
    if c.get("rate"):
        parts["rate"] = c["rate"] * np.diff(T, prepend=T[0]) * 60.0   # 1 s thermal step
    for k, v in c.items():
        m = re.fullmatch(r"gradient\[(\w+)-(\w+)\]", k)
        if m and v:
            parts["gradients"] = parts["gradients"] + v * (col(m[1]) - col(m[2]))
    if c.get("uhfo"):
        ut = device.get("uhfo", {})
        cu = {k.split(".", 1)[1]: v for k, v in co.items() if k.startswith("uhfo.")}
        Tu = col(str(ut.get("node", "discharge")))
        xu = Tu - float(ut.get("t_ref_c", 20.0))
        u_law = x0 = cu.get("value", 0.0)
        u_law = x0 + xu * (cu.get("c1", 0.0) + xu * (cu.get("c2", 0.0) + xu * cu.get("c3", 0.0)))
        if cu.get("knee"):
            u_law = u_law + cu["knee"] * np.tanh((Tu - cu["knee_c"]) / cu["knee_width"])
        if cu.get("step"):
            u_law = u_law + cu["step"] / (1.0 + np.exp(-(Tu - cu["step_c"]) / cu["step_width"]))
        if cu.get("rate"):
            u_law = u_law + cu["rate"] * np.diff(Tu, prepend=Tu[0]) * 60.0
        u0 = x0
        parts["uhfo law"] = c["uhfo"] * (u_law - u0)
        parts["uhfo wander"] = c["uhfo"] * (u_dev - (u_law - u0))
    rows = np.rint(np.asarray(w["time_s"], dtype=float) / 100.0).astype(int) - 1
    out = {g: np.asarray(window_average(v, 1.0, 100.0))[rows] for g, v in parts.items()}
    out["hops and the rest"] = law - sum(out.values())
    return out


def _centred_rms(a: np.ndarray, b: np.ndarray) -> float:
    """RMS of the difference of two window series, each less its mean (the common length)."""
    n = min(a.size, b.size)
    return float(np.sqrt(np.mean(((a[:n] - a[:n].mean()) - (b[:n] - b[:n].mean())) ** 2)))


def law_decomposition(po: dict[str, np.ndarray], pt: dict[str, np.ndarray]) -> str:
    """One line: the RMS of the twin-minus-original bias-law difference (each centred, as the
    bound compares them) that each group of :func:`law_terms` contributes, and what the
    difference's RMS would be with that group alone made equal in the twin — the groups are
    correlated (a gradient standing in for the rate), so the second figure says which part
    dominates. ``po``, ``pt``: :func:`law_terms` of the original and the twin."""
    n = min(next(iter(po.values())).size, next(iter(pt.values())).size)
    d = {g: (po[g][:n] - po[g][:n].mean()) - (pt[g][:n] - pt[g][:n].mean()) for g in po}
    total = sum(d.values())
    rms = lambda v: float(np.sqrt(np.mean(v ** 2)))          # noqa: E731
    return ("law difference by term group [°/h], RMS of the group's difference / total RMS "
            f"without it (total {rms(total):.4f}): " + "; ".join(
                f"{g} {rms(d[g]):.4f}/{rms(total - d[g]):.4f}" for g in LAW_GROUPS))
