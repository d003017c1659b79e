"""``identify(recording, out_dir)``: a digital twin of the recorded device — a thermal preset, a
device preset and a scenario that replays the recorded chamber programme on the twin — with a
report of the fit quality (docs/identify.md).

Steps: read and check the recording (:mod:`.recording_data`); fit the thermal multipliers of
the thermal template (:mod:`.thermal_fit`; the read-out spikes of the gyro samples,
:mod:`.spike_fit`, are found meanwhile in a thread); drive the fitted network with the recorded
air and fit the UHFO law, the bias law and the noise on its thermal state (:mod:`.law_fit`),
and, where the turntable turns, the scale-factor law (:mod:`.scale_factor_fit`); write
``thermal.toml``, ``device.toml``, ``replay.toml`` (:mod:`.preset_text`) and the report
(:mod:`.identify_report`); the texts are :mod:`.twin_text`'s, the templates
:mod:`.twin_templates`'s; a recording of several gyros with none chosen goes to
:mod:`.twin_gyros` (one device preset with every gyro's law). Templates: for an rlgsim dataset
the device and thermal presets it was simulated with (its embedded texts); for a recording
``device_template`` is required and ``thermal_template`` defaults to the device template's
``thermal_preset``; a several-gyro template gives the chosen gyro's view.
"""

from __future__ import annotations

import os
import time
import tomllib
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from threadpoolctl import threadpool_limits

from rlgsim.lab.identify._median_kernel import rolling_median
from rlgsim.lab.identify.law_fit import fit_laws, read_out_spikes
from rlgsim.lab.identify.recording_data import read_recording, scale_factor_line
from rlgsim.lab.identify.scale_factor_fit import fit_scale_factor, scale_factor_table
from rlgsim.lab.identify.thermal_fit import fit_thermal
from rlgsim.lab.identify.twin_result import Identification
from rlgsim.lab.identify.twin_templates import files_read as _inputs
from rlgsim.lab.identify.twin_templates import load_templates
from rlgsim.lab.identify.twin_text import device_dict as _device_dict
from rlgsim.lab.identify.twin_text import law_header as _law_header
from rlgsim.lab.identify.twin_text import scenario_text as _scenario_text
from rlgsim.lab.identify.twin_text import thermal_text as _thermal_text
from rlgsim.lab.identify.preset_text import dumps
from rlgsim.lab.report import write_atomic

__all__ = ["Identification", "identify", "load_templates"]


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
    from rlgsim.lab.identify import twin_gyros as G
    axes = [chosen.gyro] if chosen.gyro is not None else G.recorded_gyros(source)
    if len(axes) > 1:                    # several gyros and none chosen: one twin of them all
        return G.identify_gyros(source, out_dir, axes, chosen, name, suggest_programme,
                                overwrite, t0)
    device_template, thermal_template = chosen.device_template, chosen.thermal_template
    inputs = _inputs(source, device_template, thermal_template)
    dev_name, dev_t, th_name, th_t = load_templates(source, device_template, thermal_template,
                                                    several=True)
    dev_t = G.one_gyro_template(dev_t, axes, source)   # a several-gyro template: that gyro's
    name = name or f"{dev_name}_twin"
    planned_outputs(out_dir, name, inputs, overwrite=overwrite, next_file=suggest_programme)
    data = read_recording(source, gyro=chosen.gyro)
    from rlgsim.lab.identify.probe_mapping import map_probes, sidecar_probe_table
    data, probe_lines = map_probes(th_t, data, sidecar_probe_table(source), source)
    # the spike scan needs no twin: a thread beside the thermal fit (numpy's and the compiled
    # median's loops release the GIL). Its kernel is loaded here first, so the thread never
    # holds numba's compiler lock while the fit forks its Jacobian workers
    rolling_median(np.zeros(1), 31, 5)
    with ThreadPoolExecutor(max_workers=1) as beside:
        spikes = beside.submit(read_out_spikes, data, dev_t)    # no twin needed: in parallel
        thermal = fit_thermal(th_t, data.air_c, data.power, data.step_s, data.probe_names,
                              data.probes_c, source=source)
        laws = fit_laws(data, thermal.nodes_c, thermal.network.node_names, dev_t,
                        spikes=spikes.result())
    sf = fit_scale_factor(data, thermal.nodes_c, thermal.network.node_names, dev_t, laws)
    from rlgsim.lab.identify.outputs import make_folder
    out = make_folder(out_dir)
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
