"""``identify(recording, out_dir)``: a digital twin of the recorded device — a thermal preset, a
device preset and a scenario that replays the recorded chamber programme on the twin — with a
report of the fit quality (docs/identify.md).

Steps: read and check the recording (:mod:`.recording_data`); fit the thermal multipliers of
the thermal template (:mod:`.thermal_fit`); drive the fitted network with the recorded air and
fit the UHFO law, the bias law and the noise on its thermal state (:mod:`.law_fit`), and, where
the turntable turns, the scale-factor law (:mod:`.scale_factor_fit`); write
``thermal.toml``, ``device.toml``, ``replay.toml`` (:mod:`.preset_text`) and the report
(:mod:`.identify_report`). Templates: for an rlgsim dataset the device and thermal presets it
was simulated with (its embedded texts); for a recording ``device_template`` is required and
``thermal_template`` defaults to the device template's ``thermal_preset``.
"""

from __future__ import annotations

import copy
import os
import pathlib
import time
import tomllib
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from rlgsim.ground.errors import UserInputError
from rlgsim.sim import presets
from rlgsim.lab.identify.law_fit import LawFit, fit_laws
from rlgsim.lab.identify.preset_text import dumps, piecewise_programme
from rlgsim.lab.identify.recording_data import RecordingData, read_recording, scale_factor_line
from rlgsim.lab.identify.scale_factor_fit import (ScaleFactorFit, fit_scale_factor,
                                                  scale_factor_table)
from rlgsim.lab.identify.thermal_fit import ThermalFit, fit_thermal
from rlgsim.lab.report import write_atomic

__all__ = ["Identification", "identify", "load_templates"]

_BIAS_KEEP = ("node", "t_ref_c", "arm_nodes", "langmuir_deg_per_h_per_ma",
              "leg_imbalance_ma_per_k")
_BIAS_KEYS = {"c1": "c1_deg_per_h_per_k", "c2": "c2_deg_per_h_per_k2",
              "c3": "c3_deg_per_h_per_k3", "rate": "rate_deg_per_h_per_c_per_min",
              "uhfo": "uhfo_deg_per_h_per_v", "knee": "knee_deg_per_h", "step": "step_deg_per_h"}
_UHFO_KEYS = {"c1": "c1_v_per_k", "c2": "c2_v_per_k2", "c3": "c3_v_per_k3",
              "rate": "rate_v_per_c_per_min"}


@dataclass
class Identification:
    """Where the outputs went and what was fitted."""

    out_dir: pathlib.Path
    device_path: pathlib.Path
    thermal_path: pathlib.Path
    scenario_path: pathlib.Path
    report_path: pathlib.Path
    data: RecordingData
    thermal: ThermalFit
    laws: LawFit
    device: dict
    thermal_preset: dict
    seconds: float
    name: str
    #: the scale-factor law from the turntable's rate segments (None: a static recording)
    scale_factor: ScaleFactorFit | None = None
    #: how the recorded probes were placed on the template's (empty: named as the template)
    probe_lines: tuple[str, ...] = ()
    #: defaults taken for what the recording's sidecar does not say (sidecar_choices)
    notes: tuple[str, ...] = ()
    #: the next experiment (``suggest_programme``; None: not asked, or nothing to separate)
    suggestion: object = None
    next_path: pathlib.Path | None = None


def load_templates(source: str, device_template: str | None, thermal_template: str | None
                   ) -> tuple[str, dict, str, dict]:
    """(device name, device dict, thermal name, thermal dict) of the templates."""
    from rlgsim.ground.recording import is_recording
    dev_name, dev, base = None, None, None
    if device_template is not None:
        f = presets.load_device_file(device_template)
        dev_name, dev, base = f.name, f.data, f.base_dir
        dev_src = str(f.source)
    elif not is_recording(source):
        from rlgsim.ground.dataset_format import open_dataset
        with open_dataset(source) as ds:
            text = str(ds.attrs.get("device_text", ""))
            dname = str(ds.attrs.get("device", "device"))
            ttext = str(ds.attrs.get("thermal_preset_text", ""))
        if text:
            dev_name = dname
            dev = tomllib.loads(text)
            if thermal_template is None and ttext:
                tname = str(dev.get("device", {}).get("thermal_preset", "thermal preset"))
                dev = _one_day(dev)
                _one_gyro(dev_name, dev)
                _check_device_tables(f"{source}: device_text", dev)
                return dev_name, dev, f"{tname} (as embedded in the dataset)", \
                    tomllib.loads(ttext)
    if dev is None:
        raise UserInputError(f"{source}: a recording needs a device template (the device preset "
                             f"whose law family and noise keys the twin takes; e.g. trplg_001): "
                             f"give --device-template PRESET or, in its sidecar, [identify] "
                             f"device_template = \"PRESET\"")
    dev = _one_day(dev)
    _one_gyro(dev_name, dev)
    _check_device_tables(dev_src if device_template is not None else f"{source}: device_text",
                         dev)
    tref = thermal_template or dev.get("device", {}).get("thermal_preset")
    if not tref:
        raise UserInputError(f"{dev_name}: no thermal preset; give --thermal-template PRESET "
                             f"or, in the recording's sidecar, [identify] thermal_template")
    t = presets.load_thermal_file(tref, base_dir=base)
    return dev_name, dev, t.name, t.data


def _one_day(dev: dict) -> dict:
    """The template without its ``[run_to_run]`` table: a twin is one recording, one day, and
    the table's mount links name nodes of the template's own thermal network, which the twin
    may replace (sim/run/run_to_run.py)."""
    return {k: v for k, v in dev.items() if k != "run_to_run"}


def _check_device_tables(where: str, dev: dict) -> None:
    """The template's sensor tables checked by the simulator's own validators (the twin's
    modules read them raw: a bad template is one line naming the key, not a traceback)."""
    from rlgsim.sim.config import Ctx
    from rlgsim.sim.run.scenario import validate_device_tables
    validate_device_tables(dev, Ctx(where))


def _one_gyro(dev_name: str, dev: dict) -> None:
    axes = dev.get("gyro", {}).get("axes", [])
    if len(axes) != 1:
        raise UserInputError(f"{dev_name}: the device template has {len(axes)} gyro axes; "
                             f"identification fits one gyro (a single-gyro template such as "
                             f"trplg_001 or rlg8_003)")


def _se_note(se: float, what: str = "") -> str:
    return f"fitted, standard error {se:.3g}{'; ' + what if what else ''}"


def _law_note(sel, t: str) -> str:
    """Comment of a BIC-selected term: its standard error in the chosen law, and the
    model-averaged value with the selection uncertainty (and, for a term the recording cannot
    separate from another, which one)."""
    note = _se_note(sel.se(t), "BIC-selected")
    if t in sel.averaged:
        v, se, p = sel.averaged[t]
        note += f"; model-averaged {v:.4g} ± {se:.2g} (inclusion {p:.2f})"
    for group, _ in sel.unseparable:
        if t in group:
            others = [g for g in group if g != t]
            note += f"; not separable from {', '.join(others)} (header)"
    return note


def _law_header(sel) -> str:
    lines = []
    for _, reason in sel.unseparable:
        lines.append(f"bias law: {reason}")
    return "\n".join(lines)


def _thermal_text(fit: ThermalFit, tname: str, source: str) -> tuple[dict, str]:
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


def _device_dict(template: dict, laws: LawFit, name: str, source: str
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
    comments[("gyro", "bias", "value_deg_per_h")] = _se_note(sel.se("intercept"))
    for t in sel.terms:
        if t in _BIAS_KEYS:
            bias[_BIAS_KEYS[t]] = sel.value(t)
            comments[("gyro", "bias", _BIAS_KEYS[t])] = _law_note(sel, t)
        if t in ("knee", "step"):
            bias[f"{t}_c"] = sel.value(f"{t}.center_c")
            bias[f"{t}_width_k"] = sel.value(f"{t}.width_k")
            comments[("gyro", "bias", f"{t}_c")] = _se_note(sel.se(f"{t}.center_c"))
            comments[("gyro", "bias", f"{t}_width_k")] = _se_note(sel.se(f"{t}.width_k"))
    grads = [t for t in sel.terms if t.startswith("gradient[")]
    if grads:
        bias["gradients"] = []
        for i, t in enumerate(grads):
            a, b = laws.gradient_pairs[t]
            bias["gradients"].append({"a": a, "b": b, "coeff_deg_per_h_per_k": sel.value(t)})
            comments[("gyro", "bias", "gradients", i, "coeff_deg_per_h_per_k")] = \
                f"{a}-{b}: " + _law_note(sel, t)
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
        comments[("uhfo", "value_v")] = _se_note(us.se("intercept"))
        for t in us.terms:
            keep[_UHFO_KEYS[t]] = us.value(t)
            comments[("uhfo", _UHFO_KEYS[t])] = _se_note(us.se(t), "BIC-selected")
        for key, (v, se) in laws.uhfo_noise.items():
            if np.isfinite(v):
                keep[key] = float(v)
                comments[("uhfo", key)] = _se_note(float(se), "from the law residual")
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


def _scenario_text(data: RecordingData, name: str) -> str:
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


def _inputs(source: str, *templates: str | None) -> list[str]:
    """The files identification reads: the recording (and its sidecar) and template files."""
    from rlgsim.ground.recording import is_recording, sidecar_path
    found = [source] + ([str(sidecar_path(source))] if is_recording(source) else [])
    return found + [t for t in templates if t is not None and os.path.lexists(t)]


def identify(recording: str | os.PathLike, out_dir: str | os.PathLike, *,
             device_template: str | None = None, thermal_template: str | None = None,
             name: str | None = None, gyro: str | None = None,
             suggest_programme: bool = False, overwrite: bool = False) -> Identification:
    """Identify a twin of the device in ``recording`` (a recording or an rlgsim dataset) and
    write ``thermal.toml``, ``device.toml``, ``<name>_replay.toml`` and ``report.md``/``.html``
    into ``out_dir`` (module docstring, docs/identify.md); the outputs are checked first
    (:mod:`rlgsim.lab.identify.outputs`: never an input, a link or a special file; an existing
    file an earlier identification did not write only with ``overwrite``).
    ``suggest_programme``: also write ``<name>_next.toml``, a chamber programme that would
    separate the terms this recording could not (:mod:`.next_experiment`).

    It all runs with one BLAS thread (threadpoolctl): the fits factorise tall, thin Jacobians
    and integrate small networks, which a BLAS thread pool only slows down on a shared machine
    (the thermal integrator's and the Monte Carlo workers' reason;
    tests/test_identify_lab_probes.py checks the limit is in force inside the fits)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify(recording, out_dir, device_template=device_template,
                         thermal_template=thermal_template, name=name, gyro=gyro,
                         suggest_programme=suggest_programme, overwrite=overwrite)


def _identify(recording: str | os.PathLike, out_dir: str | os.PathLike, *,
              device_template: str | None, thermal_template: str | None, name: str | None,
              gyro: str | None, suggest_programme: bool, overwrite: bool) -> Identification:
    """:func:`identify` under its thread limit."""
    from rlgsim.ground.paths import input_file
    from rlgsim.lab.identify.outputs import check_name, planned_outputs
    t0 = time.perf_counter()
    source = os.fspath(input_file(recording, "a recording or an rlgsim dataset"))
    if name is not None:
        check_name(name)
    from rlgsim.lab.identify.sidecar_choices import sidecar_choices
    chosen = sidecar_choices(source, device_template, thermal_template, gyro)
    device_template, thermal_template = chosen.device_template, chosen.thermal_template
    inputs = _inputs(source, device_template, thermal_template)
    dev_name, dev_t, th_name, th_t = load_templates(source, device_template, thermal_template)
    name = name or f"{dev_name}_twin"
    planned_outputs(out_dir, name, inputs, overwrite=overwrite, next_file=suggest_programme)
    data = read_recording(source, gyro=chosen.gyro)
    from rlgsim.lab.identify.probe_mapping import map_probes, sidecar_probe_table
    data, probe_lines = map_probes(th_t, data, sidecar_probe_table(source), source)
    thermal = fit_thermal(th_t, data.air_c, data.power, data.step_s, data.probe_names,
                          data.probes_c, source=source)
    laws = fit_laws(data, thermal.nodes_c, thermal.network.node_names, dev_t)
    sf = fit_scale_factor(data, thermal.nodes_c, thermal.network.node_names, dev_t, laws)
    out = pathlib.Path(out_dir).expanduser()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserInputError(f"{out}: cannot create the output folder ({exc.strerror or exc})"
                             ) from None
    files = planned_outputs(out, name, inputs, overwrite=overwrite, next_file=suggest_programme)
    fitted_thermal, ttext = _thermal_text(thermal, th_name, source)
    dev, comments = _device_dict(dev_t, laws, name, source)
    sf_lines = sf.lines if sf is not None else [scale_factor_line(data)]
    if sf is not None and sf.identified:
        table, notes = scale_factor_table(dev_t, sf)
        dev.setdefault("gyro", {})["scale_factor"] = table
        comments.update({("gyro", "scale_factor", k): v for k, v in notes.items()})
        tol = dev.get("tolerance", {}).get("gyro", {})
        if "scale_factor" in tol:
            tol["scale_factor"] = {k: v for k, v in tol["scale_factor"].items()
                                   if k in table or (k.startswith("knee_") and "knee_ppm" in table)}
    header = [*chosen.notes, *probe_lines, *sf_lines]
    dtext = dumps(dev, comments, f"Device preset identified by rlgsim identify from {source}\n"
                                 f"template: {dev_name}; bias and UHFO terms chosen by BIC, "
                                 f"noise from the Allan deviation of the law residual"
                                 + ("\n" + _law_header(laws.bias) if laws.bias.unseparable
                                    else "") + "\n" + "\n".join(header))
    stext = _scenario_text(data, name)
    suggestion, ntext = None, None
    if suggest_programme:
        from rlgsim.lab.identify.next_experiment import scenario_text, suggest_programme as suggest
        suggestion = suggest(data, thermal, laws, dev_t)
        if suggestion is not None:
            ntext = scenario_text(suggestion, data, name)
    for text in (ttext, dtext, stext, ntext or ""):
        tomllib.loads(text)                        # never write what cannot be read back
    tp, dp, sp = files["thermal"], files["device"], files["replay"]
    write_atomic(tp, ttext)
    write_atomic(dp, dtext)
    write_atomic(sp, stext)
    next_path = None
    if ntext is not None:
        next_path = files["next"]
        write_atomic(next_path, ntext)
    seconds = time.perf_counter() - t0
    result = Identification(out_dir=out, device_path=dp, thermal_path=tp, scenario_path=sp,
                            report_path=out / "report.md", data=data, thermal=thermal, laws=laws,
                            device=dev, thermal_preset=fitted_thermal, seconds=seconds, name=name,
                            scale_factor=sf, probe_lines=tuple(probe_lines), notes=chosen.notes,
                            suggestion=suggestion, next_path=next_path)
    from rlgsim.lab.identify.identify_report import build_report
    build_report(result, dev_name, th_name).write(out)
    return result
