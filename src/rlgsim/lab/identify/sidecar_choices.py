"""What a recording's sidecar tells ``rlgsim identify`` so that the recording goes through with
its sidecar alone (docs/identify.md, docs/recordings.md): the ``[identify]`` table names the
device template, the thermal template and the gyro to identify; a command-line flag (or
keyword argument) wins over the sidecar. A template path in the sidecar is read relative to the
sidecar's folder (as a scenario's preset paths are relative to the scenario).

What is missing and has a sensible default becomes one note line (printed, and written into
the twin's ``device.toml`` header and report): without ``[site] latitude_deg`` the Earth rate
on the gyro axis is taken at the default latitude (:data:`rlgsim.ground.earth.
DEFAULT_LATITUDE_DEG`), which moves only the bias law's constant. What is missing without a
default (the device template of a recording, the gyro of a several-gyro recording) is refused
in one line by :func:`rlgsim.lab.identify.twin.load_templates` and
:func:`rlgsim.lab.identify.recording_data.read_recording`, naming both the flag and the
sidecar key.
"""

from __future__ import annotations

import pathlib
from dataclasses import dataclass

from rlgsim.ground.earth import DEFAULT_LATITUDE_DEG

__all__ = ["Choices", "sidecar_choices"]


@dataclass(frozen=True)
class Choices:
    """The templates and gyro identification uses, and the notes on the defaults taken."""

    device_template: str | None
    thermal_template: str | None
    gyro: str | None
    notes: tuple[str, ...] = ()


def _relative_to(folder: pathlib.Path, ref: str | None) -> str | None:
    """A template reference from the sidecar: a relative path that exists beside the sidecar
    becomes that file; a shipped preset name stays a name."""
    from rlgsim.sim.presets import looks_like_path
    if ref is None or not looks_like_path(ref):
        return ref
    p = pathlib.Path(ref).expanduser()
    if not p.is_absolute() and (folder / p).exists():
        return str(folder / p)
    return ref


def sidecar_choices(source: str, device_template: str | None, thermal_template: str | None,
                    gyro: str | None) -> Choices:
    """The arguments completed from the sidecar's ``[identify]`` table (a recording; a dataset
    keeps its own defaults), with a note for each default taken."""
    from rlgsim.ground.recording import is_recording, read_sidecar, sidecar_path
    if not is_recording(source):
        return Choices(device_template, thermal_template, gyro)
    sc = read_sidecar(sidecar_path(source))
    from rlgsim.ground.recording_sidecar import need_fixed_site
    need_fixed_site(sc, "rlgsim identify")
    folder = sc.path.parent
    side = sc.identify
    notes = []
    if not sc.site_given:
        notes.append(f"site: [site] latitude_deg not in the sidecar {sc.path.name}; the Earth "
                     f"rate on the gyro axis is taken at latitude {DEFAULT_LATITUDE_DEG:g}° "
                     f"(a wrong latitude moves only the bias law's constant)")
    return Choices(
        device_template if device_template is not None
        else _relative_to(folder, side.get("device_template")),
        thermal_template if thermal_template is not None
        else _relative_to(folder, side.get("thermal_template")),
        gyro if gyro is not None else side.get("gyro"),
        tuple(notes))
