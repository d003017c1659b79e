"""Writing a recording: its sidecar (TOML, read back before it is kept) and its table (CSV or
Parquet, block by block), each to a temporary name renamed on success (docs/recordings.md).

Part of :mod:`rlgsim.ground.recording`; nothing here imports ``rlgsim.sim``.
"""

from __future__ import annotations

import os
import pathlib
import tomllib
from typing import Any, Mapping

from rlgsim.ground.atomic import atomic_file
from rlgsim.ground.toml_text import dumps

__all__ = ["write_sidecar", "write_table"]


def write_sidecar(path: str | os.PathLike, tables: Mapping[str, Mapping[str, Any]],
                  comment: str = "") -> pathlib.Path:
    """Write a sidecar: ``tables`` maps table name to ``{key: value}`` (scalars, lists)."""
    p = pathlib.Path(path)
    text = dumps({name: dict(table) for name, table in tables.items() if table}, header=comment)
    tomllib.loads(text)                  # never write a sidecar that does not read back
    with atomic_file(p) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return p


def write_table(path: str | os.PathLike, blocks, fmt: str) -> pathlib.Path:
    """Write the table from an iterable of pandas DataFrames (same columns) as CSV or Parquet,
    block by block (memory bounded by one block), to a temporary name renamed on success.
    Floats are written with full precision, so a CSV reads back to identical float64."""
    p = pathlib.Path(path)
    if fmt == "parquet":
        from rlgsim.ground.recording_columns import need_pyarrow
        need_pyarrow(p, "writing")
    writer = None
    with atomic_file(p) as tmp:
        try:
            if fmt == "csv":
                with open(tmp, "w", newline="") as fh:
                    first = True
                    for df in blocks:
                        df.to_csv(fh, index=False, header=first, na_rep="", float_format=None,
                                  lineterminator="\n")
                        first = False
            elif fmt == "parquet":
                import pyarrow as pa
                import pyarrow.parquet as pq
                for df in blocks:
                    table = pa.Table.from_pandas(df, preserve_index=False)
                    if writer is None:
                        writer = pq.ParquetWriter(tmp, table.schema)
                    writer.write_table(table)
            else:
                raise ValueError(f"unknown table format {fmt!r}")
        finally:
            if writer is not None:
                writer.close()
    return p
