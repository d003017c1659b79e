"""The report of a several-gyro identification (:mod:`.twin_gyros`): the thermal network once,
then a section per gyro with the same tables and figures as a single gyro's report
(:mod:`.identify_report`: bias law with its standard errors and model averaging, anomalies,
UHFO law, noise, scale factor), each table's title and file named after its gyro."""

from __future__ import annotations

from typing import Any

from rlgsim.lab.report import Report, slug

__all__ = ["build_gyros_report"]


def _intro(rep: Report, result: Any, device_name: str, thermal_name: str) -> None:
    d = result.data
    axes = [g.axis for g in result.gyros]
    uh = [g.axis for g in result.gyros if g.data.uhfo_v is not None]
    rep.paragraph(
        f"Identified from `{d.source}` ({d.duration_s / 3600:.2f} h, probes every {d.step_s:g} s, "
        f"gyros {', '.join(f'`{a}`' for a in axes)} at {d.sample_rate_hz:g} Hz) with the device "
        f"template `{device_name}` and the thermal template `{thermal_name}` in "
        f"{result.seconds:.1f} s. The thermal network is fitted once (the gyros share it); each "
        f"gyro's laws are fitted on it as a single gyro's are, "
        + (f"with its own UHFO column ({', '.join(uh)}; the others without a UHFO term)"
           if uh else "without UHFO (the recording has no UHFO column)")
        + f". `device.toml` holds every gyro's law: a key with one value per gyro (in the order "
          f"{', '.join(axes)}) where they differ. Files: `thermal.toml`, `device.toml`, "
          f"`{result.scenario_path.name}` (the recorded chamber programme on the twin: "
          f"`rlgsim run {result.scenario_path.name}`).")
    from rlgsim.lab.identify.identify_report import notes_paragraphs
    notes_paragraphs(rep, result)
    if result.suggestion is not None:
        rep.paragraph(f"The next experiment (`{result.next_path.name}`) is designed for gyro "
                      f"`{result.next_gyro}` only (the first whose bias law has terms this "
                      f"recording cannot separate, else the first gyro).")


def _gyro_section(rep: Report, result: Any, g: Any, plt: Any) -> None:
    """One gyro's laws, anomalies, UHFO, noise and scale factor; its tables retitled."""
    from rlgsim.lab.identify import identify_report as R
    from rlgsim.lab.identify.recording_data import scale_factor_line
    before = len(rep.tables)
    rep.heading(f"Gyro {g.axis}", level=2)
    line = (g.scale_factor.lines[0] + " (section Scale factor)" if g.scale_factor is not None
            else scale_factor_line(g.data))
    rep.paragraph(f"{len(g.data.windows)} windows of {g.data.window_s:g} s. "
                  + line[0].upper() + line[1:] + ".")
    R.gyro_sections(rep, g.data, g.laws, g.scale_factor, g.device, plt)
    for t in rep.tables[before:]:
        t.title = f"Gyro {g.axis}: {t.title}"
        t.csv_name = f"{slug(t.title)}.csv"


def build_gyros_report(result, device_name: str, thermal_name: str) -> Report:
    """The several-gyro twin's report (module docstring)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rlgsim.lab.identify import identify_report as R
    rep = Report(f"Digital twin of {result.data.source}")
    _intro(rep, result, device_name, thermal_name)
    R._thermal_section(rep, result, plt)
    for g in result.gyros:
        _gyro_section(rep, result, g, plt)
    return rep
