"""Identification of a several-gyro recording into one device preset (docs/identify.md,
"Several gyros"): what :func:`rlgsim.lab.identify.twin.identify` does when the recording has
several gyros and neither ``gyro`` nor the sidecar's ``[identify] gyro`` picks one.

The gyros share the thermal network, so it is fitted once (the probes and the chamber air are
the same for every gyro); then each gyro's laws are fitted on that thermal state as a single
gyro's are (:func:`rlgsim.lab.identify.law_fit.fit_laws`, the scale factor where the table
turns), each on its own single-gyro view of the device template
(:func:`rlgsim.lab.identify.gyro_views.gyro_view`: a three-gyro template's own gyro, or a
single-gyro template standing for every gyro) and with its own UHFO column when the recording
has one for it (``uhfo_<axis>_v``; a gyro without one gets a law without a UHFO term). The
per-gyro twins are merged into one ``device.toml`` whose laws hold one value per gyro
(:func:`rlgsim.lab.identify.gyro_views.merge_devices`), and the report has a section per gyro.
The next experiment (``suggest_programme``) is designed for one gyro only (said in the report
and printed): the first whose bias law has terms this recording cannot separate, else the
first gyro.
"""

from __future__ import annotations

import dataclasses
import time
import tomllib
from dataclasses import dataclass

from rlgsim.ground.errors import UserInputError
from rlgsim.lab.report import write_atomic

__all__ = ["GyroTwin", "recorded_gyros", "identify_gyros", "one_gyro_template"]


@dataclass
class GyroTwin:
    """One gyro of a several-gyro identification: its recording view, law fit, scale-factor
    fit (None: a static recording), the single-gyro template view it was fitted on and its
    own single-gyro twin (before the merge)."""

    axis: str
    data: object
    laws: object
    scale_factor: object
    template: dict
    device: dict


def recorded_gyros(source: str) -> list[str]:
    """The gyro axes of a recording or a dataset ([] when it has none: the single-gyro path
    then refuses it in its own words): a recording's sidecar ``[gyro] axes`` when it lists them
    (the reader holds the columns to that list), else the opened table; a dataset's ``imu/gyro``
    coordinate."""
    from rlgsim.ground.datatree import open_tree
    from rlgsim.ground.recording import is_recording, read_sidecar, sidecar_path
    if is_recording(source):
        axes = read_sidecar(sidecar_path(source)).gyro_axes
        if axes is not None:
            return [str(a) for a in axes]
    else:
        from rlgsim.ground.dataset_format import open_dataset
        with open_dataset(source) as ds:               # the coordinate alone, not the tree
            return ds.strings("imu", "gyro") if ds.has("imu", "gyro") else []
    tree = open_tree(source)
    try:
        if "imu" not in tree.children or "gyro" not in tree["imu"].coords:
            return []
        return [str(a) for a in tree["imu"]["gyro"].values]
    finally:
        tree.close()


def one_gyro_template(template: dict, axes: list[str], source: str) -> dict:
    """The template a one-gyro identification fits on: itself when it has one gyro (or the
    recording none, which the reader refuses), else the single-gyro view of the recorded gyro
    ``axes[0]`` (:func:`rlgsim.lab.identify.gyro_views.gyro_view`: its block, its laws)."""
    from rlgsim.lab.identify.gyro_views import gyro_view, template_component
    if len(template.get("gyro", {}).get("axes", [])) <= 1 or not axes:
        return template
    return gyro_view(template, axes[0], template_component(template, axes[0], source))


def _fit_gyro(axis: str, view: dict, data, thermal, names) -> tuple[GyroTwin, dict, dict]:
    """One gyro's laws on the shared thermal state, and its single-gyro twin device."""
    from rlgsim.lab.identify.law_fit import fit_laws
    from rlgsim.lab.identify.scale_factor_fit import fit_scale_factor, scale_factor_table
    from rlgsim.lab.identify.twin_text import device_dict
    laws = fit_laws(data, thermal.nodes_c, names, view)
    sf = fit_scale_factor(data, thermal.nodes_c, names, view, laws)
    dev, comments = device_dict(view, laws, "twin", data.source)
    if sf is not None and sf.identified:
        table, notes = scale_factor_table(view, sf)
        dev["gyro"]["scale_factor"] = table
        comments.update({("gyro", "scale_factor", k): v for k, v in notes.items()})
        tol = dev.get("tolerance", {}).get("gyro", {})
        if "scale_factor" in tol:
            tol["scale_factor"] = {k: v for k, v in tol["scale_factor"].items()
                                   if k in table or (k.startswith("knee_") and "knee_ppm" in table)}
    return GyroTwin(axis, data, laws, sf, view, dev), dev, comments


def _header(source: str, dev_name: str, axes, gyros: list[GyroTwin], lines) -> str:
    from rlgsim.lab.identify.recording_data import scale_factor_line
    from rlgsim.lab.identify.twin_text import law_header
    out = [f"Device preset identified by rlgsim identify from {source}",
           f"template: {dev_name}; gyros {', '.join(axes)} identified one by one on one "
           f"thermal twin: each law key holds one value per gyro (x, y, z order of [gyro] axes) "
           f"where the gyros differ; bias and UHFO terms chosen by BIC per gyro, noise from the "
           f"Allan deviation of each gyro's law residual"]
    for g in gyros:
        uh = "with its UHFO column" if g.data.uhfo_v is not None else "no UHFO column"
        out.append(f"gyro {g.axis} ({uh}): bias terms "
                   f"{', '.join(g.laws.bias.terms) or 'none (constant)'}")
        if g.laws.bias.unseparable:
            out += [f"gyro {g.axis} " + x for x in law_header(g.laws.bias).splitlines()]
        sf = g.scale_factor
        out.append(f"gyro {g.axis} " + (sf.lines[0] if sf is not None
                                        else scale_factor_line(g.data)))
    return "\n".join(out + list(lines))


def identify_gyros(source: str, out_dir, axes: list[str], chosen, name: str | None,
                   suggest_programme: bool, overwrite: bool, t0: float):
    """Identify every gyro of ``source`` into one twin (module docstring); ``chosen`` the
    sidecar choices (:func:`rlgsim.lab.identify.sidecar_choices.sidecar_choices`)."""
    from rlgsim.lab.identify.twin_result import Identification
    from rlgsim.lab.identify.twin_templates import files_read, load_templates
    from rlgsim.lab.identify.twin_text import scenario_text, thermal_text
    from rlgsim.lab.identify.gyro_views import gyro_view, merge_devices, template_component
    from rlgsim.lab.identify.outputs import planned_outputs
    from rlgsim.lab.identify.preset_text import dumps
    from rlgsim.lab.identify.probe_mapping import map_probes, sidecar_probe_table
    from rlgsim.lab.identify.recording_data import read_recordings
    from rlgsim.lab.identify.thermal_fit import fit_thermal
    inputs = files_read(source, chosen.device_template, chosen.thermal_template)
    dev_name, dev_t, th_name, th_t = load_templates(source, chosen.device_template,
                                                      chosen.thermal_template, several=True)
    index = [template_component(dev_t, a, source) for a in axes]
    name = name or f"{dev_name}_twin"
    planned_outputs(out_dir, name, inputs, overwrite=overwrite, next_file=suggest_programme)
    datas = read_recordings(source, axes)          # the file opened once
    data0, probe_lines = map_probes(th_t, datas[0], sidecar_probe_table(source), source)
    datas = [data0] + [dataclasses.replace(d, probe_names=data0.probe_names,
                                           probes_c=data0.probes_c) for d in datas[1:]]
    thermal = fit_thermal(th_t, data0.air_c, data0.power, data0.step_s, data0.probe_names,
                          data0.probes_c, source=source)
    names = thermal.network.node_names
    fits = [_fit_gyro(a, gyro_view(dev_t, a, i), d, thermal, names)
            for a, i, d in zip(axes, index, datas)]
    gyros = [f[0] for f in fits]
    devs = [f[1] for f in fits]
    for d in devs:
        d["device"]["name"] = name
    dev, comments = merge_devices(dev_t, axes, devs, [f[2] for f in fits],
                                  [g.laws for g in gyros])
    from rlgsim.lab.identify.outputs import make_folder
    out = make_folder(out_dir)
    files = planned_outputs(out, name, inputs, overwrite=overwrite, next_file=suggest_programme)
    fitted_thermal, ttext = thermal_text(thermal, th_name, source)
    dtext = dumps(dev, comments, _header(source, dev_name, axes, gyros,
                                         [*chosen.notes, *probe_lines]))
    stext = scenario_text(data0, name)
    suggestion, ntext = None, None
    target = next((g for g in gyros if g.laws.bias.unseparable), gyros[0])
    if suggest_programme:
        from rlgsim.lab.identify import next_experiment as NE
        suggestion = NE.suggest_programme(target.data, thermal, target.laws, target.template)
        if suggestion is not None:
            ntext = NE.scenario_text(suggestion, target.data, name)
    for text in (ttext, dtext, stext, ntext or ""):
        tomllib.loads(text)                        # never write what cannot be read back
    _check_preset(dev, source)
    write_atomic(files["thermal"], ttext)
    write_atomic(files["device"], dtext)
    write_atomic(files["replay"], stext)
    next_path = None
    if ntext is not None:
        next_path = files["next"]
        write_atomic(next_path, ntext)
    result = Identification(
        out_dir=out, device_path=files["device"], thermal_path=files["thermal"],
        scenario_path=files["replay"], report_path=out / "report.md", data=data0,
        thermal=thermal, laws=gyros[0].laws, device=dev, thermal_preset=fitted_thermal,
        seconds=time.perf_counter() - t0, name=name, scale_factor=gyros[0].scale_factor,
        probe_lines=tuple(probe_lines), notes=chosen.notes, suggestion=suggestion,
        next_path=next_path, gyros=tuple(gyros),
        next_gyro=target.axis if suggest_programme else None)
    from rlgsim.lab.identify.identify_report_gyros import build_gyros_report
    build_gyros_report(result, dev_name, th_name).write(out)
    return result


def _check_preset(dev: dict, source: str) -> None:
    """The merged preset read by the simulator's own validator (a merge the simulator would
    refuse is a bug here, said in one line, before anything is written)."""
    from rlgsim.sim.config import Ctx
    from rlgsim.sim.run.scenario import validate_device_tables
    try:
        validate_device_tables(dev, Ctx(f"{source}: identified device"))
    except UserInputError as exc:
        raise UserInputError(f"the merged several-gyro twin is not a valid device preset "
                             f"({exc})") from None
