"""A study's fitted compensators as files: ``models/<compensator>.json``, ``.c`` and ``.h`` in the
report folder (``[study] export_models = true`` or ``rlgsim study --export-models``).

Each file set is written by :func:`rlgsim.estimators.c_codegen.save_compensator`: the JSON
(coefficients, inputs with units, standardisation, training range, kind, rlgsim version) loads
back with :func:`rlgsim.estimators.model_export.load_json`; the C function is self-contained
for the gyro's microprocessor (docs/compensator_export.md). A recipe hands its fitted models
over through its optional hook ``fitted_models(config, result) -> list[FittedModel]``
(:func:`from_fitted` turns the fitting loop's records into them); the study runner
(:mod:`rlgsim.lab.study`) writes them and adds a table of the files to the report. A
compensator of ``kind = "custom"`` (the user's own regressor) has no export and is listed as
such.
"""

from __future__ import annotations

import pathlib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

#: Units of the single-gyro recipes' inputs (rlgsim.lab.studies: window means and slopes).
INPUT_UNITS = {"T": "°C", "dT/dt": "K/s", "U": "V"}
MODELS_DIR = "models"


def input_unit(name: str) -> str:
    """Unit of a study input: T °C, dT/dt K/s, U V, a probe-pair gradient "A-B" K, a probe °C."""
    if name in INPUT_UNITS:
        return INPUT_UNITS[name]
    return "K" if re.fullmatch(r"[^-]+-[^-]+", name) else "°C"


@dataclass(frozen=True)
class FittedModel:
    """One fitted compensator of a study run, as a recipe hands it to the export.

    ``X_train`` are the inputs it was fitted on (array or Columns; their range is the training
    range), ``inputs`` their names in model order, ``target``/``target_unit`` what it predicts.
    """

    name: str
    kind: str
    model: Any
    X_train: Any
    inputs: tuple[str, ...]
    target: str = "bias"
    target_unit: str = "°/h"


def from_fitted(fitted: Sequence[Any], prefix: str = "") -> list[FittedModel]:
    """:class:`FittedModel` records of the fitting loop's results (``Fitted``: ``spec`` with
    ``name``, ``kind``, ``inputs``; ``model``; ``X_train``), names prefixed by ``prefix``."""
    return [FittedModel(prefix + f.spec.name, f.spec.kind, f.model, f.X_train,
                        tuple(f.spec.inputs)) for f in fitted]


def write_models(models: Sequence[FittedModel], folder: str | pathlib.Path
                 ) -> list[dict[str, Any]]:
    """Write every model into ``folder`` (created); returns one record per model for the
    report: compensator, kind, the three file names relative to the report folder, or a note
    why there is none. File stems are C identifiers made from the names, made unique."""
    from rlgsim.estimators.c_codegen import c_identifier, save_compensator
    from rlgsim.estimators.model_export import KINDS
    folder = pathlib.Path(folder)
    exportable = set(KINDS.values())
    used: set[str] = set()
    records = []
    for m in models:
        if m.kind not in exportable:
            records.append({"compensator": m.name, "kind": m.kind, "JSON": "—", "C": "—",
                            "note": "no export for this kind (a custom regressor)"})
            continue
        stem = base = c_identifier(m.name)
        k = 2
        while stem in used:
            stem, k = f"{base}_{k}", k + 1
        used.add(stem)
        paths = save_compensator(m.model, m.X_train, folder, name=m.name, stem=stem,
                                 input_names=m.inputs,
                                 input_units={n: input_unit(n) for n in m.inputs},
                                 target=m.target, target_unit=m.target_unit)
        rel = f"{folder.name}/"
        records.append({"compensator": m.name, "kind": m.kind,
                        "JSON": rel + paths["json"].name,
                        "C": f"{rel}{paths['c'].name}, {paths['h'].name}", "note": ""})
    return records


def report_models(report, records: list[dict[str, Any]]) -> None:
    """The report section listing the exported files (``report``: rlgsim.lab.report.Report)."""
    from rlgsim.lab.report import Table
    report.heading("Exported compensators", 2)
    report.paragraph(
        "Each fitted compensator as JSON (coefficients, inputs with units, standardisation, "
        "training range; `rlgsim.estimators.model_export.load_json` reads it back and predicts "
        "as the fitted model) and as a self-contained C function for the gyro's "
        "microprocessor, `double f(const double x[], unsigned long long *range_flags)`: "
        "`range_flags` has bit i set when input i is outside its training range "
        "(docs/compensator_export.md).")
    report.table(Table("Exported compensators", ["compensator", "kind", "JSON", "C", "note"],
                       [[r[c] for c in ("compensator", "kind", "JSON", "C", "note")]
                        for r in records], csv_name="exported_models.csv"))
