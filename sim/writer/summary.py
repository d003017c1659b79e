"""What ``rlgsim info`` prints of a dataset: :func:`summary`, read through the one reader
(:func:`rlgsim.ground.dataset_format.open_dataset`) — format and versions, the run's root
attributes, and every group's variables with their dimensions and units."""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from rlgsim.ground.dataset_format import FORMAT, TIME, VERSION_ATTR, open_dataset


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return str(value.item())
    return str(value)


def summary(path: str | os.PathLike) -> str:
    """A human-readable summary of a dataset (what ``rlgsim info`` prints)."""
    with open_dataset(path) as ds:
        a = ds.attrs
        lines = [f"{path}: {FORMAT} v{_text(a.get(VERSION_ATTR))}, "
                 f"rlgsim {_text(a.get('software_version', '?'))}"]
        if "software_versions" in a:            # datasets written since issue 29
            try:
                made = json.loads(_text(a["software_versions"]))
                lines.append("  made with: " + ", ".join(f"{k} {v}" for k, v in made.items()))
            except (ValueError, AttributeError):
                pass
        for key, label in (("scenario_name", "scenario"), ("scenario_source", "scenario file"),
                           ("device", "device"), ("seed", "seed"),
                           ("duration_s", "duration [s]"),
                           ("thermal_step_s", "thermal step [s]")):
            if key in a:
                lines.append(f"  {label}: {_text(a[key])}")
        for gname in ds.groups():
            desc = _text(ds.group_attrs(gname).get("description", ""))
            lines.append(f"  group {gname}: {desc}")
            for v in ds.variables(gname):
                shape = "×".join(f"{d}={n}" for d, n in zip(v.dims, v.shape))
                units = _text(v.units) if v.units is not None else ""
                extra = ""
                if v.name == TIME and v.shape[0]:
                    n = v.shape[0]
                    first = ds.read(gname, TIME, slice(0, 1))[0]
                    last = ds.read(gname, TIME, slice(n - 1, n))[0]
                    extra = f"  [{first:g} .. {last:g}]"
                lines.append(f"    {v.name:<18} ({shape}) {units}{extra}")
    return "\n".join(lines)
