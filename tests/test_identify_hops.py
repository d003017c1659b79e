"""Mode hops and read-out spikes in identification (src/rlgsim/lab/identify/hop_fit.py, spike_fit.py,
estimators/identify/step_detection.py; docs/identify.md "Mode hops").

The step scan's false-alarm level against many noise-only series drawn from the window-mean
covariance of white + flicker noise (the simulator's construction); recovery of injected steps
of known size; end to end: a simulated recording with a known hysteresis pair is identified
(times within two windows, sizes and the mapped simulator keys within their standard errors),
noise-only recordings over several seeds give no hop, and the twin's device.toml loads and
simulates.
"""

from __future__ import annotations

import copy
import pathlib
import tomllib

import numpy as np
import pytest

import identify_truth as IT
from rlgsim.estimators.identify.step_detection import detect_steps
from rlgsim.estimators.identify.window_noise import window_mean_covariance

# trplg_001's noise in the window-noise units: N = 60 × ARW [(°/h)√s], B [°/h]
N_W, B_F = 60 * 0.0008, 0.002
WINDOW = 100.0


def _noise_cov(n: int) -> np.ndarray:
    return window_mean_covariance(np.arange(n) * WINDOW, WINDOW, n=N_W, b=B_F,
                                  tau_min_s=2.0, tau_max_s=1e5, per_decade=2)


def _law(n: int) -> np.ndarray:
    x = np.linspace(-1.0, 1.0, n)
    return np.column_stack([np.ones(n), x, x ** 2])


def test_step_scan_false_alarms_over_many_seeds():
    """Noise only (white + flicker, no step) under the true covariance: the family level is
    α = 1 % per series (Bonferroni, conservative) — over 300 series at most 3 + 3·√3 false
    alarms would be plausible at the nominal level; none or very few is expected."""
    n = 200
    C = _noise_cov(n)
    L = np.linalg.cholesky(C)
    X = _law(n)
    rng = np.random.default_rng(17)
    alarms = 0
    for _ in range(300):
        y = X @ np.array([0.01, 0.003, -0.002]) + L @ rng.standard_normal(n)
        alarms += len(detect_steps(y, X, C, alpha=0.01).index) > 0
    assert alarms <= 3 + 3 * np.sqrt(3)


def test_step_scan_recovers_known_steps():
    """Two steps of about eight standard errors: found within two windows, sizes within three
    standard errors, on every one of 30 seeds."""
    n = 240
    C = _noise_cov(n)
    L = np.linalg.cholesky(C)
    X = _law(n)
    rng = np.random.default_rng(5)
    z_sizes = []
    for _ in range(30):
        y = X @ np.array([0.0, 0.002, 0.001]) + L @ rng.standard_normal(n)
        y[70:] += 0.025
        y[170:] -= 0.025
        fit = detect_steps(y, X, C, alpha=0.01)
        assert len(fit.index) == 2
        assert abs(fit.index[0] - 70) <= 2 and abs(fit.index[1] - 170) <= 2
        z_sizes += [(fit.size[0] - 0.025) / fit.se[0], (fit.size[1] + 0.025) / fit.se[1]]
    z = np.abs(np.array(z_sizes))
    assert z.max() < 4.0 and np.mean(z < 2) > 0.85


HOP = {"nodes": ["A", "B", "C"], "modes_per_k": 0.05, "range_modes": 1.5, "reference_c": 22.0,
       "bias_step_deg_per_h": 0.04}


def _recording(folder: pathlib.Path, seed: int, hop: dict | None) -> pathlib.Path:
    """A 4.9 h rlg_single recording (IT.PROGRAMME_A) with trplg_001's noise, a c1 law and
    optionally a mode-hop model (the block's A, B, C nodes)."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify.preset_text import dumps
    folder.mkdir(parents=True, exist_ok=True)
    th = IT.thermal_truth(folder, {})
    dev_t = presets.load_device_file("trplg_001").data
    bias = {"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 3e-4}
    d = IT.device_truth(folder, th, bias=bias, keep_uhfo=False, noise=dict(dev_t["noise"]))
    if hop is not None:
        data = tomllib.loads(d.read_text())
        data["anomalies"] = {"mode_hop": copy.deepcopy(hop)}
        d.write_text(dumps(data))
    return IT.simulate(IT.scenario(folder, d, seed=seed), folder / "r.h5")


def _true_hops(path) -> list[tuple[float, float]]:
    import rlgsim
    with rlgsim.open_tree(str(path), load=True) as tr:
        if "anomalies" not in tr.children:
            return []
        a = tr["anomalies"]
        kind = np.asarray(a["kind"].values).astype(str)
        sel = np.char.startswith(kind, "mode_hop")
        return list(zip(np.asarray(a["time"].values)[sel].tolist(),
                        np.asarray(a["size"].values)[sel].tolist()))


def test_identify_recovers_injected_hops_and_the_twin_simulates(tmp_path):
    from rlgsim.lab.identify import identify
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    rec = _recording(tmp_path / "hop", 3, HOP)
    truth = _true_hops(rec)
    assert len(truth) == 2                       # up on the 45 °C ramp, back down on cooling
    r = identify(rec, tmp_path / "twin")
    hf = r.laws.hops
    assert len(hf.hops) == 2
    for h, (t, size) in zip(hf.hops, truth):
        assert abs(h.time_s - t) <= 2 * WINDOW
        assert abs(h.size_deg_per_h - size) <= 3 * h.size_se_deg_per_h
    assert [h.direction for h in hf.hops] == [1, -1]
    assert len(hf.pairs) == 1 and hf.pairs[0][2] > 0          # a hysteresis loop
    mh = hf.mode_hop
    # one hop level: κ is the template's (here the truth's), R and T_ref fitted
    assert mh["modes_per_k"] == HOP["modes_per_k"]
    assert abs(mh["range_modes"] - HOP["range_modes"]) < 0.1
    assert abs(mh["reference_c"] - HOP["reference_c"]) < 1.0
    assert abs(mh["bias_step_deg_per_h"] - 0.04) < 3 * 0.0063
    # the mapped model hops on the twin's T_c where the recording did
    assert [d for _, d in hf.predicted] == [1, -1]
    for (tp, _), (t, _) in zip(hf.predicted, truth):
        assert abs(tp - t) <= 3 * WINDOW
    # device.toml: the simulator's keys, each number commented; it loads and simulates
    text = r.device_path.read_text()
    dev = tomllib.loads(text)
    assert set(dev["anomalies"]["mode_hop"]) >= {"nodes", "modes_per_k", "range_modes",
                                                 "reference_c", "bias_step_deg_per_h"}
    assert "reference_c = " in text and "standard error" in text.split("reference_c = ")[1]
    assert "Mode hops" in r.report_path.read_text()
    sc = tmp_path / "twin" / "short.toml"
    sc.write_text('name = "short"\ndescription = "twin check"\ndevice = "device.toml"\n'
                  'seed = 2\n[acquisition]\nsample_rate_hz = 1.0\nthermal_step_s = 1.0\n'
                  '[chamber]\nstart_c = 20.0\nsegments = [{type = "ramp", to_c = 45.0, '
                  'rate_c_per_min = 1.0}, {type = "hold", duration_min = 30}]\n')
    out = simulate(load_scenario(str(sc)), str(tmp_path / "twin" / "short.h5"), progress=False)
    assert _true_hops(out)                       # the twin hops on the way up


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_noise_only_recordings_give_no_hop(tmp_path, seed):
    """Noise only (white + flicker, trplg_001's levels) and a c1 law, no anomalies: no hop,
    and no mode-hop table in the twin (fit_laws on the true network's node temperatures)."""
    from rlgsim.sim import presets
    from rlgsim.lab.identify.law_fit import fit_laws
    from rlgsim.lab.identify.recording_data import read_recording
    from rlgsim.lab.identify.thermal_fit import build, twin_response
    rec_path = _recording(tmp_path / f"n{seed}", seed, None)
    rec = read_recording(rec_path)
    net, probes = build(presets.load_thermal_file(str(tmp_path / f"n{seed}" /
                                                      "truth_thermal.toml")).data)
    nodes, _ = twin_response(net, probes, rec.air_c, rec.power, rec.step_s)
    dev = tomllib.loads((tmp_path / f"n{seed}" / "truth_device.toml").read_text())
    laws = fit_laws(rec, nodes, net.node_names, dev)
    assert laws.hops is not None and laws.hops.hops == ()
    assert laws.hops.mode_hop is None and not laws.bias.fixed


def test_spikes_counted_and_rate_estimated():
    """Injected read-out spikes of 3-8 pulses in a quantised 1 Hz pulse stream are all found
    (sizes to a pulse); the rate is count / hours scaled for the invisible sizes, inside its
    interval."""
    from rlgsim.lab.identify.spike_fit import find_spikes
    rng = np.random.default_rng(3)
    k, f, n = 2.14, 1.0, 36000
    phase = np.cumsum(np.full(n, 11.0 * k / f) + 0.1 * rng.standard_normal(n))
    pulses = np.diff(np.floor(np.concatenate(([0.0], phase))))
    where = np.array([1000, 9000, 20000, 33000])
    sizes = np.array([3, -8, 5, 7])
    pulses[where] += sizes
    sp = find_spikes(pulses * f / k, f, k, np.ones(n, dtype=bool))
    # sizes to within the quantisation (the neighbours' median is 23 or 24 pulses)
    assert np.all(np.abs(np.array(sp.sizes) - sizes) <= 1)
    assert sp.times_s == tuple(float(w + 1) for w in where)
    assert abs(sp.max_pulses - 8) <= 1
    lo, hi = sp.rate_ci95_per_h
    assert lo < sp.rate_per_h < hi
    M = sp.max_pulses
    assert sp.rate_per_h == pytest.approx(4 / 10.0 / ((M - 2) / M))


def test_fixed_regressor_against_statsmodels():
    """``select_terms(..., fixed=...)``: a step carried in every model; with the true term
    chosen, its coefficient and standard error are statsmodels' least squares (the GLS standard
    error with C = σ²I: the OLS one rescaled to the modelled σ unless the residual is larger)."""
    import statsmodels.api as sm
    from rlgsim.estimators.identify.term_selection import Term, select_terms
    rng = np.random.default_rng(8)
    n = 300
    x = np.linspace(-1, 1, n)
    step = (np.arange(n) >= 120).astype(float)
    sigma = 0.1
    y = 1.0 + 2.0 * x + 0.5 * step + sigma * rng.standard_normal(n)
    cands = [Term("x", lambda th: x), Term("x2", lambda th: x ** 2)]
    sel = select_terms(y, cands, noise_cov=sigma ** 2 * np.eye(n),
                       fixed=[Term("hop1", lambda th: step)])
    assert sel.terms == ("x",) and sel.fixed == ("hop1",)
    ols = sm.OLS(y, np.column_stack([np.ones(n), step, x])).fit()
    assert sel.value("hop1") == pytest.approx(ols.params[1], rel=1e-6)
    assert sel.value("x") == pytest.approx(ols.params[2], rel=1e-6)
    s2w = ols.ssr / sigma ** 2 / (n - 3)
    assert sel.se("hop1") == pytest.approx(ols.bse[1] * np.sqrt(max(1.0, s2w) / s2w), rel=1e-4)
    assert sel.averaged["hop1"][2] == 1.0              # in every averaged model
    with pytest.raises(ValueError):
        select_terms(y, cands, fixed=[Term("x", lambda th: step)])


DRAWN_HOP = {**HOP, "modes_per_k_rel": 0.1, "bias_step_rel": 0.2, "phase_per_unit": True}


def _drawn_unit(folder: pathlib.Path, unit: int, hop: dict | None, fit: bool = True):
    """Monte Carlo unit ``unit`` of an rlg_single / c1-law / trplg_001-noise device whose
    template carries ``DRAWN_HOP`` (κ ± 10 %, Δb ± 20 %, the lock point drawn per unit: every
    unit hops at its own temperatures; ``hop`` None: the unit has no hops), simulated, and the
    law fitted (``fit``) on the unit's true thermal state with the template's mode-hop model."""
    import dataclasses
    from rlgsim.sim import presets
    from rlgsim.lab.identify.law_fit import fit_laws
    from rlgsim.lab.identify.preset_text import dumps
    from rlgsim.lab.identify.recording_data import read_recording
    from rlgsim.sim.run.scenario import load_scenario
    from rlgsim.sim.run.simulate import simulate
    folder.mkdir(parents=True, exist_ok=True)
    th = IT.thermal_truth(folder, {})
    dev_t = presets.load_device_file("trplg_001").data
    bias = {"node": "A", "t_ref_c": 20.0, "value_deg_per_h": 0.01, "c1_deg_per_h_per_k": 3e-4}
    d = IT.device_truth(folder, th, bias=bias, keep_uhfo=False, noise=dict(dev_t["noise"]))
    data = tomllib.loads(d.read_text())
    template = copy.deepcopy(data)
    template["anomalies"] = {"mode_hop": copy.deepcopy(DRAWN_HOP)}
    if hop is not None:
        data["anomalies"] = {"mode_hop": copy.deepcopy(hop)}
    d.write_text(dumps(data))
    s = dataclasses.replace(load_scenario(str(IT.scenario(folder, d, seed=3))), unit=unit)
    out = simulate(s, str(folder / "r.h5"), progress=False)
    import rlgsim
    with rlgsim.open_tree(str(out), load=True) as tr:
        names = [str(n) for n in tr["thermal"]["node"].values]
        nodes = np.asarray(tr["thermal"]["node_temperature"].values)
    if not fit:
        return out, nodes, tuple(names), None
    rec = read_recording(out)
    return out, nodes, tuple(names), fit_laws(rec, nodes, tuple(names), template)


def test_drawn_units_hops_match_the_truth_record(tmp_path):
    """Drawn units whose hops lie at their own temperatures, at one and two mode levels (unit 1:
    up, down, down, up across two levels — a staircase that follows the temperature, which the
    c1 term absorbs and a one-step scan misses): every true hop found once, of the right
    direction, within two windows (200 s), its T_c within 1 K of the true T_c there (the
    twin's T_c moves up to about 0.7 K over two windows on the programme's 1 °C/min ramps),
    and nothing else. Identified end to end, the template the dataset's own device (its
    mode-hop model with the lock point free)."""
    from rlgsim.lab.identify import identify
    for unit in (1, 2, 3):
        out, nodes, names, _ = _drawn_unit(tmp_path / f"u{unit}", unit, DRAWN_HOP, fit=False)
        truth = _true_hops(out)
        cols = [names.index(f"g.{n}") for n in DRAWN_HOP["nodes"]]
        tc = nodes[:, cols].mean(axis=1)
        found = identify(out, tmp_path / f"twin{unit}").laws.hops.hops
        assert len(truth) >= 2 and len(found) == len(truth), (unit, truth, found)
        for h, (t, size) in zip(found, truth):
            assert abs(h.time_s - t) <= 2 * WINDOW and h.direction == np.sign(size), (unit, h, t)
            assert abs(h.temperature_c - tc[int(round(t)) - 1]) < 1.0, (unit, h, t)


def test_pattern_search_adds_no_hop_to_hop_free_drawn_units(tmp_path):
    """The same template (its hops' lock point free), units without hops: no hop found."""
    for unit in (4, 5):
        _, _, _, laws = _drawn_unit(tmp_path / f"n{unit}", unit, None)
        assert laws.hops.hops == (), unit
