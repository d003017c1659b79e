"""Exported compensators (docs/compensator_export.md) as gyro-bias predictions for navigation.

``rlgsim navigate --models`` takes JSON files written by ``rlgsim study --export-models``. A
file whose stem ends in ``_x``, ``_y`` or ``_z`` predicts that gyro axis; files with the same
stem before the suffix form one variant. A file without an axis suffix is applied to all three
gyros, each with its own inputs. Inputs are computed per window (the study's window, 100 s)
by :func:`rlgsim.lab.api.window_table`: a probe name → its window mean [°C], ``A-B`` → the
difference of two probes [K], ``U`` → the UHFO voltage [V], ``T``/``dT/dt`` → the mean and
slope of the temperature probe (``temperature_probe``; needed when the source has several
probes). The prediction [°/h] holds over its window (piecewise constant) and is subtracted
from the gyro's rate; windows the table leaves out (unpowered) predict 0.
"""

from __future__ import annotations

import pathlib
import re
from typing import Callable, Sequence

import numpy as np

from rlgsim.ground.errors import UserInputError
from rlgsim.ground.units import DEG, HOUR

_AXIS = re.compile(r"^(.*?)[_\[]([xyz])\]?$")


def _files(paths: Sequence[str | pathlib.Path]) -> list[pathlib.Path]:
    out: list[pathlib.Path] = []
    for p in map(pathlib.Path, paths):
        if p.is_dir():
            found = sorted(p.glob("*.json"))
            if not found:
                raise UserInputError(f"{p}: no compensator .json files in this folder")
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise UserInputError(f"{p}: no such compensator file or folder")
    return out


def _column(name: str, df, temperature_probe: str | None, path: pathlib.Path) -> np.ndarray:
    probes = [c[len("probe_"):-len("_c")] for c in df.columns if c.startswith("probe_")]
    if name in ("T", "dT/dt"):
        probe = temperature_probe or (probes[0] if len(probes) == 1 else None)
        if probe is None:
            raise UserInputError(f"{path}: input {name!r} needs the temperature probe "
                                 f"(--temperature-probe, one of {', '.join(probes)})")
        key = f"probe_{probe}_c" if name == "T" else f"dTdt_{probe}_k_per_s"
    elif name == "U":
        key = "uhfo_v"
    elif name in probes:
        key = f"probe_{name}_c"
    elif "-" in name and all(p in probes for p in name.split("-", 1)):
        a, b = name.split("-", 1)
        return df[f"probe_{a}_c"].to_numpy() - df[f"probe_{b}_c"].to_numpy()
    else:
        key = ""
    if key not in df:
        raise UserInputError(f"{path}: input {name!r} has no series in the source (probes: "
                             f"{', '.join(probes) or 'none'})")
    return df[key].to_numpy()


def load_models(paths: Sequence[str | pathlib.Path], source: str | pathlib.Path, *,
                temperature_probe: str | None = None, window_s: float = 100.0
                ) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    """Variant name → f(t_s) giving the predicted gyro bias [rad/s] (m, 3)."""
    from rlgsim.estimators.model_export import load_json
    from rlgsim.lab.api import window_table
    groups: dict[str, dict[str, pathlib.Path]] = {}
    for f in _files(paths):
        m = _AXIS.match(f.stem)
        name, axis = (m.group(1), m.group(2)) if m else (f.stem, "*")
        groups.setdefault(name, {})[axis] = f
    tables = {a: window_table(source, window_s, gyro=a) for a in "xyz"}
    out = {}
    for name, files in groups.items():
        ends, preds = [], []
        for a in "xyz":
            f = files.get(a, files.get("*"))
            if f is None:
                raise UserInputError(f"{name}: no compensator for gyro {a} (give {name}_{a}.json)")
            model = load_json(f)
            df = tables[a]
            x = np.column_stack([_column(n, df, temperature_probe, f) for n in model.input_names_])
            ends.append(df["time_s"].to_numpy())
            preds.append(np.asarray(model.predict(x), float) * DEG / HOUR)

        def predict(t: np.ndarray, ends=ends, preds=preds) -> np.ndarray:
            cols = []
            for e, p in zip(ends, preds):
                i = np.searchsorted(e, t, side="left")          # the window that ends after t
                ok = (i < e.size) & (t >= e[np.minimum(i, e.size - 1)] - window_s)
                cols.append(np.where(ok, p[np.minimum(i, e.size - 1)], 0.0))
            return np.column_stack(cols)
        out[name] = predict
    return out
