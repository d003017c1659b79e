"""Fit of the paper-003 device (rlg8_003 + thermal preset rlg8_003_block) to paper 003's
measurements: Table 3 (|r| of the bias with the 28 pairwise gradients of thermometers A-H) and
the raw 100 s bias STD of Table 4 (0.0258 °/h on the four-rate cycles).

Only the thermal network and the probes of the study's train run (paper003_cycles, its own
seed) are simulated (≈ 1 s); the bias is the device's temperature law evaluated on the true node
temperatures, plus white noise of 0.002 °/h on the 100 s means (the device's oracle floor: ARW,
flicker and read-out in 100 s means, docs/sensors.md). The figures it prints are those of the
study's Table 3 section to within that noise approximation; the study itself is the check.

    python benchmarks/fit_rlg8_003.py                 the shipped presets: Table 3 figures
    python benchmarks/fit_rlg8_003.py --set KEY=VALUE the same with parameters changed
    python benchmarks/fit_rlg8_003.py --law           ... and the bias-law direction refitted
    python benchmarks/fit_rlg8_003.py --fit [--evals N] fit the parameters below (prints them;
                                                      the presets are edited by hand)
    --thermal/--device/--scenario PATH                 variants of the presets / another run

The shipped numbers come from ``--fit --evals 90`` started at windward 1.6, leeward 0.6,
ballast_E power 1.2, the other factors 1, table 8 kg / 2.5 W/K (≈ 95 s wall on 2 busy cores):
pattern 0.725, mirror pairs 0.89 / 0.86 / 0.89, A row ≥ 0.958; rounded as in the presets they
give 0.719 here and 0.720 in the study. The bias law is the nominal one (no unit-to-unit draw).

What is fitted (each within the bounds its physical source allows; docs/thermal.md §7):
the airflow face factors, the nominal arm-asymmetry factors (ballast power, anode-region
capacity and coupling), the turntable's mass and its link to the laboratory, and the four
gradient coefficients of the bias law (their direction by the Table 3 pattern, their scale by
the raw STD). The objective is the Table 3 pattern only — the Pearson correlation of our |r|
with the paper's over the 28 pairs, with penalties below the issue's floors (mirror pairs 0.6,
A row 0.9) — never a compensation ranking.
"""

from __future__ import annotations

import argparse
import itertools
import pathlib
import re
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

PUBLISHED = np.array([            # paper 003 Table 3 (rows/columns A ... H)
    [0.0,   0.939, 0.938, 0.913, 0.938, 0.912, 0.935, 0.942],
    [0.939, 0.0,   0.781, 0.888, 0.898, 0.902, 0.913, 0.739],
    [0.938, 0.781, 0.0,   0.876, 0.633, 0.242, 0.824, 0.916],
    [0.913, 0.888, 0.876, 0.0,   0.924, 0.831, 0.904, 0.647],
    [0.938, 0.898, 0.633, 0.924, 0.0,   0.733, 0.412, 0.231],
    [0.912, 0.902, 0.242, 0.831, 0.733, 0.0,   0.647, 0.750],
    [0.935, 0.913, 0.824, 0.904, 0.412, 0.647, 0.0,   0.932],
    [0.942, 0.739, 0.916, 0.647, 0.231, 0.750, 0.932, 0.0]])
POINTS = "ABCDEFGH"
MIRRORS = ((1, 2), (3, 4), (5, 7))        # B-C, D-E, F-H
RAW_STD = 0.0258                          # paper 003 Table 4, before compensation [°/h]
FLOOR = 0.002                             # white part of the 100 s means [°/h]

THERMAL = ROOT / "scenarios" / "thermal" / "rlg8_003_block.toml"
DEVICE = ROOT / "scenarios" / "devices" / "rlg8_003.toml"
SCENARIO = ROOT / "scenarios" / "paper003_cycles.toml"

_NUM = r"([-+0-9.eE]+)"
#: name: (file, regex with one number group, lower, upper)
PARAMS: dict[str, tuple[str, str, float, float]] = {
    "windward": ("thermal", r"face_factors = \{ windward = " + _NUM, 1.0, 2.0),
    "leeward": ("thermal", r"face_factors = \{ windward = [-+0-9.eE]+, leeward = " + _NUM,
                0.4, 1.0),
    "ballast_E_power": ("thermal", r"power_factors = \{ ballast_E = " + _NUM, 0.8, 1.25),
    "E_capacitance": ("thermal", r"capacitance_factors = \{ E = " + _NUM, 0.8, 1.25),
    "discharge_E_link": ("thermal", r'link_factors = \{ "discharge--E" = ' + _NUM, 0.8, 1.25),
    "ballast_E_link": ("thermal", r'"ballast_E--E" = ' + _NUM, 0.5, 2.0),
    "table_mass_kg": ("thermal", r"mass_kg = " + _NUM + r"\s+# fitted: turntable", 2.0, 30.0),
    "table_lab_w_per_k": ("thermal", r"conductance_w_per_k = " + _NUM
                          + r"\s+# fitted: shaft", 0.1, 5.0),
}
GRADIENTS = ("G", "H", "B", "D")          # candidate bias-law gradients A-X (paper 003 §4.3)


def _sub(text: str, pattern: str, value: float) -> str:
    m = re.search(pattern, text)
    if m is None:
        raise SystemExit(f"pattern not found: {pattern}")
    return text[:m.start(1)] + f"{value:.4g}" + text[m.end(1):]


def current() -> dict[str, float]:
    text = THERMAL.read_text()
    out = {}
    for name, (_, pat, _, _) in PARAMS.items():
        m = re.search(pat, text)
        if m is not None:                 # a variant may lack a mechanism
            out[name] = float(m.group(1))
    return out


def simulate(params: dict[str, float], tmp: pathlib.Path, scenario: pathlib.Path | None = None):
    """Thermal + probes of the train run with ``params``; returns (node temps, node names,
    probe 100 s means, probe names, scenario)."""
    import h5py

    import rlgsim.sim.run.simulate as S
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.stages.probes import ProbeStage

    thermal = THERMAL.read_text()
    for name, value in params.items():
        thermal = _sub(thermal, PARAMS[name][1], value)
    (tmp / "thermal.toml").write_text(thermal)
    dev = DEVICE.read_text().replace('thermal_preset = "rlg8_003_block"',
                                     f'thermal_preset = "{tmp / "thermal.toml"}"')
    (tmp / "device.toml").write_text(dev)
    sc_text = (scenario or SCENARIO).read_text().replace('device = "rlg8_003"',
                                           f'device = "{tmp / "device.toml"}"')
    (tmp / "scenario.toml").write_text(sc_text)
    sc = load_scenario(str(tmp / "scenario.toml"))
    stages = S.STAGES
    S.STAGES = [ProbeStage.create]
    try:
        S.simulate(sc, tmp / "run.h5", progress=False)
    finally:
        S.STAGES = stages
    with h5py.File(tmp / "run.h5") as f:
        T = f["thermal/node_temperature"][...]
        nodes = [n.decode() if isinstance(n, bytes) else str(n) for n in f["thermal/node"][...]]
        pr = f["probes/temperature"][...]
        pn = [n.decode() if isinstance(n, bytes) else str(n) for n in f["probes/probe"][...]]
    return T, nodes, pr, pn, sc


class Windows:
    """100 s means of the law's terms and of the probe gradients for one simulated run."""

    def __init__(self, T, nodes, pr, pn, sc) -> None:
        law = sc.device.parts["gyro"].bias.realise(lambda n, s: np.zeros(s))
        law.bind(["g"], nodes)
        full = law.evaluate(T, T[0], 1.0)[:, 0] / law.spec.to_si
        self.nw = full.size // 100
        w = lambda x: x[:self.nw * 100].reshape(self.nw, 100, *x.shape[1:]).mean(axis=1)
        ia = nodes.index("g.A")
        self.terms = np.column_stack([w(T[:, ia] - T[:, nodes.index(f"g.{x}")])
                                      for x in GRADIENTS])
        self.coef = np.zeros(len(GRADIENTS))                 # the preset's, on GRADIENTS
        for g in law.gradients:
            if g.a == "A" and g.b in GRADIENTS:
                self.coef[GRADIENTS.index(g.b)] += float(g.coeff[0])
        self.rest = w(full) - self.terms @ self.coef          # every other term of the law
        pw = w(pr)
        self.grad = {}
        for i, j in itertools.combinations(range(8), 2):
            self.grad[i, j] = (pw[:, pn.index(f"g.{POINTS[i]}")]
                               - pw[:, pn.index(f"g.{POINTS[j]}")])
        self.noise = np.random.default_rng(0).normal(0.0, FLOOR, self.nw)

    def bias(self, coef: np.ndarray) -> np.ndarray:
        return self.terms @ coef + self.rest + self.noise

    def table3(self, coef: np.ndarray) -> np.ndarray:
        y = self.bias(coef)
        R = np.zeros((8, 8))
        for (i, j), g in self.grad.items():
            R[i, j] = R[j, i] = np.corrcoef(g, y)[0, 1]
        return R


def figures(R: np.ndarray) -> dict[str, float]:
    iu = np.triu_indices(8, 1)
    ours, theirs = np.abs(R[iu]), PUBLISHED[iu]
    return {"pattern": float(np.corrcoef(ours, theirs)[0, 1]),
            "mirror_min": float(min(abs(R[i, j]) for i, j in MIRRORS)),
            "a_row_min": float(np.abs(R[0, 1:]).min()),
            **{f"{POINTS[i]}-{POINTS[j]}": float(abs(R[i, j])) for i, j in MIRRORS}}


def objective(fig: dict[str, float]) -> float:
    return (-fig["pattern"] + 3.0 * max(0.0, 0.6 - fig["mirror_min"])
            + 3.0 * max(0.0, 0.9 - fig["a_row_min"]))


def scaled(win: Windows, direction: np.ndarray) -> np.ndarray:
    """Gradient coefficients along ``direction`` scaled so the raw STD is the paper's."""
    d = np.maximum(direction, 0.0)
    d = d / max(float(np.sum(d)), 1e-300) * 0.03      # a typical total [°/h/K], then scaled
    lo, hi = 0.0, 1.0
    while np.std(win.bias(hi * d), ddof=1) < RAW_STD and hi < 1e3:
        hi *= 2.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.std(win.bias(mid * d), ddof=1) < RAW_STD else (lo, mid)
    return 0.5 * (lo + hi) * d


def best_law(win: Windows, start: np.ndarray) -> tuple[np.ndarray, float]:
    """Direction of the four gradient coefficients that best matches Table 3 (Nelder-Mead on
    their logarithms), scaled to the raw STD."""
    from scipy.optimize import minimize

    def f(z):
        return objective(figures(win.table3(scaled(win, np.exp(z)))))
    res = minimize(f, np.log(np.maximum(start, 1e-5)), method="Nelder-Mead",
                   options={"maxfev": 200, "xatol": 0.05, "fatol": 1e-4})
    return scaled(win, np.exp(res.x)), float(res.fun)


def report(params: dict[str, float], win: Windows, coef: np.ndarray) -> None:
    R = win.table3(coef)
    fig = figures(R)
    print("parameters: " + ", ".join(f"{k} = {v:.4g}" for k, v in params.items()))
    print("bias gradients [°/h/K]: " + ", ".join(f"A-{x} {c:.4g}"
                                                 for x, c in zip(GRADIENTS, coef)))
    print(f"Table 3: pattern r = {fig['pattern']:.3f}; mirror pairs B-C {fig['B-C']:.3f}, "
          f"D-E {fig['D-E']:.3f}, F-H {fig['F-H']:.3f}; A row min {fig['a_row_min']:.3f}; "
          f"raw STD {np.std(win.bias(coef), ddof=1):.4f} °/h")
    for i in range(8):
        print(f"  {POINTS[i]} " + " ".join("   -      " if i == j else
                                          f"{abs(R[i, j]):.2f}/{PUBLISHED[i, j]:.2f}"
                                          for j in range(8)))
    print("  (ours/paper)")


def main(argv: list[str]) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fit", action="store_true", help="fit the parameters (Powell)")
    p.add_argument("--evals", type=int, default=120, help="thermal simulations of the fit")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--thermal", type=pathlib.Path, default=None,
                   help="a variant of the thermal preset (default: the shipped one)")
    p.add_argument("--device", type=pathlib.Path, default=None,
                   help="a variant of the device preset (default: the shipped one)")
    p.add_argument("--scenario", type=pathlib.Path, default=None,
                   help="the run to simulate (default: the study's train run)")
    p.add_argument("--law", action="store_true",
                   help="also refit the bias-law gradient directions for the given parameters")
    args = p.parse_args(argv)
    global THERMAL, DEVICE, SCENARIO
    THERMAL = args.thermal or THERMAL
    DEVICE = args.device or DEVICE
    SCENARIO = args.scenario or SCENARIO
    from _machine import machine
    print(f"machine: {machine()}")
    params = current()
    for kv in args.set:
        k, v = kv.split("=")
        if k not in PARAMS:
            raise SystemExit(f"unknown parameter {k}; one of {', '.join(PARAMS)}")
        params[k] = float(v)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = pathlib.Path(tmpdir)
        win = Windows(*simulate(params, tmp))
        coef = win.coef
        if args.law or args.fit:
            coef, _ = best_law(win, coef)
        if args.fit:
            from scipy.optimize import minimize
            names = list(params)
            lo = np.array([PARAMS[n][2] for n in names])
            hi = np.array([PARAMS[n][3] for n in names])
            state = {"coef": coef, "best": (np.inf, dict(params), coef), "n": 0}

            def f(u):
                x = lo + (hi - lo) * np.clip(u, 0.0, 1.0)
                pr = dict(zip(names, x))
                w = Windows(*simulate(pr, tmp))
                c, val = best_law(w, state["coef"])
                val += 10.0 * float(np.sum(np.clip(u, None, 0.0) ** 2
                                           + np.clip(u - 1.0, 0.0, None) ** 2))
                state["n"] += 1
                if val < state["best"][0]:
                    state["best"] = (val, pr, c)
                    state["coef"] = c
                    print(f"[{state['n']}] {val:+.4f} "
                          + ", ".join(f"{k}={v:.3g}" for k, v in pr.items()), flush=True)
                return val
            u0 = np.array([(params[n] - PARAMS[n][2]) / (PARAMS[n][3] - PARAMS[n][2])
                           for n in names])
            minimize(f, u0, method="Powell",
                     options={"maxfev": args.evals, "xtol": 0.02, "ftol": 1e-3})
            _, params, coef = state["best"]
            win = Windows(*simulate(params, tmp))
        report(params, win, coef)
    print(f"wall time {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
