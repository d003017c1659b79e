"""Digital twin (issue 17): closed-loop figures of `rlgsim identify` against truth.

Part A — coverage: units whose thermal multipliers are drawn around the rlg_single template
(log-normal, 10 %) with a known bias law (c1, rate, gradient A-G) and trplg_001's noise are
simulated, identified, and |estimate − truth| / standard error is collected; printed: recovered
vs drawn multipliers and the fraction of |z| below 1 and 2 (nominal 68 % / 95 %) for the
thermal multipliers, the chosen law's coefficients, the model-averaged coefficients (selection
uncertainty included) and the law's prediction on another programme (its own twin's thermal
state there against the unit's true law), with the term groups reported as unseparable. Each
unit's programmes are shifted by its own uniform draw below the probes' resolution (a chamber
set-point error; ``--fixed-setpoints``: none), so that the units draw where their probes sit on
the quantisation grid, as the multipliers' standard errors assume; the last lines are issue 28's
table, each row beside its target (1σ 68 ± 6 %, 2σ 95 ± 3 %) with a verdict.

Part B — closed loop on two presets (trplg_001, rlg8_003): Monte Carlo units (unit ≥ 1: the
thermal network and every law coefficient drawn from the presets' tolerances, i.e. a unit *not*
in the twin's family of group multipliers) are simulated through a 20 h programme at 1 Hz
(probes and gyro), identified (timed, target ≤ 60 s on 2 cores: median, spread, a verdict only
with ≥ 5 units and the others' load ≤ 1.5), then the twin and the
original unit are both simulated through a *different* programme (10 h): probe RMS difference,
bias-law RMS difference (true law of each less its UHFO discharge wander's share — a random
process every run draws anew — 100 s windows; beside it the figure with the wander and the
difference split by term group, :func:`law_decomposition`), raw 100 s bias stability ratio twin /
original; the noise fit against the unit's drawn ARW and bias instability; and one compensator study (LS cubic in T, LS linear in all probes, stepwise, LSSVM;
trained on the 20 h run, scored on the 10 h run against each run's true bias) on the twin and on
the original: the Spearman rank correlation of the two rankings.

Part C (optional, ``--sf-units N``) — scale-factor coverage: Monte Carlo units of rlg8_003
(every coefficient drawn from the preset's tolerances, the scale factor's ``value_ppm`` ± 5 ppm
and ``c1_ppm_per_k`` ± 0.1 ppm/K among them) on a turntable that rests 456 s then turns ten
times at +50 °/s and ten at −50 °/s about the gyro axis every 10 min, through a 4 h chamber
programme (50 → −10 → 20 °C) at 2 Hz, identified with the preset as template: the fraction of
|z| below 1 and 2 for the scale-factor law's value and chosen coefficients against the drawn
truth (c2 against 0), with the binomial standard error.

Parts D (``--hop-units N``: drawn units with mode hops, found against the truth record) and E
(``--next-units N``: the suggested next experiment run on each twin and identified again) are in
``benchmarks/identify_drawn.py``; ``--rate-hz`` sets the gyro rate of the timing run (issue 28's
target: a 20 h recording at 100 Hz in ≤ 10 s, printed beside it with the figure before the
compiled Jacobian; ``--timing-runs N`` identifies its recording N times: median and spread).

The issue 28 speed figure alone::

    python benchmarks/bench_identify.py --coverage-units 0 --presets --rate-hz 100 --timing-runs 3

    python benchmarks/bench_identify.py [--units 2] [--coverage-units 10]
                                        [--presets trplg_001 rlg8_003] [--no-10hz]
                                        [--jobs 1] [--sf-units 0] [--fixed-setpoints]
                                        [--rate-hz 10] [--timing-runs 1]

Why this file is long: parts A–C share one set-up (programmes, the drawn units' scenarios, the
window bias and the coverage counting) and one report of bounds; parts D and E, which need
only the twin, already live in ``benchmarks/identify_drawn.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import pathlib
import statistics
import sys
import tempfile
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

import identify_truth as IT                     # noqa: E402
from _machine import LoadWatch, load_text, machine, spread  # noqa: E402
from _twin_law_terms import (_centred_rms, law_decomposition, law_terms,  # noqa: E402
                             window_bias)

PROGRAMME_20H = [{"type": "hold", "duration_h": 1}, {"type": "ramp", "to_c": -20.0,
                 "rate_c_per_min": 1.0}, {"type": "hold", "duration_h": 3},
                 {"type": "ramp", "to_c": 60.0, "rate_c_per_min": 1.0},
                 {"type": "hold", "duration_h": 3}, {"type": "ramp", "to_c": 0.0,
                 "rate_c_per_min": 0.5}, {"type": "hold", "duration_h": 2},
                 {"type": "ramp", "to_c": 40.0, "rate_c_per_min": 2.0},
                 {"type": "hold", "duration_h": 2}, {"type": "ramp", "to_c": 25.0,
                 "rate_c_per_min": 1.0}, {"type": "hold", "duration_min": 263}]
PROGRAMME_10H = [{"type": "hold", "duration_h": 1}, {"type": "ramp", "to_c": 50.0,
                 "rate_c_per_min": 0.7}, {"type": "hold", "duration_h": 2.5},
                 {"type": "ramp", "to_c": -10.0, "rate_c_per_min": 1.5},
                 {"type": "hold", "duration_h": 3}, {"type": "ramp", "to_c": 30.0,
                 "rate_c_per_min": 1.0}, {"type": "hold", "duration_min": 67}]
BIAS = {"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 3e-4,
        "rate_deg_per_h_per_c_per_min": -0.01, "langmuir_deg_per_h_per_ma": 0.0,
        "gradients": [{"a": "A", "b": "G", "coeff_deg_per_h_per_k": 0.008}]}


TRUE_LAW = {"c1": 3e-4, "rate": -0.01, "gradient[A-G]": 0.008}
#: issue 28's coverage targets: the fraction inside the ±1σ (68.3 %) and ±2σ (95.4 %)
#: intervals, 68 ± 6 % and 95 ± 3 %, over at least 20 units
COVERAGE_TARGETS = ((0.68, 0.06), (0.95, 0.03))
COVERAGE_MIN_UNITS = 20


def coverage_verdict(f1: float, f2: float, n_units: int) -> str:
    """"met" or what is off (1σ / 2σ too narrow or too wide) against COVERAGE_TARGETS."""
    if n_units < COVERAGE_MIN_UNITS:
        return f"no verdict ({n_units} units < {COVERAGE_MIN_UNITS})"
    off = []
    for label, f, (target, tol) in zip(("1σ", "2σ"), (f1, f2), COVERAGE_TARGETS):
        if f < target - tol:
            off.append(f"{label} too narrow")
        elif f > target + tol:
            off.append(f"{label} too wide")
    return "met" if not off else ", ".join(off)


def _inside(per_unit: list[tuple[np.ndarray, np.ndarray]]) -> tuple:
    """Fractions inside the 1σ and 2σ intervals, pooled over the units ``[(inside 1σ, inside
    2σ) of each unit's estimates]``, and their standard errors with the unit as the cluster —
    a unit's estimates share its recording's errors (its probes' quantisation, its flicker), so
    they are not independent draws and a binomial error would understate the spread: the ratio
    estimator's ``√(U/(U−1)·Σ_u (a_u − f·n_u)²) / Σ_u n_u`` (Cochran, *Sampling Techniques*,
    1977, §6.4) with ``a_u`` inside of ``n_u`` estimates of unit u."""
    out = []
    for k in (0, 1):
        a = np.array([float(np.sum(p[k])) for p in per_unit])
        n = np.array([float(np.size(p[k])) for p in per_unit])
        f = float(a.sum() / n.sum()) if n.sum() else float("nan")
        u = int(np.sum(n > 0))
        e = (float(np.sqrt(u / (u - 1) * np.sum((a - f * n) ** 2)) / n.sum())
             if u > 1 else float("nan"))
        out += [f, e]
    return tuple(out)


def coverage_table(rows: list[tuple[str, int, tuple]], n_units: int) -> None:
    """Issue 28's table: each row's fractions inside ±1σ / ±2σ beside the target, a verdict."""
    (t1, d1), (t2, d2) = COVERAGE_TARGETS
    print(f"\n   coverage over {n_units} units (target: 1σ {t1:.0%} ± {d1:.0%}, 2σ {t2:.0%} ± "
          f"{d2:.0%}, over ≥ {COVERAGE_MIN_UNITS} units; ± the standard error with the unit as "
          f"the cluster; the verdict compares the fraction itself with the target band)")
    print(f"   {'':34s} {'n':>5s}  {'1σ':>10s}  {'2σ':>10s}  verdict")
    for name, n, (f1, e1, f2, e2) in rows:
        print(f"   {name:34s} {n:5d}  {f1:4.0%} ± {e1:3.0%}  {f2:4.0%} ± {e2:3.0%}  "
              f"{coverage_verdict(f1, f2, n_units)}")


def coverage_unit(task: tuple[int, dict, str]) -> dict:
    """Simulate, identify and score one coverage unit ``(u, drawn multipliers, folder)``."""
    from threadpoolctl import threadpool_limits
    from rlgsim.sim import presets
    from rlgsim.lab.identify.law_fit import bias_features, fit_laws
    from rlgsim.lab.identify.recording_data import read_recording
    from rlgsim.lab.identify.thermal_fit import build, fit_thermal, twin_response
    import rlgsim
    u, mult, path, *rest = task
    offset = rest[0] if rest else 0.0
    folder = pathlib.Path(path)
    folder.mkdir()
    template = presets.load_thermal_file("rlg_single").data
    dev_t = presets.load_device_file("trplg_001").data
    out = {k: [] for k in ("zt", "zt_bm", "zt_q", "rows", "z_avg", "z_comb", "zl",
                           "zl_exact", "it68", "it95")}
    true_law = TRUE_LAW
    with threadpool_limits(limits=1, user_api="blas"):
        dev = IT.device_truth(folder, IT.thermal_truth(folder, mult), bias=BIAS,
                              keep_uhfo=False, noise=dict(dev_t["noise"]))
        rec = read_recording(IT.simulate(IT.scenario(
            folder, dev, programme=shifted(IT.PROGRAMME_A, offset), start_c=20.0 + offset,
            seed=500 + u), folder / "r.h5"))
        fit = fit_thermal(template, rec.air_c, rec.power, rec.step_s, rec.probe_names,
                          rec.probes_c)
        for k in fit.multipliers:           # every fitted one (not drawn: truth 1)
            true = mult.get(k, 1.0)
            dz = math.log(fit.multipliers[k]) - math.log(true)
            out["zt"].append(dz / fit.rel_se[k])
            out["zt_bm"].append(dz / fit.fit.se[fit.fit.names.index(k)])
            out["zt_q"].append(dz / fit.se_quantised[k])
            out["it68"].append(abs(dz) / fit.interval_68[k])    # < 1: inside its interval
            out["it95"].append(abs(dz) / fit.interval_95[k])
            out["rows"].append((u, k, true, fit.multipliers[k],
                                fit.rel_se[k] * fit.multipliers[k]))
        dev_law = {**dev_t, "gyro": {**dev_t["gyro"], "bias": BIAS}}
        t0 = time.perf_counter()
        laws = fit_laws(rec, fit.nodes_c, fit.network.node_names, dev_law)
        out["t_sel"] = time.perf_counter() - t0
        out["chosen"] = tuple(laws.bias.terms)
        sel = laws.bias
        out["groups"] = "; ".join(" ~ ".join(g) for g, _ in sel.unseparable) or "-"
        for term, true in true_law.items():          # model-averaged: every unit, every term
            out["z_avg"].append((sel.averaged[term][0] - true) / sel.averaged[term][1])
        for group, (lead, value, se_c, slopes) in sel.combined.items():
            true_c = sum(true_law.get(g, 0.0) * slopes[g] for g in group)
            out["z_comb"].append((value - true_c) / se_c)
        out["outl"] = len(laws.outlier_windows_s)
        # the law's prediction (with selection uncertainty) on a programme it was not
        # identified from, against the true law of the same unit there
        rec_b = read_recording(IT.simulate(IT.scenario(folder, dev,
                                                       programme=shifted(IT.PROGRAMME_B, offset),
                                                       start_c=20.0 + offset, seed=900 + u,
                                                       name="held_out"),
                                           folder / "b.h5"))
        nodes_b, _ = twin_response(fit.network, fit.probes, rec_b.air_c, rec_b.power,
                                   rec_b.step_s)
        pred, pse = sel.predict(bias_features(rec_b, nodes_b, fit.network.node_names,
                                              dev_law, laws))
        w = rlgsim.window_table(str(folder / "b.h5"))
        truth = np.asarray(w["true_bias_deg_per_h"] - w["true_random_deg_per_h"])
        truth = truth[np.searchsorted(np.asarray(w["time_s"]),
                                      np.asarray(rec_b.windows["time_s"]))]
        out["z_pred"] = (pred - truth) / pse
        err = pred - truth
        out["split"] = (float(np.mean(err) / np.median(pse)),
                        float(np.std(err) / np.median(pse)))
        # the same law fed the unit's true thermal state there: the law's own uncertainty
        true_net, true_probes = build(presets.load_thermal_file(
            str(folder / "truth_thermal.toml")).data)
        nodes_t, _ = twin_response(true_net, true_probes, rec_b.air_c, rec_b.power,
                                   rec_b.step_s)
        pred_t, pse_t = sel.predict(bias_features(rec_b, nodes_t, true_net.node_names,
                                                  dev_law, laws))
        out["z_pred_true"] = (pred_t - truth) / pse_t
        for term, true in true_law.items():
            if term in laws.bias.terms:
                z = (laws.bias.value(term) - true) / laws.bias.se(term)
                out["zl"].append(z)
                if set(laws.bias.terms) == set(true_law):
                    out["zl_exact"].append(z)
    return out


def shifted(programme: list[dict], offset_c: float) -> list[dict]:
    """A chamber programme with every set-point ``offset_c`` higher."""
    return [dict(seg, to_c=seg["to_c"] + offset_c) if "to_c" in seg else dict(seg)
            for seg in programme]


def coverage(n_units: int, work: pathlib.Path, jobs: int = 1, setpoint_offsets: bool = True
             ) -> None:
    """Part A over ``n_units`` units (``jobs`` processes; the draws and the printed figures do
    not depend on it). ``setpoint_offsets``: each unit's programmes shifted by its own uniform
    draw in [0, the probes' resolution) — a chamber's air is never exactly at a round set-point,
    and without the draw every unit's probes that soak at the air temperature sit at the same
    place on the quantisation grid, share one quantisation error and make the units one draw of
    it, while the multipliers' standard errors describe the spread over grid positions."""
    from rlgsim.sim import presets
    rng = np.random.default_rng(2017)
    tasks = [(u, {k: float(np.exp(0.1 * rng.standard_normal())) for k in IT.IDENTIFIABLE},
              str(work / f"cov{u}")) for u in range(n_units)]
    q = float(presets.load_thermal_file("rlg_single").data["probes"]["defaults"]["resolution_c"])
    offsets = np.random.default_rng(2018).uniform(0.0, q, n_units) if setpoint_offsets \
        else np.zeros(n_units)
    tasks = [(*t, float(o)) for t, o in zip(tasks, offsets)]
    if jobs > 1:
        import multiprocessing
        with multiprocessing.get_context("spawn").Pool(jobs) as pool:
            units = pool.map(coverage_unit, tasks, chunksize=1)
    else:
        units = [coverage_unit(t) for t in tasks]

    def cat(key):
        return [v for r in units for v in r[key]]
    zt, zt_bm, zt_q, rows = cat("zt"), cat("zt_bm"), cat("zt_q"), cat("rows")
    z_avg, z_comb, zl, zl_exact = cat("z_avg"), cat("z_comb"), cat("zl"), cat("zl_exact")
    chosen = [r["chosen"] for r in units]
    groups = [r["groups"] for r in units]
    outl = [r["outl"] for r in units]
    t_sel = [r["t_sel"] for r in units]
    z_pred = [r["z_pred"] for r in units]
    z_pred_true = [r["z_pred_true"] for r in units]
    split = [r["split"] for r in units]
    print(f"\nA. coverage over {n_units} units (rlg_single, 3.8 h programme, trplg_001 noise; "
          + (f"set-points shifted per unit by U[0, {q:g} °C)" if setpoint_offsets
             else "set-points as written") + ")")
    print("   unit  multiplier                        drawn   recovered  std.err")
    for u, k, true, est, se in rows:
        print(f"   {u:4d}  {k:32s} {true:7.4f}  {est:9.4f}  {se:7.4f}")
    exact = sum(set(c) == {"c1", "rate", "gradient[A-G]"} for c in chosen)
    print(f"   bias-law terms chosen: {'; '.join(', '.join(c) for c in chosen)}")
    print(f"   the true terms (c1, rate, gradient[A-G]) exactly: {exact} of {n_units} units")
    print(f"   unseparable term groups reported per unit: {' | '.join(groups)}")
    print(f"   windows left out as outliers per unit: {outl}")
    print(f"   law fit (selection + model averaging) per unit: "
          f"{np.median(t_sel):.2f} s median, {max(t_sel):.2f} s max")
    zp = np.concatenate(z_pred)
    per_unit = [float(np.sqrt(np.mean(z ** 2))) for z in z_pred]
    print("   (±: binomial standard error of a fraction, √(p(1−p)/n), for independent "
          "estimates; the prediction's windows are correlated within a unit, so its ± is "
          "the spread of the per-unit fractions / √units instead)")
    for name, z in (("thermal multipliers (reported: the larger standard error)", zt),
                    ("  the same with the batch-means sandwich alone", zt_bm),
                    ("  the same with the probes' error model alone", zt_q),
                    ("bias-law coefficients of the chosen law (its own standard errors)", zl),
                    ("the same when the true terms were chosen", zl_exact),
                    ("bias-law coefficients model-averaged (selection in the standard errors; "
                     "c1, rate, gradient[A-G] of every unit)", z_avg),
                    ("combined effect of each unseparable group (truth: Σ true coefficient × "
                     "slope on the lead)", z_comb),
                    (f"law prediction on another programme, per 100 s window ({zp.size} "
                     f"windows; windows of a unit are correlated)", zp),
                    ("the same with the unit's true thermal state on that programme (the law's "
                     "own uncertainty alone)", np.concatenate(z_pred_true))):
        if not len(z):
            print(f"   {name}: none")
            continue
        z = np.abs(z)
        if len(z) == zp.size and name.startswith(("law prediction", "the same with")):
            parts = z_pred if name.startswith("law") else z_pred_true
            pu = [np.abs(q) for q in parts]
            e1 = np.std([np.mean(q < 1) for q in pu], ddof=1) / np.sqrt(len(pu))
            e2 = np.std([np.mean(q < 2) for q in pu], ddof=1) / np.sqrt(len(pu))
        else:
            e1 = np.sqrt(np.mean(z < 1) * (1 - np.mean(z < 1)) / len(z))
            e2 = np.sqrt(np.mean(z < 2) * (1 - np.mean(z < 2)) / len(z))
        print(f"   {name}: {len(z)} estimates, |z| < 1: {np.mean(z < 1):.0%} ± {e1:.0%} "
              f"(nominal 68 %), |z| < 2: {np.mean(z < 2):.0%} ± {e2:.0%} (nominal 95 %), "
              f"largest |z| {z.max():.2f}")
    it68, it95 = np.asarray(cat("it68")), np.asarray(cat("it95"))
    print(f"   thermal multipliers inside their reported 68.3 % / 95.4 % intervals (the wider of "
          f"the sandwich's ±1, ±2 standard errors and the probes' error model's percentile "
          f"interval): {np.mean(it68 < 1):.0%} / {np.mean(it95 < 1):.0%}")
    def inside_by_unit(key):
        return [(np.abs(np.asarray(r[key])) < 1, np.abs(np.asarray(r[key])) < 2) for r in units]
    coverage_table([("law coefficients (model-averaged)", len(z_avg),
                     _inside(inside_by_unit("z_avg"))),
                    ("thermal multipliers", it68.size,
                     _inside([(np.asarray(r["it68"]) < 1, np.asarray(r["it95"]) < 1)
                              for r in units])),
                    ("predictions on another programme", zp.size,
                     _inside(inside_by_unit("z_pred"))),
                    ("combined effects", len(z_comb), _inside(inside_by_unit("z_comb")))],
                   n_units)
    print(f"   law prediction on another programme: RMS of z per unit "
          f"{', '.join(f'{v:.2f}' for v in per_unit)} (nominal 1); with the true thermal "
          f"state {', '.join(f'{np.sqrt(np.mean(z ** 2)):.2f}' for z in z_pred_true)}")
    print("   prediction error per unit, mean / standard deviation over the windows, in units of "
          "the median standard error: " + ", ".join(f"{a:+.2f}/{b:.2f}" for a, b in split))


PROGRAMME_SF = [{"type": "hold", "duration_min": 20}, {"type": "ramp", "to_c": 50.0,
                 "rate_c_per_min": 1.0}, {"type": "hold", "duration_min": 40},
                {"type": "ramp", "to_c": -10.0, "rate_c_per_min": 1.0},
                {"type": "hold", "duration_min": 40}, {"type": "ramp", "to_c": 20.0,
                 "rate_c_per_min": 1.0}, {"type": "hold", "duration_min": 20}]
TABLE_SF = {"program": "custom", "continuous": True,
            "motions": [{"type": "hold", "duration_s": 456.0},
                        {"type": "continuous", "axis": "inner", "rate_deg_s": 50.0,
                         "duration_s": 72.0},
                        {"type": "continuous", "axis": "inner", "rate_deg_s": -50.0,
                         "duration_s": 72.0}]}


def sf_coverage(n_units: int, work: pathlib.Path, preset: str = "rlg8_003") -> None:
    """Part C: scale-factor coverage over ``n_units`` drawn units of ``preset``."""
    import h5py
    import rlgsim
    from rlgsim.lab.identify.preset_text import dumps
    z, z_avg, rows, secs = [], [], [], []
    for u in range(1, n_units + 1):
        folder = work / f"sf{u}"
        folder.mkdir()
        sc = {"name": f"sf{u}", "description": "scale-factor coverage unit", "device": preset,
              "seed": u, "device_seed": u,
              "acquisition": {"sample_rate_hz": 2.0, "thermal_step_s": 1.0},
              "power": {"on_at_s": 0.0},
              "chamber": {"start_c": 20.0, "segments": PROGRAMME_SF}, "turntable": TABLE_SF}
        path = folder / f"sf{u}.toml"
        path.write_text(dumps(sc), encoding="utf-8")
        rec = IT.simulate(path, folder / "rec.h5")
        with h5py.File(rec, "r") as h:
            names = [n.decode() if isinstance(n, bytes) else str(n)
                     for n in h["truth/coefficient"][()]]
            truth = dict(zip(names, map(float, h["truth/coefficient_value"][()])))
        t0 = time.perf_counter()
        r = rlgsim.identify(rec, folder / "twin")
        secs.append(time.perf_counter() - t0)
        sf = r.scale_factor
        if sf is None or not sf.identified:
            rows.append((u, "refused: " + (sf.lines[0] if sf else "no motion")))
            continue
        got = []
        for key, c in (("value_ppm", "value"), ("c1_ppm_per_k", "c1"), ("c2_ppm_per_k2", "c2")):
            true = truth[f"gyro.scale_factor.{c}[z]"]
            if key in sf.values:
                v, se = sf.values[key]
                z.append((v - true) / se)
                got.append(f"{c} {v:.4g} ± {se:.2g} (drawn {true:.4g}, z {(v - true) / se:+.2f})")
            v, se, _ = sf.law.averaged["intercept" if c == "value" else c]
            z_avg.append((v - true) / se)
        rows.append((u, "; ".join(got)))
    print(f"\nC. scale-factor coverage over {n_units} drawn {preset} units (±50 °/s every "
          f"10 min, 4 h at 2 Hz)")
    for u, text in rows:
        print(f"   unit {u}: {text}")
    for what, zz in (("value and chosen coefficients of the written law", z),
                     ("value, c1, c2 model-averaged (selection in the standard errors; a term "
                      "out of a subset counts 0)", z_avg)):
        if not zz:
            continue
        a = np.abs(np.array(zz))
        p1, p2 = np.mean(a < 1), np.mean(a < 2)
        e1, e2 = np.sqrt(p1 * (1 - p1) / a.size), np.sqrt(p2 * (1 - p2) / a.size)
        print(f"   {what}: {a.size} estimates (correlated within a unit), |z| < 1: {p1:.0%} "
              f"± {e1:.0%} (nominal 68 %), |z| < 2: {p2:.0%} ± {e2:.0%} (nominal 95 %), "
              f"largest |z| {a.max():.2f}")
    print(f"   identification per unit: {np.median(secs):.1f} s median; load average now "
          f"{os.getloadavg()[0]:.1f}")


#: the closed loop's bounds (judgement: a twin whose probes stray by more than half a kelvin, whose
#: law differs by half the law's own RMS, whose raw stability is off by a factor 1.5 or which
#: reorders the compensators is not a twin of the unit)
BOUNDS = {"probe_rms_c": 0.5, "law_rms_fraction": 0.5, "stability_ratio": (1 / 1.5, 1.5),
          "spearman": 0.8}


def _bound(value: float, lo: float | None, hi: float | None, what: str = "") -> str:
    """``[bound …: holds]`` or ``[bound …: EXCEEDED]``."""
    eps = 1e-9                     # a rank correlation of five items is a multiple of 0.1 (0.8
    ok = ((lo is None or value >= lo - eps)          # comes out as 0.7999…)
          and (hi is None or value <= hi + eps))
    rng = (f"{lo:.2f}–{hi:.2f}" if lo is not None and hi is not None else
           f"≤ {hi:g}" if hi is not None else f"≥ {lo:g}")
    return f"[bound {rng}{' ' + what if what else ''}: {'holds' if ok else 'EXCEEDED'}]"


def compensator_scores(train, test, probes: list[str], uhfo: bool) -> dict[str, float]:
    from rlgsim.estimators.lssvm import LSSVMRegressor
    from rlgsim.estimators.polynomial import PolynomialRegressor
    from rlgsim.estimators.stepwise import StepwiseRegressor
    a = probes[0]
    t_in = [f"probe_{a}_c"]
    all_in = [f"probe_{p}_c" for p in probes]
    sw_in = [f"probe_{a}_c", f"dTdt_{a}_k_per_s"] + (["uhfo_v"] if uhfo else all_in[1:4])
    models = {"LS cubic T": (PolynomialRegressor(degree=3), t_in),
              "LS linear, all probes": (PolynomialRegressor(degree=1), all_in),
              "stepwise": (StepwiseRegressor(), sw_in),
              "LSSVM": (LSSVMRegressor(gamma=100.0, sigma2=4.0), sw_in)}
    out = {}
    truth = np.asarray(test["true_bias_deg_per_h"])
    for name, (m, cols) in models.items():
        m.fit(train[cols], train["bias_deg_per_h"])
        pred = m.predict(test[cols])
        out[name] = float(np.sqrt(np.mean((pred - truth) ** 2)))
    out["raw"] = float(np.sqrt(np.mean((np.mean(np.asarray(train["bias_deg_per_h"]))
                                         - truth) ** 2)))
    return out


def _cpu() -> float:
    """CPU seconds of this process and its finished children (the thermal fit's batched
    Jacobian of a heater network runs in two worker processes)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def _simulate_unit(preset: str, unit: int, folder: pathlib.Path) -> None:
    """Drawn unit ``unit`` of ``preset`` through the identification (20 h) and the validation
    (10 h) programmes at 1 Hz: ``folder/{ident,valid}.toml`` and ``orig_{ident,valid}.h5``."""
    from rlgsim.lab.identify.preset_text import dumps
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    folder.mkdir()
    for prog, name in ((PROGRAMME_20H, "ident"), (PROGRAMME_10H, "valid")):
        sc = {"name": name, "description": "bench", "device": preset, "seed": 40 + unit,
              "device_seed": 4000, "acquisition": {"sample_rate_hz": 1.0,
                                                   "thermal_step_s": 1.0},
              "power": {"on_at_s": 0.0}, "chamber": {"start_c": 25.0 if name == "ident"
                                                     else 20.0, "segments": prog}}
        (folder / f"{name}.toml").write_text(dumps(sc))
        s = dataclasses.replace(load_scenario(str(folder / f"{name}.toml")), unit=unit)
        simulate(s, str(folder / f"orig_{name}.h5"), progress=False)


def closed_loop(preset: str, units: int, work: pathlib.Path, times: list[float],
                cpus: list[float]) -> None:
    import rlgsim
    from scipy.stats import spearmanr
    from rlgsim.lab.identify import identify
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    from rlgsim.sim import presets
    thermal_name = presets.load_device_file(preset).data["device"]["thermal_preset"]
    print(f"\nB. closed loop, {preset} (thermal template {thermal_name}), {units} drawn unit(s)")
    for unit in range(1, units + 1):
        folder = work / f"{preset}_{unit}"
        _simulate_unit(preset, unit, folder)
        t0, c0 = time.perf_counter(), _cpu()
        r = identify(folder / "orig_ident.h5", folder / "twin", name=f"{preset}_twin{unit}")
        dt, cpu = time.perf_counter() - t0, _cpu() - c0
        times.append(dt)
        cpus.append(cpu)
        # the twin through both programmes (unit 0: the twin is its own nominal design)
        for name in ("ident", "valid"):
            text = (folder / f"{name}.toml").read_text().replace(
                f'device = "{preset}"', f'device = "twin/device.toml"')
            (folder / f"twin_{name}.toml").write_text(text)
            simulate(load_scenario(str(folder / f"twin_{name}.toml")),
                     str(folder / f"twin_{name}.h5"), progress=False)
        to = rlgsim.open_tree(str(folder / "orig_valid.h5"), load=True)
        tt = rlgsim.open_tree(str(folder / "twin_valid.h5"), load=True)
        po = np.asarray(to["probes"]["temperature"].values)
        pt = np.asarray(tt["probes"]["temperature"].values)
        probe_rms = np.sqrt(np.mean((po - pt) ** 2, axis=0))
        names = [str(p) for p in to["probes"]["probe"].values]
        to.close()
        tt.close()
        law_w, raw_o, w_o = window_bias(folder / "orig_valid.h5")
        law_tw, raw_t, w_t = window_bias(folder / "twin_valid.h5")
        # like for like: the law without the UHFO wander's share (a random process each run
        # draws anew, as the gyro's own noise, which "true_random" already leaves out)
        parts_o = law_terms(folder / "orig_valid.h5")
        parts_t = law_terms(folder / "twin_valid.h5")
        law_o, law_t = law_w - parts_o["uhfo wander"], law_tw - parts_t["uhfo wander"]
        law_rms = _centred_rms(law_o, law_t)
        law_rms_w = _centred_rms(law_w, law_tw)
        ratio = float(np.std(raw_t, ddof=1) / np.std(raw_o, ddof=1))
        th = r.thermal
        print(f"   unit {unit}: identified in {dt:.1f} s wall, {cpu:.1f} s CPU (all processes; "
              f"target ≤ 60 s on 2 cores; load average {os.getloadavg()[0]:.1f}); fitted: " + ", ".join(
            f"{k} ×{v:.3f}±{th.rel_se[k] * v:.3f}" for k, v in th.multipliers.items()))
        print(f"     refused: {', '.join(th.refused) or 'none'}")
        print(f"     bias law terms: {', '.join(r.laws.bias.terms)}; noise ARW "
              f"{r.laws.noise.values['arw_deg_per_sqrt_h']:.2e} °/√h, BI "
              f"{r.laws.noise.values['bi_deg_per_h']:.2e} °/h")
        with rlgsim.open_tree(str(folder / "orig_ident.h5"), load=True) as tr:
            co = dict(zip(map(str, tr["truth"]["coefficient"].values),
                          tr["truth"]["coefficient_value"].values))
        drawn = {k.split(".")[2].split("[")[0]: float(v) for k, v in co.items()
                 if k.startswith("gyro.bias.")}
        pairs = []
        for term in r.laws.bias.terms:
            if term in drawn and drawn[term] != 0:
                pairs.append(f"{term} {r.laws.bias.value(term):.3g}±{r.laws.bias.se(term):.2g}"
                             f" (drawn {drawn[term]:.3g})")
        print(f"     law vs drawn: {'; '.join(pairs) or '-'}")
        nf, d_as = r.laws.noise, math.degrees(1.0) * 3600.0          # rad → arcsec
        true_noise = {"arw_deg_per_sqrt_h": co.get("noise.gyro_arw[z]", math.nan) * d_as / 60.0,
                      "bi_deg_per_h": co.get("noise.gyro_bi[z]", math.nan) * d_as}
        print("     noise vs drawn (95 % interval): " + "; ".join(
            f"{k} {nf.values[k]:.3g} [{nf.intervals[k][0]:.3g}, {nf.intervals[k][1]:.3g}] "
            f"(drawn {v:.3g}: {'inside' if nf.intervals[k][0] <= v <= nf.intervals[k][1] else 'OUTSIDE'})"
            for k, v in true_noise.items()) + f"; Q {nf.values['q_arcsec']:.3f} arcsec "
            f"({'fixed from the pulse weight' if nf.q_fixed else 'fitted'})")
        print(f"     other programme: probe RMS difference max {probe_rms.max():.3f} °C "
              f"({names[int(np.argmax(probe_rms))]}), mean {probe_rms.mean():.3f} °C "
              f"{_bound(probe_rms.max(), None, BOUNDS['probe_rms_c'])}; bias-law RMS difference "
              f"{law_rms:.4f} °/h (law RMS {np.std(law_o):.4f}) "
              f"{_bound(law_rms / np.std(law_o), None, BOUNDS['law_rms_fraction'], 'of the law RMS')}"
              f" (with each run's own UHFO wander in the law, as compared before: {law_rms_w:.4f} "
              f"°/h, law RMS {np.std(law_w):.4f}, {law_rms_w / np.std(law_w):.2f} of it)"
              f"; raw 100 s stability twin/original {ratio:.2f} "
              f"{_bound(ratio, *BOUNDS['stability_ratio'])}")
        print("     " + law_decomposition(parts_o, parts_t))
        probes = [p for p in names if p != "housing"]
        uh = "uhfo_v" in w_o.columns
        train_o, _, _ = window_bias(folder / "orig_ident.h5")
        s_o = compensator_scores(window_bias(folder / "orig_ident.h5")[2], w_o, probes, uh)
        s_t = compensator_scores(window_bias(folder / "twin_ident.h5")[2], w_t, probes, uh)
        keys = list(s_o)
        rho = spearmanr([s_o[k] for k in keys], [s_t[k] for k in keys]).statistic
        print("     compensators, RMSE vs truth on the other programme [°/h] original / twin: "
              + "; ".join(f"{k} {s_o[k]:.4f}/{s_t[k]:.4f}" for k in keys))
        print(f"     rank correlation (Spearman) of the rankings: {rho:.2f} "
              f"{_bound(rho, BOUNDS['spearman'], None)}")
        if "anomalies" in presets.load_device_file(preset).data:
            hop_lines(folder, r, law_o, raw_o, law_rms, ratio)


def hop_lines(folder: pathlib.Path, r, law_o, raw_o, law_rms: float, ratio: float) -> None:
    """Mode hops and read-out spikes found against the unit's true ones (the dataset's truth
    ``anomalies`` group — here only, never in identification), and the closed-loop figures of
    the identification with the hop handling switched off (as it was before it: no hop search,
    the template's ``[anomalies]`` kept) beside those with it."""
    import rlgsim
    from rlgsim.lab.identify import hop_fit as H
    from rlgsim.lab.identify import hop_mapping as HM
    from rlgsim.lab.identify import identify
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    with rlgsim.open_tree(str(folder / "orig_ident.h5"), load=True) as tr:
        a = tr["anomalies"] if "anomalies" in tr.children else None
        ev = ([] if a is None else list(zip(np.asarray(a["time"].values).tolist(),
                                            np.asarray(a["kind"].values).astype(str).tolist(),
                                            np.asarray(a["size"].values).tolist())))
    true_hops = [e for e in ev if e[1].startswith("mode_hop")]
    true_spikes = [e for e in ev if e[1] == "pulse_spike"]
    hf, sp = r.laws.hops, r.laws.spikes
    print("     mode hops, true (truth record): " + ("; ".join(
        f"{t / 3600:.2f} h {k.split('_')[-1]} {s:+.4f} °/h" for t, k, s in true_hops) or "none"))
    print("     mode hops, found: " + ("; ".join(
        f"{h.time_s / 3600:.2f} h {'up' if h.direction > 0 else 'down'} "
        f"{h.size_deg_per_h:+.4f}±{h.size_se_deg_per_h:.4f} °/h at T_c {h.temperature_c:.1f} °C"
        for h in hf.hops) or "none") + f" (blind threshold |z| {hf.threshold_z:.2f}; template "
          f"search best |z| / threshold: " + (", ".join(
              f"{abs(z):.2f}/{t:.2f}" for z, t, _ in hf.pattern[0]) if hf.pattern else "-")
          + ")")
    for note in hf.notes:
        print(f"       {note}")
    print(f"     read-out spikes: {len(true_spikes)} true "
          f"({', '.join(f'{s:+.0f}' for _, _, s in true_spikes)} pulses), {len(sp.sizes)} found "
          f"({', '.join(f'{s:+d}' for s in sp.sizes)}); twin rate {sp.rate_per_h:.3g}/h "
          f"[{sp.rate_ci95_per_h[0]:.3g}, {sp.rate_ci95_per_h[1]:.3g}]")
    saved = H.find_hops, HM.describe_hops, HM.anomalies_table
    H.find_hops = lambda y, cands, cov, sel, *a, **k: (sel, None, (), 0, None)
    HM.describe_hops = lambda *a, **k: (None, ())
    HM.anomalies_table = lambda template, hops, spikes: (template, {})
    try:
        identify(folder / "orig_ident.h5", folder / "twin_before", name="before")
    finally:
        H.find_hops, HM.describe_hops, HM.anomalies_table = saved
    text = (folder / "twin_valid.toml").read_text().replace("twin/device.toml",
                                                             "twin_before/device.toml")
    (folder / "before_valid.toml").write_text(text)
    simulate(load_scenario(str(folder / "before_valid.toml")), str(folder / "before_valid.h5"),
             progress=False)
    law_b, raw_b, _ = window_bias(folder / "before_valid.h5")
    law_b = law_b - law_terms(folder / "before_valid.h5")["uhfo wander"]
    rms_b = _centred_rms(law_o, law_b)
    ratio_b = float(np.std(raw_b, ddof=1) / np.std(raw_o, ddof=1))
    print(f"     without / with the hop handling: bias-law RMS difference {rms_b:.4f} / "
          f"{law_rms:.4f} °/h (law RMS {np.std(law_o):.4f}); raw 100 s stability twin/original "
          f"{ratio_b:.2f} / {ratio:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--units", type=int, default=2)
    ap.add_argument("--coverage-units", type=int, default=10)
    ap.add_argument("--presets", nargs="*", default=["trplg_001", "rlg8_003"],
                    help="closed-loop presets (none: coverage only)")
    ap.add_argument("--no-10hz", action="store_true", help="skip the 10 Hz timing")
    ap.add_argument("--jobs", type=int, default=1, help="processes for the coverage units")
    ap.add_argument("--fixed-setpoints", action="store_true",
                    help="coverage units at the programmes' own set-points (every unit's soaked "
                         "probes then share one place on the quantisation grid)")
    ap.add_argument("--hop-seeds", type=int, default=0,
                    help="hop-free recordings per law for the false mode-hop count")
    ap.add_argument("--hop-units", type=int, default=0, help="part D: drawn units with hops")
    ap.add_argument("--next-units", type=int, default=0, help="part E: the next experiment")
    ap.add_argument("--rate-hz", type=float, default=10.0, help="gyro rate of the timing run")
    ap.add_argument("--timing-runs", type=int, default=1,
                    help="identifications of the timing run's recording (median and spread)")
    ap.add_argument("--sf-units", type=int, default=0,
                    help="part C: scale-factor coverage over this many drawn rlg8_003 units")
    args = ap.parse_args()
    print("bench_identify:", machine())
    watch = LoadWatch()
    print(f"load average before: {load_text()}", flush=True)
    times: list[float] = []
    cpus: list[float] = []
    with tempfile.TemporaryDirectory(prefix="bench-identify-") as tmp:
        work = pathlib.Path(tmp)
        t0 = time.perf_counter()
        if args.coverage_units:
            coverage(args.coverage_units, work, args.jobs, not args.fixed_setpoints)
        if args.sf_units:
            sf_coverage(args.sf_units, work)
        for preset in args.presets:
            closed_loop(preset, args.units, work, times, cpus)
        if args.hop_seeds:
            from identify_hops import hop_false_alarms
            hop_false_alarms(args.hop_seeds, work)
        if args.hop_units or args.next_units:
            from identify_drawn import hop_drawn_units, next_units
            if args.hop_units:
                hop_drawn_units(args.hop_units, work)
            if args.next_units:
                next_units(args.next_units, work)
        if times:
            print(f"\none identification of a 20 h recording (1 Hz probes and gyro, 100 s "
                  f"windows): wall {spread(times, '.1f', ' s')}, CPU of all processes "
                  f"{spread(cpus, '.1f', ' s')} (target ≤ 60 s on 2 cores: "
                  f"{watch.verdict(statistics.median(times) <= 60.0, len(times))}; a heater "
                  f"network's Jacobian runs in two processes, so on an idle 2-core machine "
                  f"the wall time is about the CPU time less the parallel part's share)")
        if not args.no_10hz:
            from identify_timing import timing_line, timing_run
            walls, cpus_t = timing_run(work, PROGRAMME_20H, args.rate_hz, args.timing_runs)
            print(timing_line(args.rate_hz, walls, cpus_t, watch))
        print(f"total {time.perf_counter() - t0:.0f} s; {watch.line()}")


if __name__ == "__main__":
    main()
