"""Part C of ``benchmarks/bench_identify.py`` (``--hop-seeds N``): false mode hops of the law
fit on hop-free recordings (kept apart so that bench_identify.py stays one readable file)."""

from __future__ import annotations

import pathlib

import numpy as np

import identify_truth as IT


def hop_false_alarms(seeds: int, work: pathlib.Path) -> None:
    """Hop-free recordings (4.9 h, rlg_single, no anomalies) through the law fit on the true
    network's temperatures: how many get a (false) mode hop — a c1 law with trplg_001's noise,
    and trplg_001's own law (knee, rate, UHFO)."""
    import tomllib
    from rlgsim.sim import presets
    from rlgsim.lab.identify.law_fit import fit_laws
    from rlgsim.lab.identify.recording_data import read_recording
    from rlgsim.lab.identify.thermal_fit import build, twin_response
    dev_t = presets.load_device_file("trplg_001").data
    print(f"\nC. false mode hops on hop-free recordings, {seeds} seeds per law (family level "
          f"≤ 1 % per recording)")
    for kind in ("c1 law, trplg_001 noise", "trplg_001 law"):
        false, zmax = 0, []
        for seed in range(seeds):
            f = work / f"fa_{kind[:2]}_{seed}"
            f.mkdir()
            th = IT.thermal_truth(f, {})
            bias = ({"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01,
                     "c1_deg_per_h_per_k": 3e-4} if kind.startswith("c1") else None)
            d = (IT.device_truth(f, th, bias=bias, keep_uhfo=False, noise=dict(dev_t["noise"]))
                 if bias else IT.device_truth(f, th))
            rec = read_recording(IT.simulate(IT.scenario(f, d, seed=100 + seed), f / "r.h5"))
            net, probes = build(presets.load_thermal_file(str(f / "truth_thermal.toml")).data)
            nodes, _ = twin_response(net, probes, rec.air_c, rec.power, rec.step_s)
            hf = fit_laws(rec, nodes, net.node_names, tomllib.loads(d.read_text())).hops
            false += bool(hf.hops)
            zmax.append(hf.scan_max_z)
        print(f"   {kind}: {false} of {seeds} recordings with a false hop; largest |z| of the "
              f"last scan median {np.median(zmax):.2f}, max {max(zmax):.2f} (threshold "
              f"{hf.threshold_z:.2f})")
