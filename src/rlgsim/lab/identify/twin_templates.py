"""The templates an identification starts from (docs/identify.md): the device template (whose
law family and keys the twin takes) and the thermal template (whose topology it keeps), from the
flags, the recording's sidecar or an rlgsim dataset's embedded presets, each checked by the
simulator's own validators; and the files an identification reads (which it never overwrites).
"""

from __future__ import annotations

import os
import tomllib

from rlgsim.ground.errors import UserInputError
from rlgsim.sim import presets

__all__ = ["load_templates", "files_read"]


def load_templates(source: str, device_template: str | None, thermal_template: str | None,
                   several: bool = False) -> tuple[str, dict, str, dict]:
    """(device name, device dict, thermal name, thermal dict) of the templates; ``several``:
    a template of several gyros is allowed (:mod:`.twin_gyros`)."""
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
                _one_gyro(dev_name, dev, several)
                _check_device_tables(f"{source}: device_text", dev)
                return dev_name, dev, f"{tname} (as embedded in the dataset)", \
                    tomllib.loads(ttext)
    if dev is None:
        raise UserInputError(f"{source}: a recording needs a device template (the device preset "
                             f"whose law family and noise keys the twin takes; e.g. trplg_001): "
                             f"give --device-template PRESET or, in its sidecar, [identify] "
                             f"device_template = \"PRESET\"")
    dev = _one_day(dev)
    _one_gyro(dev_name, dev, several)
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


def _one_gyro(dev_name: str, dev: dict, several: bool = False) -> None:
    axes = dev.get("gyro", {}).get("axes", [])
    if len(axes) != 1 and not (several and axes):
        raise UserInputError(f"{dev_name}: the device template has {len(axes)} gyro axes; "
                             f"identification fits one gyro (a single-gyro template such as "
                             f"trplg_001 or rlg8_003)")


def files_read(source: str, *templates: str | None) -> list[str]:
    """The files identification reads: the recording (and its sidecar) and template files."""
    from rlgsim.ground.recording import is_recording, sidecar_path
    found = [source] + ([str(sidecar_path(source))] if is_recording(source) else [])
    return found + [t for t in templates if t is not None and os.path.lexists(t)]
