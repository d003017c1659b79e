"""Parts D and E of ``benchmarks/bench_identify.py`` (issue 28), kept apart so that
bench_identify.py stays one readable file.

D (``--hop-units N``): drawn units with mode hops — an rlg_single unit with trplg_001's noise, a
c1 law and a mode-hop model (κ 0.05/K, R 1.5, T_ref 22 °C, Δb 0.04 °/h; Monte Carlo spreads
κ ±10 %, Δb ±20 % and the lock phase per unit, so every unit hops at its own temperatures),
Monte Carlo units 1…N (the thermal network drawn too) through the 4.9 h programme, identified;
the hops found against the truth record: count, times, and the twin's T_c at each found hop
against the true T_c (the mean of the hop nodes' true temperatures) at the matched true hop.

E (``--next-units N``): the next experiment on drawn units — units as in part A of the
coverage (six multipliers log-normal 10 %, the c1/rate/gradient law) identified with
``suggest_programme``; the suggested programme run on each twin and identified again; per
target term the full law's standard error now, predicted and on the run.
"""

from __future__ import annotations

import copy
import dataclasses
import pathlib
import time
import tomllib

import numpy as np

import identify_truth as IT

HOP = {"nodes": ["A", "B", "C"], "modes_per_k": 0.05, "range_modes": 1.5, "reference_c": 22.0,
       "bias_step_deg_per_h": 0.04, "modes_per_k_rel": 0.1, "bias_step_rel": 0.2,
       "phase_per_unit": True}
#: a found hop matches a true one within two 100 s windows
MATCH_S = 200.0


def _true_hops(path, nodes: list[str]) -> list[tuple[float, int, float, float]]:
    """(time, direction, size, true T_c) of the truth record's mode hops."""
    import rlgsim
    with rlgsim.open_tree(str(path), load=True) as tr:
        if "anomalies" not in tr.children:
            return []
        a = tr["anomalies"]
        kind = np.asarray(a["kind"].values).astype(str)
        sel = np.char.startswith(kind, "mode_hop")
        th = tr["thermal"]
        names = [str(n) for n in th["node"].values]
        T = np.asarray(th["node_temperature"].values)
        t = np.asarray(th["time"].values, dtype=float)
    cols = [names.index(n) if n in names else names.index(f"g.{n}") for n in nodes]
    tc = T[:, cols].mean(axis=1)
    return [(float(ti), 1 if k.endswith("up") else -1, float(s), float(np.interp(ti, t, tc)))
            for ti, k, s in zip(np.asarray(a["time"].values)[sel], kind[sel],
                                np.asarray(a["size"].values)[sel])]


def hop_drawn_units(n_units: int, work: pathlib.Path) -> None:
    """Part D (module docstring)."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify import identify
    from rlgsim.lab.identify.preset_text import dumps
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    f = work / "hopdrawn"
    f.mkdir()
    th = IT.thermal_truth(f, {})
    dev_t = presets.load_device_file("trplg_001").data
    bias = {"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 3e-4}
    d = IT.device_truth(f, th, bias=bias, keep_uhfo=False, noise=dict(dev_t["noise"]))
    data = tomllib.loads(d.read_text())
    data["anomalies"] = {"mode_hop": copy.deepcopy(HOP)}
    d.write_text(dumps(data))
    sp = IT.scenario(f, d, seed=3)
    print(f"\nD. mode hops on {n_units} drawn units (rlg_single, c1 law, trplg_001 noise, "
          f"κ 0.05/K ± 10 %, R 1.5, Δb 0.04 °/h ± 20 %, lock phase per unit; 4.9 h); a found "
          f"hop matches a true one within {MATCH_S:.0f} s")
    n_true = n_found = n_match = 0
    dT = []
    for u in range(1, n_units + 1):
        s = dataclasses.replace(load_scenario(str(sp)), unit=u)
        out = simulate(s, str(f / f"u{u}.h5"), progress=False)
        true = _true_hops(out, HOP["nodes"])
        t0 = time.perf_counter()
        hops = identify(out, f / f"twin{u}").laws.hops.hops
        secs = time.perf_counter() - t0
        matched = []
        for h in hops:
            near = [x for x in true if abs(x[0] - h.time_s) <= MATCH_S and x[1] == h.direction]
            if near:
                x = min(near, key=lambda x: abs(x[0] - h.time_s))
                matched.append(x)
                dT.append(h.temperature_c - x[3])
        n_true, n_found, n_match = n_true + len(true), n_found + len(hops), n_match + len(matched)
        print(f"   unit {u}: true " + ("; ".join(
            f"{t / 3600:.2f} h {'up' if d > 0 else 'down'} {s:+.4f} °/h at T_c {T:.2f} °C"
            for t, d, s, T in true) or "none") + "\n           found " + ("; ".join(
            f"{h.time_s / 3600:.2f} h {'up' if h.direction > 0 else 'down'} "
            f"{h.size_deg_per_h:+.4f}±{h.size_se_deg_per_h:.4f} °/h at T_c {h.temperature_c:.2f}"
            f"±{h.temperature_se_c:.2f} °C" for h in hops) or "none")
            + f" ({len(matched)} matched; identified in {secs:.1f} s)")
    dT = np.abs(np.array(dT))
    print(f"   total: {n_true} true hops, {n_found} found, {n_match} matched; |T_c found − T_c "
          f"true| at the matched hops: " + (f"median {np.median(dT):.2f} K, largest "
                                             f"{dT.max():.2f} K" if dT.size else "-"))


def next_units(n_units: int, work: pathlib.Path) -> None:
    """Part E (module docstring)."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify import identify
    from rlgsim.lab.identify.next_experiment import recorded_se
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    bias = {"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 3e-4,
            "rate_deg_per_h_per_c_per_min": -0.01, "langmuir_deg_per_h_per_ma": 0.0,
            "gradients": [{"a": "A", "b": "G", "coeff_deg_per_h_per_k": 0.008}]}
    dev_t = presets.load_device_file("trplg_001").data
    rng = np.random.default_rng(2828)
    print(f"\nE. the next experiment on {n_units} drawn units (rlg_single multipliers ± 10 %, "
          f"c1/rate/gradient A−G law, trplg_001 noise, 4.9 h): the full law's standard error "
          f"now → predicted → on the suggested programme run on the twin")
    ratios, pred_ok = [], []
    for u in range(n_units):
        f = work / f"next{u}"
        f.mkdir()
        mult = {k: float(np.exp(0.1 * rng.standard_normal())) for k in IT.IDENTIFIABLE}
        d = IT.device_truth(f, IT.thermal_truth(f, mult), bias=bias, keep_uhfo=False,
                            noise=dict(dev_t["noise"]))
        rec = IT.simulate(IT.scenario(f, d, seed=700 + u), f / "r.h5")
        a = identify(rec, f / "a", suggest_programme=True)
        s = a.suggestion
        if s is None:
            print(f"   unit {u}: nothing to separate (no unseparable group)")
            continue
        simulate(load_scenario(str(a.next_path)), str(f / "next.h5"), progress=False)
        b = identify(f / "next.h5", f / "b")
        got = recorded_se(b.data, b.thermal.nodes_c, b.thermal.network.node_names,
                          tomllib.loads(d.read_text()), a.laws, b.laws.noise,
                          b.laws.bias.c_hat, list(s.se))
        parts = []
        for t in s.targets:
            now, pred = s.se[t]
            ratios.append(got[t] / now)
            pred_ok.append(got[t] / pred)
            parts.append(f"{t} {now:.3g} → {pred:.3g} → {got[t]:.3g}")
        print(f"   unit {u} ({s.duration_s / 3600:.1f} h programme): " + "; ".join(parts))
    if ratios:
        r, p = np.array(ratios), np.array(pred_ok)
        print(f"   {r.size} target standard errors: shrank in {int(np.sum(r < 1))} (on the run / "
              f"now: median {np.median(r):.2f}, largest {r.max():.2f}); on the run / predicted: "
              f"median {np.median(p):.2f}, range {p.min():.2f}–{p.max():.2f}")
