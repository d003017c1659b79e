"""The twin's preset texts (docs/identify.md): the thermal preset with its fitted multipliers,
the device preset with the fitted laws, noise and anomalies — every fitted number commented with
its standard error and where it came from — and the scenario that replays the recorded chamber
programme on the twin. Shared by the single-gyro and the several-gyro identifications
(:mod:`.twin`, :mod:`.twin_gyros`)."""

from __future__ import annotations

import copy
import pathlib

import numpy as np

from rlgsim.lab.identify.law_fit import LawFit
from rlgsim.lab.identify.preset_text import dumps, piecewise_programme
from rlgsim.lab.identify.recording_data import RecordingData
from rlgsim.lab.identify.thermal_fit import ThermalFit

__all__ = ["device_dict", "law_header", "scenario_text", "thermal_text"]

_BIAS_KEEP = ("node", "t_ref_c", "arm_nodes", "langmuir_deg_per_h_per_ma",
              "leg_imbalance_ma_per_k")
_BIAS_KEYS = {"c1": "c1_deg_per_h_per_k", "c2": "c2_deg_per_h_per_k2",
              "c3": "c3_deg_per_h_per_k3", "rate": "rate_deg_per_h_per_c_per_min",
              "uhfo": "uhfo_deg_per_h_per_v", "knee": "knee_deg_per_h", "step": "step_deg_per_h"}
_UHFO_KEYS = {"c1": "c1_v_per_k", "c2": "c2_v_per_k2", "c3": "c3_v_per_k3",
              "rate": "rate_v_per_c_per_min"}


def se_note(se: float, what: str = "") -> str:
    return f"fitted, standard error {se:.3g}{'; ' + what if what else ''}"


def law_note(sel, t: str) -> str:
    """Comment of a BIC-selected term: its standard error in the chosen law, and the
    model-averaged value with the selection uncertainty (and, for a term the recording cannot
    separate from another, which one)."""
    note = se_note(sel.se(t), "BIC-selected")
    if t in sel.averaged:
        v, se, p = sel.averaged[t]
        note += f"; model-averaged {v:.4g} ± {se:.2g} (inclusion {p:.2f})"
    for group, _ in sel.unseparable:
        if t in group:
            others = [g for g in group if g != t]
            note += f"; not separable from {', '.join(others)} (header)"
    return note


def law_header(sel) -> str:
    lines = []
    for _, reason in sel.unseparable:
        lines.append(f"bias law: {reason}")
    return "\n".join(lines)


def thermal_text(fit: ThermalFit, tname: str, source: str) -> tuple[dict, str]:
    comments = {}
    for path, (param, old, new) in fit.changes.items():
        parts = []
        for name in param.split("+"):    # two multipliers on one value (a source on its own)
            m = fit.multipliers[name]
            parts.append(f"{name} × {m:.5g} ± {fit.rel_se[name] * m:.2g}")
        comments[path] = (f"fitted: {', '.join(parts)} (standard error); template "
                          f"{old:.6g}")
    lines = [f"Thermal preset identified by rlgsim identify from {source}",
             f"template: {tname}; topology kept, multipliers fitted (log scale, least squares "
             f"on the exact integrator)",
             "fitted multipliers (× template, ± standard error):"]
    for p in fit.params:
        if p.name in fit.multipliers:
            lines.append(f"  {p.name}: {fit.multipliers[p.name]:.5g} ± "
                         f"{fit.rel_se[p.name] * fit.multipliers[p.name]:.2g}  ({p.description})")
        elif p.name in fit.refused:
            lines.append(f"  {p.name}: kept at the template — {fit.refused[p.name]}")
    lines.append("probe residual RMS after the fit [°C]: " + ", ".join(
        f"{k} {v:.4f}" for k, v in fit.rms_fitted_c.items()))
    return fit.fitted, dumps(fit.fitted, comments, "\n".join(lines))


def device_dict(template: dict, laws: LawFit, name: str, source: str
                 ) -> tuple[dict, dict[tuple, str]]:
    dev = copy.deepcopy(template)
    comments: dict[tuple, str] = {}
    dev.setdefault("device", {})
    dev["device"].update({"name": name, "description": f"digital twin identified from {source}",
                          "source": f"rlgsim identify {source}", "thermal_preset": "thermal.toml"})
    comments[("device", "thermal_preset")] = "the identified thermal preset beside this file"
    gyro = dev.setdefault("gyro", {})
    old = gyro.get("bias", {})
    bias = {k: old[k] for k in _BIAS_KEEP if k in old}
    sel = laws.bias
    bias["value_deg_per_h"] = sel.value("intercept")
    comments[("gyro", "bias", "value_deg_per_h")] = se_note(sel.se("intercept"))
    for t in sel.terms:
        if t in _BIAS_KEYS:
            bias[_BIAS_KEYS[t]] = sel.value(t)
            comments[("gyro", "bias", _BIAS_KEYS[t])] = law_note(sel, t)
        if t in ("knee", "step"):
            bias[f"{t}_c"] = sel.value(f"{t}.center_c")
            bias[f"{t}_width_k"] = sel.value(f"{t}.width_k")
            comments[("gyro", "bias", f"{t}_c")] = se_note(sel.se(f"{t}.center_c"))
            comments[("gyro", "bias", f"{t}_width_k")] = se_note(sel.se(f"{t}.width_k"))
    grads = [t for t in sel.terms if t.startswith("gradient[")]
    if grads:
        bias["gradients"] = []
        for i, t in enumerate(grads):
            a, b = laws.gradient_pairs[t]
            bias["gradients"].append({"a": a, "b": b, "coeff_deg_per_h_per_k": sel.value(t)})
            comments[("gyro", "bias", "gradients", i, "coeff_deg_per_h_per_k")] = \
                f"{a}-{b}: " + law_note(sel, t)
    gyro["bias"] = bias
    used = set(bias)
    tol = dev.get("tolerance", {}).get("gyro", {})
    if "bias" in tol:
        tol["bias"] = {k: v for k, v in tol["bias"].items()
                       if k in used or (k == "gradients_rel" and grads)
                       or (k.startswith(("knee_", "step_")) and
                           f"{k.split('_')[0]}_deg_per_h" in used)}
    if laws.uhfo is not None:
        u = dev.setdefault("uhfo", {})
        keep = {k: u[k] for k in ("node", "t_ref_c", "lsb_v") if k in u}
        keep.setdefault("node", laws.uhfo_node)
        keep.setdefault("t_ref_c", laws.uhfo_t_ref_c)
        us = laws.uhfo
        keep["value_v"] = us.value("intercept")
        comments[("uhfo", "value_v")] = se_note(us.se("intercept"))
        for t in us.terms:
            keep[_UHFO_KEYS[t]] = us.value(t)
            comments[("uhfo", _UHFO_KEYS[t])] = se_note(us.se(t), "BIC-selected")
        for key, (v, se) in laws.uhfo_noise.items():
            if np.isfinite(v):
                keep[key] = float(v)
                comments[("uhfo", key)] = se_note(float(se), "from the law residual")
        dev["uhfo"] = keep
        if "uhfo" in dev.get("tolerance", {}):
            ut = dev["tolerance"]["uhfo"]
            dev["tolerance"]["uhfo"] = {k: v for k, v in ut.items()
                                        if k in keep or k in ("wander_rel", "noise_rel")}
    if laws.noise is not None:
        n = dev.setdefault("noise", {})
        nf = laws.noise
        for key, pkey in (("arw_deg_per_sqrt_h", "gyro_arw_deg_per_sqrt_h"),
                          ("bi_deg_per_h", "gyro_bias_instability_deg_per_h"),
                          ("rrw_deg_per_h_per_sqrt_h", "gyro_rrw_deg_per_h_per_sqrt_h")):
            lo, hi = nf.intervals[key]
            n[pkey] = float(nf.values[key])
            se = (hi - lo) / (2 * 1.96)
            comments[("noise", pkey)] = (f"Allan fit, standard error ≈ {se:.2g}, 95 % interval "
                                         f"[{lo:.3g}, {hi:.3g}]"
                                         + ("; not resolved by this recording" if lo == 0 else ""))
    # mode hops and read-out spikes as found in the recording (hop_fit, spike_fit)
    from rlgsim.lab.identify.hop_mapping import anomalies_table
    anomalies, acomments = anomalies_table(dev.pop("anomalies", None), laws.hops, laws.spikes)
    if anomalies is not None:
        dev["anomalies"] = anomalies
        comments.update(acomments)
    return dev, comments


def scenario_text(data: RecordingData, name: str) -> str:
    start, segs = piecewise_programme(data.t_s, data.air_c)
    powered = np.flatnonzero(data.power > 0.5)
    on = float(data.t_s[powered[0]] - data.step_s) if powered.size else 0.0
    rates = np.abs(np.diff(data.air_c)) / data.step_s * 60.0
    sc = {"name": f"{name}_replay",
          "description": f"the chamber programme of {pathlib.Path(data.source).name} replayed "
                         f"on the twin (air as a piecewise-linear setpoint within 0.05 K, no "
                         f"air lag)",
          "device": "device.toml", "seed": 1, "duration_s": float(data.t_s[-1]),
          "acquisition": {"sample_rate_hz": float(data.sample_rate_hz),
                          "thermal_step_s": float(data.step_s)},
          "power": {"on_at_s": on},
          "chamber": {"start_c": start, "air_tau_s": 0.0,
                      "max_rate_c_per_min": float(max(np.max(rates) * 2.0, 1.0)),
                      "segments": [{"type": "ramp", "to_c": round(to, 6), "duration_s": d}
                                   for d, to in segs]}}
    return dumps(sc, header=f"Replays the recorded chamber air of {data.source} on the twin "
                            f"(rlgsim run {name}_replay.toml)")
